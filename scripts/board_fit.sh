#!/usr/bin/env bash
# What this machine holds at 30 fps on each GPU backend, as a guide to the boards
# (docs/onboard.md): `digiview serve` on a 3840x2160 still (image source, 30 fps), motion
# detection on, x264, for each backend and output size; in phases of 25 s, 0, 1, 2, 3 and 4
# of the views' own streams (1280x720) are pulled by FFmpeg clients. For each phase: the
# composed stream's rate (health lines, the first of each phase left out) and the slowest
# watched view's stream rate (its FFmpeg client's timestamps, its first 5 s left out).
#
# Usage: scripts/board_fit.sh DIGIVIEW [BACKENDS [SIZES]]
#   BACKENDS: default "vulkan gl"; SIZES: default "1280x720 1920x1080".
set -uo pipefail
dv=${1:?usage: $0 DIGIVIEW [BACKENDS [SIZES]]}
backends=${2:-vulkan gl}
sizes=${3:-1280x720 1920x1080}
work=$(mktemp -d)
trap 'rm -rf "$work"' EXIT
"$dv" synth --out "$work/fish.png" >/dev/null 2>&1 || { echo "board_fit: synth failed" >&2; exit 1; }
. "$(dirname "$0")/serve_config.sh"
port=18754
for backend in $backends; do
  for size in $sizes; do
    log="$work/$backend-$size.log"
    cfg="$work/$backend-$size.toml"
    SERVE_TOP="gpu_backend = \"$backend\"" serve_config "$cfg" "$work/fish.png" $port x264 h264
    echo "board_fit: $backend $size" >&2
    RUST_LOG=info "$dv" serve --config "$cfg" --size "$size" --http off >/dev/null 2>>"$log" &
    serve=$!
    sleep 12
    if ! kill -0 $serve 2>/dev/null; then
      echo "board_fit: serve $backend $size ended: $(tail -n 1 "$log")" >&2
      port=$((port + 1))
      continue
    fi
    for watched in 0 1 2 3 4; do
      echo "=== watched $watched" >>"$log"
      pids=()
      for cam in $(seq 0 $((watched - 1))); do
        ffmpeg -nostdin -loglevel error -rtsp_transport tcp \
          -i "rtsp://127.0.0.1:$port/digiview/cam$cam" -fps_mode passthrough \
          -enc_time_base:v 1:90000 -f framemd5 "$log.$watched.cam$cam" >/dev/null 2>&1 &
        pids+=($!)
      done
      sleep 25
      # (A bare `wait` would wait for serve too.)
      if [[ ${#pids[@]} -gt 0 ]]; then
        kill "${pids[@]}" 2>/dev/null
        wait "${pids[@]}" 2>/dev/null
      fi
    done
    kill -INT $serve 2>/dev/null
    wait $serve 2>/dev/null
    port=$((port + 1))
  done
done
python3 - "$work" "$backends" "$sizes" <<'EOF'
import glob, re, statistics, sys
work, backends, sizes = sys.argv[1], sys.argv[2].split(), sys.argv[3].split()
def spread(xs):
    return f"{statistics.median(xs):.1f} ({min(xs):.1f}-{max(xs):.1f})" if xs else "-"
def stream_rate(path):
    """A view's own stream's rate by its timestamps, past its first 5 s."""
    pts = sorted(float(l.split(",")[2]) / 90000 for l in open(path) if l[0] != "#" and l.count(",") >= 5)
    pts = [t for t in pts if t >= pts[0] + 5] if pts else []
    return (len(pts) - 1) / (pts[-1] - pts[0]) if len(pts) > 1 else 0.0
print("| backend | output | views watched | composed fps | slowest view's stream fps | render ms | holds 30 |")
print("|---|---|---:|---:|---:|---:|---|")
for backend in backends:
    for size in sizes:
        log = f"{work}/{backend}-{size}.log"
        if "=== watched" not in open(log).read():
            continue
        parts = open(log).read().split("=== watched ")[1:]
        for part in parts:
            watched = int(part.split("\n", 1)[0])
            lines = [l for l in part.splitlines() if "health:" in l][1:]
            out = [float(m.group(1)) for l in lines if (m := re.search(r"out ([0-9.]+) fps", l))]
            render = [float(m.group(1)) for l in lines if (m := re.search(r"render ([0-9.]+) ms", l))]
            views = [stream_rate(p) for p in sorted(glob.glob(f"{log}.{watched}.cam*"))]
            slowest = min(views) if views else None
            holds = bool(out) and statistics.median(out) >= 29.5 and (slowest is None or slowest >= 29.0)
            print(f"| {backend} | {size} | {watched} | {spread(out)} | "
                  f"{'-' if slowest is None else f'{slowest:.1f}'} | {spread(render)} | {'yes' if holds else 'no'} |")
EOF
