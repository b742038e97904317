#!/usr/bin/env bash
# Glass-to-glass latency on this host: `digiview serve` on the demo with each frame's capture
# time drawn as a barcode, pulled over RTSP (rtspsrc, latency 0) and decoded on the same
# host, or watched on the tuning page in headless Chromium (`page`: WebCodecs, `mse`: Media
# Source Extensions, as over plain http from another machine); prints the median and spread.
# Usage: scripts/latency.sh [WxH] [frames] [rtsp|page|mse]
set -euo pipefail
cd "$(dirname "$0")/.."
cargo build --release --quiet --bin digiview --example glass_to_glass
client=()
case "${3:-rtsp}" in
  rtsp) ;;
  page) client=(--page) ;;
  mse) client=(--mse) ;;
  *) echo "latency.sh: the client is rtsp, page or mse, not ${3}" >&2; exit 2 ;;
esac
target/release/examples/glass_to_glass --size "${1:-1280x720}" --frames "${2:-300}" "${client[@]}" 2>/dev/null
