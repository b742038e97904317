#!/usr/bin/env bash
# Side by side: FFmpeg's v360 filter and `digiview bench` on the same 3840x2160 fisheye
# (the CIL216 lens, equidistant, as FFmpeg's `fisheye` input assumes), on this machine.
# Usage: scripts/v360_compare.sh [frames]   (needs ffmpeg; docs/performance.md explains)
set -euo pipefail
frames=${1:-60}
work=$(mktemp -d)
trap 'rm -rf "$work"' EXIT
bin=${DIGIVIEW:-target/release/digiview}
"$bin" synth --out "$work/fish.png" >/dev/null 2>&1
ffmpeg -hide_banner -loglevel error -y -i "$work/fish.png" -pix_fmt yuv420p -f rawvideo "$work/fish.i420"
# CIL216 in lens.cal: f = 775 px/rad, so the 3840x2160 frame spans 283.9 x 159.7 degrees.
input=(-f rawvideo -pix_fmt yuv420p -s 3840x2160 -stream_loop $((frames - 1)) -i "$work/fish.i420")
fish="input=fisheye:ih_fov=283.9:iv_fov=159.7:output=flat:h_fov=90:v_fov=58.7:w=960:h=540"
view() { echo "v360=$fish:yaw=$1:pitch=$2"; }
run() {
  local label=$1 graph=$2
  local t0 t1
  t0=$(date +%s.%N)
  ffmpeg -hide_banner -loglevel error -y "${input[@]}" -filter_complex "$graph" -f null -
  t1=$(date +%s.%N)
  awk -v l="$label" -v n="$frames" -v a="$t0" -v b="$t1" \
    'BEGIN { printf "%-46s %7.1f ms/frame %6.1f fps\n", l, (b - a) * 1000 / n, n / (b - a) }'
}
echo "== FFmpeg $(ffmpeg -version | head -1 | cut -d' ' -f3), $frames frames, $(nproc) cores"
run "v360 one 960x540 view" "[0]$(view 0 -45)"
run "v360 four 960x540 views, split + xstack" \
  "[0]split=4[a][b][c][d];[a]$(view 0 0)[A];[b]$(view 90 -45)[B];[c]$(view 180 -45)[C];[d]$(view -90 -90)[D];[A][B][C][D]xstack=inputs=4:layout=0_0|w0_0|0_h0|w0_h0"
echo "== digiview bench, same input size, new attitude every frame (mip filter, the default)"
"$bin" bench --frames "$frames" --input-format i420 --output-format i420 2>/dev/null
# v360 interpolates bilinearly from the full-size frame and filters nothing: the same as
# DigiView's --filter bilinear.
echo "== digiview bench, as above with --filter bilinear (v360's own interpolation)"
"$bin" bench --frames "$frames" --input-format i420 --output-format i420 --filter bilinear \
  2>/dev/null
