#!/usr/bin/env bash
# A 3840x2160 fisheye clip for `scripts/soak.sh` on a small machine: 4 s at 30 fps of the
# synthetic world (`digiview synth`), its movers moving and the vehicle turning 0.1° a frame,
# written as raw YUV 4:2:0 (Y4M, BT.709 limited range, as a camera gives it). A raw file costs
# the head what a camera's frames do, a copy; the flying demo's frames are drawn on the CPU
# and a compressed file's are decoded there, each taking most of a 2-core machine at 4K.
# The file is 1.5 GB; `serve --source file:PATH` loops it (a cut back every 4 s).
# Usage: scripts/soak_clip.sh OUT.y4m [frames]
set -euo pipefail
cd "$(dirname "$0")/.."
out=${1:?usage: scripts/soak_clip.sh OUT.y4m [frames]}
frames=${2:-120}
cargo build --release --quiet --bin digiview
dir=$(mktemp -d /tmp/digiview-clip.XXXX)
trap 'rm -rf "$dir"' EXIT
for ((i = 0; i < frames; i++)); do
  printf '\rsoak_clip: frame %d of %d' $((i + 1)) "$frames"
  t=$(awk -v i="$i" 'BEGIN { printf "%.4f", i / 30 }')
  yaw=$(awk -v i="$i" 'BEGIN { printf "%.2f", i * 0.1 }')
  target/release/digiview synth --out "$dir/$(printf %04d "$i").png" --sensor 3840x2160 \
    --time "$t" --attitude "yaw=${yaw}deg,pitch=0deg,roll=0deg" >/dev/null 2>"$dir/synth.err" ||
    { echo; cat "$dir/synth.err"; exit 1; }
done
echo
ffmpeg -v error -y -framerate 30 -i "$dir/%04d.png" -pix_fmt yuv420p -color_range tv \
  -colorspace bt709 -strict -1 "$out"
echo "soak_clip: wrote $out ($frames frames, $(du -h "$out" | cut -f1))"
