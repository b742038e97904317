#!/usr/bin/env python3
"""The ground station of scripts/soak.sh, written with pymavlink (not DigiView's own crate).

Talks to DigiView's MAVLink port as QGroundControl does for as long as it is asked to: a
HEARTBEAT a second, and a command three times a second to the cameras in turn: a request
for CAMERA_CAPTURE_STATUS, one for VIDEO_STREAM_INFORMATION (unused parameters NaN, as MAVSDK
sends them), then MAV_CMD_SET_CAMERA_ZOOM to a new zoom level, as COMMAND_INT every other
time. (The views' gimbals are the autopilot's to point in the soak: they are gimbal devices.)
It counts what was asked, what was answered and how, and the longest gap in each camera's
heartbeats. It prints a line a minute and, at the end, one JSON summary line.

Usage: soak_gcs.py PORT SECONDS
"""

import json
import math
import sys
import time

from pymavlink import mavutil

CAMERAS = range(100, 104)
VIDEO_STREAM_INFORMATION = 269
CAMERA_CAPTURE_STATUS = 262


def main():
    port, seconds = int(sys.argv[1]), float(sys.argv[2])
    link = mavutil.mavlink_connection(
        f"udpout:127.0.0.1:{port}", source_system=255, source_component=190, dialect="common"
    )
    m = link.mav
    start = time.monotonic()
    next_beat = next_ask = next_report = start
    asked = answered = streams = 0
    results = {}
    last_beat = {}
    longest_gap = {c: 0.0 for c in CAMERAS}
    turn = 0
    while time.monotonic() - start < seconds:
        now = time.monotonic()
        if now >= next_beat:
            m.heartbeat_send(mavutil.mavlink.MAV_TYPE_GCS, mavutil.mavlink.MAV_AUTOPILOT_INVALID,
                             0, 0, mavutil.mavlink.MAV_STATE_ACTIVE)
            next_beat += 1.0
        if now >= next_ask:
            cam = CAMERAS[(turn // 3) % 4]
            if turn % 3 < 2:
                msg_id = (CAMERA_CAPTURE_STATUS, VIDEO_STREAM_INFORMATION)[turn % 3]
                m.command_long_send(1, cam, mavutil.mavlink.MAV_CMD_REQUEST_MESSAGE, 0,
                                    msg_id, math.nan, math.nan, math.nan, math.nan, math.nan, 0)
            else:
                level = 50.0 + 50.0 * math.sin(turn / 7)
                cmd = mavutil.mavlink.MAV_CMD_SET_CAMERA_ZOOM
                if turn % 2:
                    m.command_int_send(1, cam, 0, cmd, 0, 0, 2, level, math.nan, math.nan, 0, 0, 0)
                else:
                    m.command_long_send(1, cam, cmd, 0, 2, level, math.nan, math.nan, 0, 0, 0)
            asked += 1
            turn += 1
            next_ask += 1.0 / 3.0
        if now >= next_report:
            if now > start:
                print(f"gcs: {int((now - start) / 60)} min: asked {asked}, answered {answered}, "
                      f"{streams} stream answers, results {results}, longest heartbeat gap "
                      f"{max(longest_gap.values()):.1f} s", flush=True)
            next_report += 60.0
        msg = link.recv_match(blocking=True, timeout=0.05)
        if msg is None:
            continue
        comp = msg.get_srcComponent()
        kind = msg.get_type()
        if kind == "HEARTBEAT" and comp in CAMERAS:
            t = time.monotonic()
            if comp in last_beat:
                longest_gap[comp] = max(longest_gap[comp], t - last_beat[comp])
            last_beat[comp] = t
        elif kind == "COMMAND_ACK" and comp in CAMERAS:
            answered += 1
            name = mavutil.mavlink.enums["MAV_RESULT"][msg.result].name
            results[name] = results.get(name, 0) + 1
        elif kind == "VIDEO_STREAM_INFORMATION":
            streams += 1
    end = time.monotonic()
    for c in CAMERAS:  # a camera silent at the end counts its silence too
        if c in last_beat:
            longest_gap[c] = max(longest_gap[c], end - last_beat[c])
    print(json.dumps({
        "asked": asked,
        "answered": answered,
        "results": results,
        "stream_answers": streams,
        "cameras_heard": sorted(last_beat),
        "longest_heartbeat_gap_s": round(max(longest_gap.values()), 2),
    }), flush=True)


if __name__ == "__main__":
    main()
