#!/usr/bin/env bash
# What watching the views costs the composed stream: `digiview serve` on a 3840x2160 still
# (image source), 1920x1080 out, motion detection on, x264; first nobody watches a view, then
# each of the four views' streams (1280x720) is pulled by one FFmpeg client. The health lines
# of each phase (the first of each left out: start-up, clients joining) give the composed
# stream's rate, the views' rate and each view's render time; each view's own stream's rate is
# counted by its FFmpeg client from the frames' timestamps. With several binaries (before
# and after a change), each round runs each binary once, in turn, since this machine's speed
# wanders; the table gives medians and ranges over every health line of every round.
# A BIN written BIN@idle runs its FFmpeg clients at the idle priority (serve_views.sh's
# PRIORITY): on a 2-core machine the four clients' decoding takes CPU time that viewers on the
# ground would not take from the head; compare BIN against BIN@idle to see how much.
#
# Usage: scripts/views_cost.sh ROUNDS BIN[@idle] [BIN[@idle]...]   (needs ffmpeg; docs/performance.md)
set -uo pipefail
rounds=${1:?rounds}
shift
[[ $# -ge 1 ]] || { echo "usage: $0 ROUNDS BIN[@idle] [BIN[@idle]...]" >&2; exit 2; }
work=$(mktemp -d)
trap 'rm -rf "$work"' EXIT
"${1%@idle}" synth --out "$work/fish.png" >/dev/null 2>&1 || { echo "views_cost: synth failed" >&2; exit 1; }
port=18654
here=$(dirname "$0")
for round in $(seq "$rounds"); do
  i=0
  for dv in "$@"; do
    i=$((i + 1))
    echo "views_cost: round $round, $dv" >&2
    : >"$work/serve-$i-$round.log"
    priority=same
    [[ $dv == *@idle ]] && priority=idle
    "$here/serve_views.sh" "${dv%@idle}" "$work/fish.png" "$work/serve-$i-$round.log" $port x264 \
      h264 ffmpeg $priority
    port=$((port + 1))
  done
done
python3 - "$work" "$@" <<'EOF'
import glob, re, statistics, sys
work, bins = sys.argv[1], sys.argv[2:]
def spread(xs):
    if not xs:
        return "-"
    return f"{statistics.median(xs):.1f} ({min(xs):.1f}-{max(xs):.1f})"
num = lambda pat, l: float(m.group(1)) if (m := re.search(pat, l)) else None
def stream_rates(log):
    """Each view's own stream's rate by its timestamps, past its first 5 s: FFmpeg's frames."""
    rates = []
    for cam in sorted(glob.glob(log + ".cam*")):
        pts = sorted(float(l.split(",")[2]) / 90000 for l in open(cam) if l[0] != "#" and l.count(",") >= 5)
        pts = [t for t in pts if pts and t >= pts[0] + 5]
        if len(pts) > 1:
            rates.append((len(pts) - 1) / (pts[-1] - pts[0]))
    return rates
print("| binary | phase | out fps | render ms | views fps | view render ms | dropped (renderer) | each view's stream (FFmpeg) fps | lines |")
print("|---|---|---:|---:|---:|---:|---:|---:|---:|")
for i, b in enumerate(bins, 1):
    phases = {"nobody watching": [], "four views watched": []}
    streams = []
    for log in sorted(glob.glob(f"{work}/serve-{i}-*.log")):
        streams += stream_rates(log)
        unwatched, watched = (open(log).read().split("=== watched") + [""])[:2]
        for name, part in (("nobody watching", unwatched), ("four views watched", watched)):
            phases[name] += [l for l in part.splitlines() if "health:" in l][1:]
    for name, lines in phases.items():
        col = lambda pat: [v for l in lines if (v := num(pat, l)) is not None]
        print(f"| {b} | {name} | {spread(col(r'out ([0-9.]+) fps'))} | {spread(col(r'render ([0-9.]+) ms'))} | "
              f"{spread(col(r'views alone ([0-9.]+) fps'))} | {spread(col(r'fps, ([0-9.]+) ms each'))} | "
              f"{spread(col(r'dropped ([0-9]+) '))} | {spread(streams) if 'watched' in name and 'nobody' not in name else '-'} | {len(lines)} |")
EOF
