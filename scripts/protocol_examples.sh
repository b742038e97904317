#!/usr/bin/env bash
# Prints the annotated request/reply examples of docs/protocol.md: starts
# `digiview serve --no-video` on a free port and runs `digiview ctl --hex` once per
# parameter type. Usage: bash scripts/protocol_examples.sh > /tmp/examples.md
set -euo pipefail
cd "$(dirname "$0")/.."
bin=target/release/digiview
out=$(mktemp)
"$bin" serve --no-video --control 127.0.0.1:0 --http off --track yaw=10deg,pitch=-40deg,size=3deg,score=90 >"$out" 2>/dev/null &
server=$!
trap 'kill $server 2>/dev/null || true; rm -f "$out"' EXIT
for _ in $(seq 50); do [ -s "$out" ] && break; sleep 0.1; done
addr=$(awk '{print $4}' "$out")

example() {
    local title=$1; shift
    printf '### %s\n\n`digiview ctl --hex %s`\n\n```\n' "$title" "$*"
    "$bin" ctl --addr "$addr" --hex "$@" 2>&1 >/dev/null
    printf '```\n\n'
}

example "SYSTEM_STATUS (0)" get system_status
example "VIDEO_OUTPUT (1)" get video_output
example "CAPTURE (2)" get capture
example "DETECTION (3)" get detection
example "DETECTED_ROI (4)" get detected_roi index=0
example "LENS (5)" set lens lens_id=0
example "CAM_EULER (6)" get cam_euler cam=1
example "CAM_ZOOM (7)" get cam_zoom cam=1
example "CAM_LOCK_FLAGS (8)" set cam_lock_flags cam=2 flags=7
example "CAM_CONTROL_MODE (9)" get cam_control_mode cam=0
example "CAM_CROP_MODE (10)" set cam_crop_mode cam=3 mode=2
example "CAM_OFFSET (11)" get cam_offset cam=0 x=0.25 y=0.1 frame_rel=0
example "CAM_FOV (12)" set cam_fov cam=0 fov=60deg
example "CAM_TARGET (13)" get cam_target cam=0 x=0 y=0.25
example "CAM_SENSOR (14)" get cam_sensor
example "GENERAL_SETTINGS (15)" get general_settings
example "An error: a cam_id outside 0..=3" get cam_fov cam=4
