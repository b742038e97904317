#!/usr/bin/env bash
# The figures docs/performance.md keeps for each machine, in one table, on whatever GPU this
# machine has (lavapipe where it has none):
# 1. `digiview bench`: 4K fisheye to the 1920x1080 four-view frame, NV12, I420 and RGBA in,
#    mip and bilinear, two interleaved rounds; NV12 turning at 90°/s without and with a
#    25 ms rolling-shutter readout corrected; NV12 mip on each backend (Vulkan, GL);
# 2. `digiview serve` on a 3840x2160 still (image source), 1920x1080 out, motion detection
#    on: the health lines with nobody watching a view, then with all four views' streams
#    (1280x720) pulled by RTSP clients, for the encoder `auto` picks and for x264, and for
#    H.265 (`auto`: a hardware H.265 encoder, else x265); a 25 ms readout corrected and KLV
#    published throughout;
# 3. glass-to-glass latency at 1280x720 over RTSP (examples/glass_to_glass.rs), three runs.
# Logs go to LOG_DIR (default: a new temporary folder); the table is printed last.
#
# Usage: scripts/gpu_figures.sh [BIN_DIR [LOG_DIR]]
#   BIN_DIR holds digiview and examples/glass_to_glass; without it both are built here.
#   On a machine without the Rust toolchain or GStreamer, use scripts/gpu_bundle.sh.
set -uo pipefail
if [[ $# -ge 1 ]]; then
  bin=$(realpath "$1")
else
  cd "$(dirname "$0")/.." || exit 1
  cargo build --release --locked --quiet --bin digiview --example glass_to_glass || exit 1
  bin=$PWD/target/release
fi
logs=$(realpath -m "${2:-$(mktemp -d)}")
mkdir -p "$logs"
dv=$bin/digiview
rows=$logs/rows.tsv
: >"$rows"
: >"$logs/latency.txt"
row() { printf '%s\n' "$(IFS=$'\t'; echo "$*")" >>"$rows"; }
export RUST_LOG=${RUST_LOG:-info}

# The machine.
gpu=$("$dv" doctor --help >/dev/null 2>&1 && "$dv" doctor 2>/dev/null | awk '$2 == "gpu" {$1=$2=""; print substr($0, 3); exit}')
row machine "$(nproc) cores; GPU ${gpu:-none found}"
if command -v nvidia-smi >/dev/null; then
  row driver "$(nvidia-smi --query-gpu=name,driver_version,memory.total --format=csv,noheader | head -1)"
fi
row codecs "$(gst-inspect-1.0 2>/dev/null | grep -oE '(nv[a-z0-9]*h26[45](enc|dec)|x26[45]enc|openh264dec|avdec_h26[45]|vaapih26[45]enc)' | sort -u | tr '\n' ' ')"

# 1. The renderer; then NV12 with the vehicle turning at 90°/s, without and with a 25 ms
# rolling-shutter readout corrected.
for round in 1 2; do
  for fmt in nv12 i420 rgba; do
    for filter in mip bilinear; do
      "$dv" bench --frames 300 --warmup 20 --json --input-format "$fmt" --filter "$filter" \
        >"$logs/bench-$fmt-$filter-$round.json" 2>>"$logs/bench.log" ||
        echo "gpu_figures: bench $fmt $filter failed (bench.log)" >&2
    done
  done
  "$dv" bench --frames 300 --warmup 20 --json --input-format nv12 --backend vulkan,gl \
    >"$logs/backends-$round.json" 2>>"$logs/bench.log" ||
    echo "gpu_figures: bench on each backend failed (bench.log)" >&2
  for readout in 0 25; do
    "$dv" bench --frames 300 --warmup 20 --json --input-format nv12 --turn yaw=90 \
      --readout-ms "$readout" >"$logs/shutter-$readout-$round.json" 2>>"$logs/bench.log" ||
      echo "gpu_figures: bench with readout $readout failed (bench.log)" >&2
  done
done

# 2. The head on a 4K still, views unwatched and watched, with a 25 ms rolling shutter
# corrected and the KLV metadata made for an MPEG-TS relay (UDP to this host).
export SERVE_TOP='publish = ["udp://127.0.0.1:5600"]' SERVE_TABLES=$'[readout]\ntime_ms = 25'

still=$logs/fisheye-3840x2160.png
"$dv" synth --out "$still" >/dev/null 2>>"$logs/synth.log" || echo "gpu_figures: synth failed" >&2
port=18554
serve_phases() { # encoder kind, codec
  local log=$logs/serve-$1-$2.log
  : >"$log"
  # The bundle has GStreamer and no FFmpeg: gst-launch pulls the views.
  "$(dirname "$0")/serve_views.sh" "$dv" "$still" "$log" $port "$1" "$2" gst
  port=$((port + 1))
}
serve_phases auto h264
grep -q 'encoder: x264enc' "$logs/serve-auto-h264.log" || serve_phases x264 h264
serve_phases auto h265

# 3. Glass to glass.
# The best decoder installed (decodebin's pick: NVDEC where the GPU has one), then the
# software decoder in the bundle, then the best again.
run=0
for decoder in decodebin openh264dec decodebin; do
  run=$((run + 1))
  "$bin/examples/glass_to_glass" --size 1280x720 --frames 300 --decoder "$decoder" \
    >>"$logs/latency.txt" 2>"$logs/latency-$run.log" ||
    echo "gpu_figures: latency run $run ($decoder) failed (latency-$run.log)" >&2
  grep -h 'decoded with' "$logs/latency-$run.log" >>"$logs/latency.txt"
done

python3 - "$logs" <<'EOF' | tee "$logs/table.md"
import glob, json, os, re, statistics, sys
logs = sys.argv[1]
def spread(xs, unit=""):
    if not xs:
        return "-"
    return f"{statistics.median(xs):.1f}{unit} ({min(xs):.1f}-{max(xs):.1f})"
print("| what | figure |\n|---|---|")
for line in open(os.path.join(logs, "rows.tsv")):
    k, v = line.rstrip("\n").split("\t", 1)
    print(f"| {k} | {v} |")
print("\n| bench (4K in, 1920x1080 I420 out, 300 frames) | upload ms | render ms | readback ms | staged ms | pipelined fps |")
print("|---|---:|---:|---:|---:|---:|")
def runs_of(pattern):
    """The bench reports matching `pattern` in the logs (a failed run's empty file left out)."""
    runs = []
    for f in sorted(glob.glob(f"{logs}/{pattern}")):
        try:
            runs.append(json.load(open(f)))
        except ValueError:
            pass
    return runs
for fmt in ("nv12", "i420", "rgba"):
    for filt in ("mip", "bilinear"):
        runs = runs_of(f"bench-{fmt}-{filt}-*.json")
        s = lambda k: [r["staged"][k] for r in runs]
        fps = [r["pipelined_fps"] for r in runs]
        print(f"| {fmt.upper()} {filt} | {spread(s('upload_ms'))} | {spread(s('render_ms'))} | "
              f"{spread(s('readback_ms'))} | {spread(s('total_ms'))} | {spread(fps)} |")
print("\n| bench, NV12 mip, each backend | adapter | render ms | staged ms | pipelined fps |")
print("|---|---|---:|---:|---:|")
by_backend = {}
for report in [r for run in runs_of("backends-*.json") for r in run]:
    by_backend.setdefault(report["backend"], []).append(report)
for backend, runs in by_backend.items():
    s = lambda k: [r["staged"][k] for r in runs]
    print(f"| {backend} | {runs[0]['adapter']} | {spread(s('render_ms'))} | {spread(s('total_ms'))} | "
          f"{spread([r['pipelined_fps'] for r in runs])} |")
print("\n| bench, NV12 mip turning at 90°/s | render ms | staged ms | pipelined fps |")
print("|---|---:|---:|---:|")
for readout in ("0", "25"):
    runs = runs_of(f"shutter-{readout}-*.json")
    s = lambda k: [r["staged"][k] for r in runs]
    print(f"| readout {readout} ms | {spread(s('render_ms'))} | {spread(s('total_ms'))} | "
          f"{spread([r['pipelined_fps'] for r in runs])} |")
print("\n| serve, 3840x2160 still to 1920x1080, detection on, 25 ms readout, KLV | encoder | out fps | render ms | encode ms | views fps | view render ms | dropped (renderer) |")
print("|---|---|---:|---:|---:|---:|---:|---:|")
num = lambda pat, l: float(m.group(1)) if (m := re.search(pat, l)) else None
last_stages = []
for log in sorted(glob.glob(f"{logs}/serve-*.log")):
    text = open(log).read()
    enc = (re.search(r"encoder: ([a-z0-9_]+enc)\b", text) or [None, "?"])[1]
    stages = re.findall(r"latency over .*", text)
    if stages:
        last_stages.append(f"{enc}: {stages[-1]}")
    unwatched, watched = (text.split("=== watched") + [""])[:2]
    for name, part in (("nobody watching a view", unwatched), ("four views watched", watched)):
        # The first line of each phase is start-up or the clients joining: left out.
        lines = [l for l in part.splitlines() if "health:" in l][1:]
        col = lambda pat: [v for l in lines if (v := num(pat, l)) is not None]
        print(f"| {name} | {enc} | {spread(col(r'out ([0-9.]+) fps'))} | "
              f"{spread(col(r'render ([0-9.]+) ms'))} | {spread(col(r'encode ([0-9.]+) ms'))} | "
              f"{spread(col(r'views alone ([0-9.]+) fps'))} | {spread(col(r'fps, ([0-9.]+) ms each'))} | "
              f"{spread(col(r'dropped ([0-9]+) '))} |")
for l in last_stages:
    print(f"\n{l}")
print("\n| glass to glass, 1280x720 over RTSP |")
print("|---|")
for l in open(os.path.join(logs, "latency.txt")) if os.path.exists(os.path.join(logs, "latency.txt")) else []:
    print(f"| {l.strip()} |")
EOF
