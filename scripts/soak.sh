#!/usr/bin/env bash
# Soak: `digiview serve` with everything on, for N minutes (default 60), as a drone flies it:
# - the demo flying its circle, its flight sent over MAVLink as an autopilot's (system 1) to
#   the link's own port, so the attitude comes back through the autopilot path;
# - a ground station (scripts/soak_gcs.py, pymavlink) polling the four cameras and steering
#   their gimbals, counting answers and heartbeat gaps;
# - detection on (the default motion detector), and the tuning page open in headless Chromium;
# - each of the four views watched by its own FFmpeg client all along, and two more clients
#   joining and leaving the composed stream at random;
# - the stream published to a relay (FFmpeg listening for SRT, as MediaMTX's SRT ingest
#   takes it), and a recording started
#   and stopped every minute.
# Samples the server's memory and /api/status every 10 s, then reports memory growth after
# warm-up, service restarts, dropped frames, viewers that had to reconnect, log lines per
# minute, and whether every MP4 plays. Exit status 0 only when serve lived and exited cleanly,
# memory grew by no more than 5%, nothing restarted and every recording plays.
# Usage: scripts/soak.sh [minutes] [workdir] [output size] [demo frame size]   (scripts/setup.sh first: it makes .venv)
set -uo pipefail
cd "$(dirname "$0")/.."
minutes=${1:-60}
work=${2:-$(mktemp -d /tmp/digiview-soak.XXXX)}
size=${3:-960x540}
# The demo's fisheye frames are drawn on the CPU, which a camera's are not: at 4K that alone
# takes most of a 2-core machine, so the soak draws them at 1080p unless told otherwise.
demo=${4:-1920x1080}
mkdir -p "$work/captures"
cargo build --release --quiet --bin digiview || exit 1
[ -x .venv/bin/python ] || { echo "soak: no .venv: run scripts/setup.sh"; exit 1; }
bin=target/release/digiview
free_port() { python3 -c 'import socket; s = socket.socket(); s.bind(("127.0.0.1", 0)); print(s.getsockname()[1])'; }
free_udp_port() { python3 -c 'import socket; s = socket.socket(type=socket.SOCK_DGRAM); s.bind(("127.0.0.1", 0)); print(s.getsockname()[1])'; }
control=$(free_port) rtsp=$(free_port) http=$(free_port) relay=$(free_udp_port) mav=$(free_udp_port)
ctl() { "$bin" ctl --addr "127.0.0.1:$control" "$@" >/dev/null; }
seconds=$((minutes * 60))

relay_loop() {  # a relay that decodes the published stream, again after each disconnect
  local n=0
  while :; do
    n=$((n + 1))
    ffmpeg -nostdin -v error -i "srt://127.0.0.1:$relay?mode=listener" \
      -progress "$work/relay.$n.progress" -f null - >>"$work/relay.log" 2>&1
    sleep 1
  done
}
relay_loop &

RUST_LOG=info "$bin" serve --size "$size" --control "127.0.0.1:$control" --rtsp-port "$rtsp" \
  --http "127.0.0.1:$http" --mavlink "udpin:127.0.0.1:$mav" --capture-dir "$work/captures" \
  --demo-size "$demo" --publish "srt://127.0.0.1:$relay" >"$work/stdout" 2>"$work/serve.log" &
pid=$!
cleanup() {  # serve, then each loop and what it runs (an orphan would hold a port)
  kill $pid 2>/dev/null
  for j in $(jobs -p); do
    kids=$(pgrep -P "$j")
    kill "$j" $kids 2>/dev/null
  done
}
trap cleanup EXIT
sleep 5
url=$(sed -n 's/^rtsp serving //p' "$work/stdout")
[ -n "$url" ] || { echo "soak: serve did not start"; cat "$work/serve.log"; exit 1; }
echo "soak: $minutes min at $size from a $demo demo, pid $pid, $url, files in $work"

.venv/bin/python scripts/soak_gcs.py "$mav" "$seconds" >"$work/gcs.log" 2>&1 &
chromium --headless --no-sandbox --disable-gpu --disable-quic --no-first-run \
  --disable-background-networking --disable-component-update --disable-sync \
  --user-data-dir="$work/chromium" --remote-debugging-port=0 "http://127.0.0.1:$http/" \
  >"$work/chromium.log" 2>&1 &

watcher() {  # one view watched all along; a reconnect is counted
  while kill -0 $pid 2>/dev/null; do
    ffmpeg -nostdin -v error -rtsp_transport tcp -i "$url/cam$1" -f null - >>"$work/view$1.log" 2>&1
    # Not counted once the soak is ending: serve is being stopped then.
    kill -0 $pid 2>/dev/null && [ ! -e "$work/ending" ] &&
      echo "reconnect $(date +%s)" >>"$work/view$1.reconnects"
    sleep 1
  done
}
client() {  # joins the composed stream for 5..60 s, leaves for 1..20 s
  while kill -0 $pid 2>/dev/null; do
    timeout $((5 + RANDOM % 56)) ffmpeg -nostdin -v error -rtsp_transport tcp -i "$url" -f null - \
      >>"$work/client$1.log" 2>&1
    sleep $((1 + RANDOM % 20))
  done
}
for i in 0 1 2 3; do watcher $i & done
for i in 1 2; do client $i & done

end=$(($(date +%s) + seconds))
echo "time_s rss_kb" >"$work/rss.txt"
start=$(date +%s)
last_minute=-1
while [ "$(date +%s)" -lt "$end" ]; do
  kill -0 $pid 2>/dev/null || { echo "soak: serve died"; tail -20 "$work/serve.log"; exit 1; }
  now=$(($(date +%s) - start))
  echo "$now $(ps -o rss= -p $pid)" >>"$work/rss.txt"
  curl -s --max-time 2 "http://127.0.0.1:$http/api/status" >"$work/status.json.new" &&
    mv "$work/status.json.new" "$work/status.json"
  minute=$((now / 60))
  if [ "$minute" != "$last_minute" ]; then   # a new recording each minute, 50 s long
    ctl set capture flags=2
    last_minute=$minute
    (sleep 50; ctl set capture flags=0) &
  fi
  sleep 10
done
touch "$work/ending"
ctl set capture flags=0
sleep 2
kill -TERM $pid
wait $pid
status=$?
sleep 2  # the ground station prints its summary when its time is up
trap - EXIT
cleanup

# Memory: after warm-up (2 minutes, or a quarter of a short run), the first sample against
# the largest and the last.
warm=$((minutes * 15 < 120 ? minutes * 15 : 120))
awk -v warm=$warm 'NR>1 && $1>=warm {if (!base) base=$2; if ($2>max) max=$2; last=$2}
     END {if (!base) {print "soak: too short to judge memory"; exit 1}
          printf "soak: rss %d kB after warm-up, max %d kB (%+.1f%%), last %d kB (%+.1f%%)\n",
          base, max, 100*(max-base)/base, last, 100*(last-base)/base;
          exit (max > base*1.05)}' "$work/rss.txt"
mem=$?
bad=0; total=0
for f in "$work"/captures/*.mp4; do
  total=$((total + 1))
  n=$(ffprobe -v error -count_frames -select_streams v:0 -show_entries stream=nb_read_frames \
      -of csv=p=0 "$f" 2>/dev/null)
  if [ -z "$n" ] || [ "$n" -lt 100 ]; then bad=$((bad + 1)); echo "soak: $f: ${n:-unreadable} frames"; fi
done
lines=$(wc -l <"$work/serve.log")
echo "soak: log: $lines lines, $((lines / minutes)) a minute ($(grep -c ' WARN ' "$work/serve.log") WARN, $(grep -c ' ERROR ' "$work/serve.log") ERROR); the commonest:"
sed -E 's/^[^ ]+ +//; s/[0-9]+(\.[0-9]+)?/N/g' "$work/serve.log" | sort | uniq -c | sort -rn | head -5
echo "soak: health lines: $(grep -c 'health:' "$work/serve.log"); frames in and out a second (min, median, max):"
grep -o 'health: in [0-9.]* fps, out [0-9.]* fps' "$work/serve.log" | awk '{print $3, $6}' |
  python3 -c 'import sys, statistics as st
rows = [tuple(map(float, l.split())) for l in sys.stdin]
for i, name in enumerate(("in", "out")):
    v = [r[i] for r in rows] or [0]
    print(f"  {name}: {min(v):.1f}, {st.median(v):.1f}, {max(v):.1f}")'
echo "soak: the last health line:"
grep "health:" "$work/serve.log" | tail -1
services=$(python3 -c 'import json,sys; print(json.load(open(sys.argv[1])).get("services") or {})' "$work/status.json" 2>/dev/null)
restarts=$(grep -c -i 'restart' "$work/serve.log")
echo "soak: services failed (last /api/status): ${services:-unknown}; log lines naming a restart: $restarts"
for i in 0 1 2 3; do
  echo "soak: view $i reconnects: $(cat "$work/view$i.reconnects" 2>/dev/null | wc -l)"
done
relay_frames=$(cat "$work"/relay.*.progress 2>/dev/null | awk -F= '/^frame=/{f=$2} /^progress=end/{s+=f; f=0} END{print s+f}')
sessions=$(grep -l '^frame=[1-9]' "$work"/relay.*.progress 2>/dev/null | wc -l)
echo "soak: relay: $sessions sessions that received frames (a second one is a reconnect), $relay_frames frames"
echo "soak: ground station: $(tail -1 "$work/gcs.log")"
echo "soak: the autopilot link, last: $(grep 'mavlink: autopilot' "$work/serve.log" | tail -1 | sed 's/.*mavlink: //')"
echo "soak: exit status $status, $total recordings, $bad bad, memory check $([ $mem = 0 ] && echo ok || echo FAILED)"
[ "$status" = 0 ] && [ "$bad" = 0 ] && [ "$mem" = 0 ] && [ "$services" = "{}" ]
