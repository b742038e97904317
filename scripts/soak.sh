#!/usr/bin/env bash
# Soak: `digiview serve` on the flying demo at 1280x720 for N minutes (default 60) while
# three RTSP clients (ffmpeg) join and leave at random and a recording is started and stopped
# every minute. Samples the server's memory every 10 s, then checks that it is still alive,
# that memory after warm-up grew by no more than 5%, and that every MP4 plays (ffprobe
# counts its frames). Usage: scripts/soak.sh [minutes] [workdir]
set -uo pipefail
cd "$(dirname "$0")/.."
minutes=${1:-60}
work=${2:-$(mktemp -d /tmp/digiview-soak.XXXX)}
mkdir -p "$work/captures"
cargo build --release --quiet --bin digiview || exit 1
bin=target/release/digiview
ctl() { "$bin" ctl --addr 127.0.0.1:5611 "$@" >/dev/null; }

RUST_LOG=info "$bin" serve --size 1280x720 --control 127.0.0.1:5611 --rtsp-port 8611 --http 127.0.0.1:0 \
  --capture-dir "$work/captures" >"$work/stdout" 2>"$work/serve.log" &
pid=$!
trap 'kill $pid 2>/dev/null; kill $(jobs -p) 2>/dev/null' EXIT
sleep 5
url=$(sed -n 's/^rtsp serving //p' "$work/stdout")
[ -n "$url" ] || { echo "soak: serve did not start"; cat "$work/serve.log"; exit 1; }
echo "soak: $minutes min, pid $pid, $url, files in $work"

client() {  # joins for 5..60 s, leaves for 1..20 s, until the soak ends
  while kill -0 $pid 2>/dev/null; do
    timeout $((5 + RANDOM % 56)) ffmpeg -nostdin -v error -rtsp_transport tcp -i "$url" -f null - \
      >>"$work/client$1.log" 2>&1
    sleep $((1 + RANDOM % 20))
  done
}
for i in 1 2 3; do client $i & done

end=$(($(date +%s) + minutes * 60))
echo "time_s rss_kb" >"$work/rss.txt"
start=$(date +%s)
last_minute=-1
while [ "$(date +%s)" -lt "$end" ]; do
  kill -0 $pid 2>/dev/null || { echo "soak: serve died"; tail -20 "$work/serve.log"; exit 1; }
  now=$(($(date +%s) - start))
  echo "$now $(ps -o rss= -p $pid)" >>"$work/rss.txt"
  minute=$((now / 60))
  if [ "$minute" != "$last_minute" ]; then   # a new recording each minute, 50 s long
    ctl set capture flags=2
    last_minute=$minute
    (sleep 50; ctl set capture flags=0) &
  fi
  sleep 10
done
ctl set capture flags=0
kill -TERM $pid
wait $pid
status=$?
trap - EXIT
kill $(jobs -p) 2>/dev/null

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
grep -c "health:" "$work/serve.log" | xargs echo "soak: health lines:"
grep "health:" "$work/serve.log" | tail -3
echo "soak: exit status $status, $total recordings, $bad bad, memory check $([ $mem = 0 ] && echo ok || echo FAILED)"
[ "$status" = 0 ] && [ "$bad" = 0 ] && [ "$mem" = 0 ]
