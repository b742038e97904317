#!/usr/bin/env bash
# Side by side: FFmpeg's v360 filter and `digiview bench` on the same 3840x2160 fisheye
# (the CIL216 lens, equidistant, as FFmpeg's `fisheye` input assumes), on this machine, from
# I420 and from the camera-native NV12 (which v360 cannot read: FFmpeg converts it first).
# v360's figure is its steady state: the time of a run of 10 + N frames less that of a run of
# 10, over N, so FFmpeg's start-up and map building (about 0.3 s) are left out, as `bench`
# leaves out its warm-up.
# Usage: scripts/v360_compare.sh [frames]   (needs ffmpeg; docs/performance.md explains)
set -euo pipefail
frames=${1:-120}
work=$(mktemp -d)
trap 'rm -rf "$work"' EXIT
bin=${DIGIVIEW:-target/release/digiview}
"$bin" synth --out "$work/fish.png" >/dev/null 2>&1
for fmt in yuv420p nv12; do
  ffmpeg -hide_banner -loglevel error -y -i "$work/fish.png" -pix_fmt $fmt -f rawvideo "$work/fish.$fmt"
done
# CIL216 in lens.cal: f = 775 px/rad, so the 3840x2160 frame spans 283.9 x 159.7 degrees.
fish="input=fisheye:ih_fov=283.9:iv_fov=159.7:output=flat:h_fov=90:v_fov=58.7:w=960:h=540"
view() { echo "v360=$fish:yaw=$1:pitch=$2"; }
one="[0]$(view 0 -45)"
four="[0]split=4[a][b][c][d];[a]$(view 0 0)[A];[b]$(view 90 -45)[B];[c]$(view 180 -45)[C];[d]$(view -90 -90)[D];[A][B][C][D]xstack=inputs=4:layout=0_0|w0_0|0_h0|w0_h0"
# Seconds to run `graph` over n frames of the input in pixel format `fmt`.
seconds() {
  local fmt=$1 n=$2 graph=$3 t0 t1
  t0=$(date +%s.%N)
  ffmpeg -hide_banner -loglevel error -y -f rawvideo -pix_fmt "$fmt" -s 3840x2160 \
    -stream_loop $((n - 1)) -i "$work/fish.$fmt" -filter_complex "$graph" -f null -
  t1=$(date +%s.%N)
  echo "$t1 - $t0" | bc -l
}
# Steady-state ms per frame of `graph` on `fmt` input, over n frames (default: frames).
run() {
  local label=$1 fmt=$2 graph=$3 n=${4:-$frames} short long
  short=$(seconds "$fmt" 10 "$graph")
  long=$(seconds "$fmt" $((n + 10)) "$graph")
  awk -v l="$label" -v n="$n" -v a="$short" -v b="$long" \
    'BEGIN { ms = (b - a) * 1000 / n; printf "%-52s %6.1f ms/frame %6.1f fps\n", l, ms, 1000 / ms }'
}
echo "== FFmpeg $(ffmpeg -version | head -1 | cut -d' ' -f3), $frames frames, $(nproc) cores, steady state"
run "v360 one 960x540 view, I420 in" yuv420p "$one"
run "v360 four 960x540 views, split + xstack, I420 in" yuv420p "$four"
run "v360 four 960x540 views, split + xstack, NV12 in" nv12 "$four"
# The views `bench` draws (its default state, layout 4): four 540x540 squares, 90° each way,
# yaw 0, 90, 180 and 270°, 30° down, 2x2 (DigiView also fills the rest of its 1920x1080 frame
# with background and detection tiles). The 960x540 views above have 1.8 times the
# pixels.
square="input=fisheye:ih_fov=283.9:iv_fov=159.7:output=flat:h_fov=90:v_fov=90:w=540:h=540"
same="[0]split=4[a][b][c][d];[a]v360=$square:yaw=0:pitch=-30[A];[b]v360=$square:yaw=90:pitch=-30[B];[c]v360=$square:yaw=180:pitch=-30[C];[d]v360=$square:yaw=-90:pitch=-30[D];[A][B][C][D]xstack=inputs=4:layout=0_0|w0_0|0_h0|w0_h0"
run "v360 bench's four 540x540 views, I420 in" yuv420p "$same"
run "v360 bench's four 540x540 views, NV12 in" nv12 "$same"
# What DigiView does every frame: every view re-aimed. v360 takes new angles as commands
# (sendcmd, one per frame at the input's 25 fps) and rebuilds its map for each; 30 frames
# are plenty at this speed.
awk 'BEGIN { for (i = 0; i < 400; i++) { y = (i * 0.7) % 360 - 180
  printf "%.2f v360@A yaw %.2f, v360@B yaw %.2f, v360@C yaw %.2f, v360@D yaw %.2f;\n", i / 25, y, y, y, y } }' \
  >"$work/aim.cmd"
moving="[0]sendcmd=f=$work/aim.cmd,split=4[a][b][c][d];[a]v360@A=$fish:yaw=0:pitch=0[A];[b]v360@B=$fish:yaw=90:pitch=-45[B];[c]v360@C=$fish:yaw=180:pitch=-45[C];[d]v360@D=$fish:yaw=-90:pitch=-90[D];[A][B][C][D]xstack=inputs=4:layout=0_0|w0_0|0_h0|w0_h0"
run "v360 four views re-aimed every frame, I420 in" yuv420p "$moving" 30
for input in i420 nv12; do
  for filter in mip bilinear; do
    # v360 interpolates bilinearly from the full-size frame and filters nothing: the same
    # as DigiView's --filter bilinear. DigiView's default is the mip filter.
    echo "== digiview bench, $input in, I420 out, new attitude every frame, --filter $filter"
    "$bin" bench --frames "$frames" --input-format $input --output-format i420 \
      --filter $filter 2>/dev/null | grep -E "upload|render|readback|total|pipelined"
  done
done
