#!/usr/bin/env bash
# Side by side: FFmpeg's v360 filter and `digiview bench` on the same 3840x2160 fisheye
# (the CIL216 lens, equidistant, as FFmpeg's `fisheye` input assumes), on this machine, from
# I420 and from the camera-native NV12 (which v360 cannot read: FFmpeg converts it first).
# v360's figure is its steady state, from FFmpeg's progress reports past its 10th frame, so its
# start-up and map building (about 0.3 s) are left out, as `bench` leaves out its warm-up.
# The machine's speed wanders by a third from minute to minute, so every case runs once per
# round, the rounds one after another, and each line gives the median over the rounds and
# their range.
# Usage: scripts/v360_compare.sh [frames] [rounds]   (needs ffmpeg; docs/performance.md)
set -euo pipefail
frames=${1:-120}
rounds=${2:-3}
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
four="[0]split=4[a][b][c][d];[a]$(view 0 0)[A];[b]$(view 90 -45)[B];[c]$(view 180 -45)[C];[d]$(view -90 -90)[D];[A][B][C][D]xstack=inputs=4:layout=0_0|w0_0|0_h0|w0_h0"
# The views `bench` draws (its default state, layout 4): four 540x540 squares, 90° each way,
# yaw 0, 90, 180 and 270°, 30° down, 2x2 (DigiView also fills the rest of its 1920x1080 frame
# with background and detection tiles). The issue's 960x540 views above have 1.8 times the
# pixels; layouts hold square views, so these are the views DigiView can draw alike.
square="input=fisheye:ih_fov=283.9:iv_fov=159.7:output=flat:h_fov=90:v_fov=90:w=540:h=540"
same="[0]split=4[a][b][c][d];[a]v360=$square:yaw=0:pitch=-30[A];[b]v360=$square:yaw=90:pitch=-30[B];[c]v360=$square:yaw=180:pitch=-30[C];[d]v360=$square:yaw=-90:pitch=-30[D];[A][B][C][D]xstack=inputs=4:layout=0_0|w0_0|0_h0|w0_h0"
# What DigiView does every frame: every view re-aimed. v360 takes new angles as commands
# (sendcmd, one per frame at the input's 25 fps) and rebuilds its map for each.
awk 'BEGIN { for (i = 0; i < 400; i++) { y = (i * 0.7) % 360 - 180
  printf "%.2f v360@A yaw %.2f, v360@B yaw %.2f, v360@C yaw %.2f, v360@D yaw %.2f;\n", i / 25, y, y, y, y } }' \
  >"$work/aim.cmd"
moving="[0]sendcmd=f=$work/aim.cmd,split=4[a][b][c][d];[a]v360@A=$fish:yaw=0:pitch=0[A];[b]v360@B=$fish:yaw=90:pitch=-45[B];[c]v360@C=$fish:yaw=180:pitch=-45[C];[d]v360@D=$fish:yaw=-90:pitch=-90[D];[A][B][C][D]xstack=inputs=4:layout=0_0|w0_0|0_h0|w0_h0"

# Steady-state ms per frame of `graph` on `fmt` input, over n frames, appended to file `key`.
# FFmpeg reports its progress (frames done) every 0.1 s; each report is stamped as it arrives
# and the rate is taken from the first report past frame 10 to the last, in one run, so
# start-up and map building are left out without subtracting two noisy runs.
v360() {
  local key=$1 fmt=$2 graph=$3 n=${4:-$frames}
  ffmpeg -hide_banner -loglevel error -nostats -y -f rawvideo -pix_fmt "$fmt" -s 3840x2160 \
    -stream_loop $((n + 9)) -i "$work/fish.$fmt" -filter_complex "$graph" \
    -progress pipe:1 -stats_period 0.1 -f null - |
    python3 -c '
import sys, time
marks = []
for line in sys.stdin:
    if line.startswith("frame="):
        marks.append((int(line.split("=")[1]), time.monotonic()))
marks = [m for m in marks if m[0] >= 10]
if len(marks) < 2:
    sys.exit("v360_compare: FFmpeg reported no progress past its 10th frame")
(f0, t0), (f1, t1) = marks[0], marks[-1]
print((t1 - t0) * 1000 / max(f1 - f0, 1))' >>"$work/$key"
}
# DigiView's pipelined ms per frame and staged total, appended to file `key`.
digiview() {
  local key=$1 input=$2 filter=$3
  "$bin" bench --frames "$frames" --input-format "$input" --output-format i420 \
    --filter "$filter" --json 2>/dev/null |
    python3 -c 'import json, sys; d = json.load(sys.stdin)
print(1000 / d["pipelined_fps"], d["staged"]["total_ms"])' >>"$work/$key"
}
for r in $(seq "$rounds"); do
  echo "round $r of $rounds" >&2
  v360 same_i420 yuv420p "$same"
  digiview dv_i420_bilinear i420 bilinear
  v360 same_nv12 nv12 "$same"
  digiview dv_nv12_bilinear nv12 bilinear
  v360 four_i420 yuv420p "$four"
  v360 four_nv12 nv12 "$four"
  digiview dv_i420_mip i420 mip
  digiview dv_nv12_mip nv12 mip
done
v360 moving_i420 yuv420p "$moving" 30

# Median and range of column `col` of file `key`.
stats() {
  python3 - "$work/$1" "${2:-1}" <<'EOF'
import statistics, sys
v = [float(l.split()[int(sys.argv[2]) - 1]) for l in open(sys.argv[1]) if l.strip()]
print("%6.1f ms (%.1f to %.1f)" % (statistics.median(v), min(v), max(v)))
EOF
}
echo "== FFmpeg $(ffmpeg -version | head -1 | cut -d' ' -f3) and digiview, $frames frames, $(nproc) cores, $rounds rounds interleaved: medians (range), ms per frame"
echo "v360, bench's four 540x540 views, fixed angles, I420 in     $(stats same_i420)"
echo "v360, bench's four 540x540 views, fixed angles, NV12 in     $(stats same_nv12)"
echo "v360, four 960x540 views, fixed angles, I420 in             $(stats four_i420)"
echo "v360, four 960x540 views, fixed angles, NV12 in             $(stats four_nv12)"
echo "v360, four views re-aimed every frame, I420 in (one run)    $(stats moving_i420)"
for input in i420 nv12; do
  for filter in bilinear mip; do
    # v360 interpolates bilinearly from the full-size frame and filters nothing: the same
    # as DigiView's --filter bilinear. DigiView's default is the mip filter.
    echo "digiview, new attitude every frame, $input in, $filter: pipelined $(stats dv_${input}_$filter 1), staged $(stats dv_${input}_$filter 2)"
  done
done
