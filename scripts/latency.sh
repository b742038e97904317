#!/usr/bin/env bash
# Glass-to-glass latency on this host: `digiview serve` on the demo with each frame's capture
# time drawn as a barcode, pulled over RTSP (rtspsrc, latency 0) and decoded on the same
# host; prints the median and spread. Usage: scripts/latency.sh [WxH] [frames]
set -euo pipefail
cd "$(dirname "$0")/.."
cargo build --release --quiet --bin digiview --example glass_to_glass
target/release/examples/glass_to_glass --size "${1:-1280x720}" --frames "${2:-300}" 2>/dev/null
