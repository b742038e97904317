#!/usr/bin/env bash
# One `digiview serve` on a still, in two phases, its log (stderr) appended to LOG: nobody
# watching a view for 22 s, then "=== watched" and each of the four views' streams pulled by
# one RTSP client for 32 s (FFmpeg's write each frame's timestamp to LOG.camN). 1920x1080 out,
# motion detection on, health lines every 5 s.
# SERVE_TOP and SERVE_TABLES, where set, add top-level keys and tables to its configuration
# (serve_config.sh).
# Used by scripts/views_cost.sh and scripts/gpu_figures.sh.
#
# Usage: scripts/serve_views.sh DIGIVIEW STILL LOG PORT [KIND [CODEC [CLIENT [PRIORITY]]]]
#   KIND: the encoder (default auto); CODEC: h264 (default) or h265;
#   CLIENT: ffmpeg (default) or gst (gst-launch-1.0's rtspsrc);
#   PRIORITY: the clients' CPU priority: same (as serve's, the default) or idle (SCHED_IDLE:
#   they take the CPU time serve leaves, as viewers on machines of their own would).
set -uo pipefail
dv=$1 still=$2 log=$3 port=$4 kind=${5:-auto} codec=${6:-h264} client=${7:-ffmpeg}
priority=${8:-same}
run_client() { if [[ $priority == idle ]]; then chrt --idle 0 "$@"; else "$@"; fi; }
cfg=$(mktemp --suffix=.toml)
trap 'rm -f "$cfg"' EXIT
. "$(dirname "$0")/serve_config.sh"
serve_config "$cfg" "$still" "$port" "$kind" "$codec"
# Appending, as the phase marker below is: both writers keep their lines.
RUST_LOG=${RUST_LOG:-info} "$dv" serve --config "$cfg" --size 1920x1080 --http off >/dev/null 2>>"$log" &
serve=$!
sleep 22
echo "=== watched" >>"$log"
pids=()
for cam in 0 1 2 3; do
  uri="rtsp://127.0.0.1:$port/digiview/cam$cam"
  if [[ $client == gst ]]; then
    run_client gst-launch-1.0 -q rtspsrc location="$uri" protocols=tcp latency=0 ! fakesink sync=false \
      >/dev/null 2>&1 &
  else
    # Each frame's timestamp (1/90000 s), for its stream's own rate: LOG.camN.
    run_client ffmpeg -nostdin -loglevel error -rtsp_transport tcp -i "$uri" -fps_mode passthrough \
      -enc_time_base:v 1:90000 -f framemd5 "$log.cam$cam" >/dev/null 2>&1 &
  fi
  pids+=($!)
done
sleep 32
kill "${pids[@]}" 2>/dev/null
kill -INT $serve 2>/dev/null
wait $serve 2>/dev/null
