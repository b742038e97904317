#!/usr/bin/env bash
# Glass-to-glass latency on this host: `digiview serve` on the demo with each frame's capture
# time drawn as a barcode, pulled over RTSP and decoded on the same host, or watched on the
# tuning page in headless Chromium; prints the median and spread. The clients:
#   rtsp    GStreamer (rtspsrc, latency 0, TCP; avdec_h264)
#   ffmpeg  the ffmpeg program (-fflags nobuffer -flags low_delay -threads 1, TCP)
#   opencv  OpenCV's capture (FFmpeg's RTSP client as a library, one decoding thread)
#   page    the tuning page (WebCodecs); mse: the page through Media Source Extensions
# Usage: scripts/latency.sh [WxH] [frames] [rtsp|ffmpeg|opencv|page|mse]
set -euo pipefail
cd "$(dirname "$0")/.."
cargo build --release --quiet --bin digiview --example glass_to_glass
client=()
case "${3:-rtsp}" in
  rtsp) ;;
  ffmpeg) client=(--ffmpeg) ;;
  opencv) client=(--opencv) ;;
  page) client=(--page) ;;
  mse) client=(--mse) ;;
  *) echo "latency.sh: the client is rtsp, ffmpeg, opencv, page or mse, not ${3}" >&2; exit 2 ;;
esac
target/release/examples/glass_to_glass --size "${1:-1280x720}" --frames "${2:-300}" "${client[@]}" 2>/dev/null
