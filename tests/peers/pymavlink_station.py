#!/usr/bin/env python3
"""A ground station written with pymavlink (not DigiView's own crate), for
tests/it/pymavlink.rs. Against camera 101 of a running `serve` (the demo hovering):

- REQUEST_MESSAGE for VIDEO_STREAM_INFORMATION (269) and VIDEO_STREAM_STATUS (270) with NaN,
  and with 0, in every unused parameter: the ACK and the stream ids that follow;
- each gimbal and camera command sent as COMMAND_LONG and, from the same starting state, as
  COMMAND_INT: the ACK of each and what the camera reports after it (the gimbal's attitude
  quaternion, the zoom level, the camera mode);
- CAMERA_TRACK_POINT on the centre of the picture with the view turned 45 degrees down:
  the tracking statuses, then CAMERA_STOP_TRACKING;
- CAMERA_FOV_STATUS with the view turned so again, left so for the test.

Prints one JSON object per line. Usage: pymavlink_station.py PORT LAT LON ALT, the point on
the ground (degrees, metres above sea level) to point a view at.
"""

import json
import math
import sys
import time

from pymavlink import mavutil

CAMERA = 101
NAN = math.nan


def main():
    link = mavutil.mavlink_connection(f"udpout:127.0.0.1:{sys.argv[1]}", source_system=255,
                                      source_component=190, dialect="common")
    m = link.mav
    m.heartbeat_send(mavutil.mavlink.MAV_TYPE_GCS, mavutil.mavlink.MAV_AUTOPILOT_INVALID, 0, 0, 4)
    beat = link.recv_match(type="HEARTBEAT", blocking=True, timeout=10,
                           condition=f"HEARTBEAT.get_srcComponent() == {CAMERA}")
    if beat is None:
        print(json.dumps({"event": "no camera"}), flush=True)
        return 1
    system = beat.get_srcSystem()

    def answer(command, wait=1.0):
        """The ACK's result for `command`, and every other message the camera sent by then."""
        m.heartbeat_send(mavutil.mavlink.MAV_TYPE_GCS, mavutil.mavlink.MAV_AUTOPILOT_INVALID, 0,
                         0, 4)
        result, then = None, []
        end = time.monotonic() + wait
        while time.monotonic() < end:
            msg = link.recv_match(blocking=True, timeout=0.05)
            if msg is None or msg.get_srcComponent() != CAMERA:
                continue
            if msg.get_type() == "COMMAND_ACK" and msg.command == command:
                result = mavutil.mavlink.enums["MAV_RESULT"][msg.result].name
                end = min(end, time.monotonic() + 0.3)
            elif msg.get_type() != "HEARTBEAT":
                then.append(msg)
        return result, then

    def long(command, *p):
        p = list(p) + [0.0] * (7 - len(p))
        m.command_long_send(system, CAMERA, command, 0, *p)
        return answer(command)

    def int_(command, frame, *p, x=0, y=0, z=0.0):
        p = list(p) + [0.0] * (4 - len(p))
        m.command_int_send(system, CAMERA, frame, command, 0, 0, *p, x, y, z)
        return answer(command)

    def attitude():
        _, then = long(mavutil.mavlink.MAV_CMD_REQUEST_MESSAGE, 285)
        msg = [x for x in then if x.get_type() == "GIMBAL_DEVICE_ATTITUDE_STATUS"][-1]
        return [round(v, 4) for v in msg.q]

    def settings():
        _, then = long(mavutil.mavlink.MAV_CMD_REQUEST_MESSAGE, 260)
        s = [x for x in then if x.get_type() == "CAMERA_SETTINGS"][-1]
        return {"zoom": round(s.zoomLevel, 3), "mode": s.mode_id}

    # Streams: NaN and 0 in what is unused.
    for msg_id in (269, 270):
        for unused in (NAN, 0.0):
            result, then = long(mavutil.mavlink.MAV_CMD_REQUEST_MESSAGE, msg_id, unused, unused,
                                unused, unused, unused, unused)
            ids = sorted({x.stream_id for x in then
                          if x.get_type() in ("VIDEO_STREAM_INFORMATION", "VIDEO_STREAM_STATUS")})
            print(json.dumps({"event": "streams", "message": msg_id, "unused": str(unused),
                              "result": result, "ids": ids}), flush=True)

    def reset():
        long(mavutil.mavlink.MAV_CMD_DO_SET_ROI_NONE, 0)
        long(mavutil.mavlink.MAV_CMD_DO_GIMBAL_MANAGER_PITCHYAW, 0, 0, NAN, NAN, 0, 0, 0)
        long(mavutil.mavlink.MAV_CMD_SET_CAMERA_ZOOM, 2, 0)
        long(mavutil.mavlink.MAV_CMD_SET_CAMERA_MODE, 0, 0)

    lock = mavutil.mavlink.GIMBAL_MANAGER_FLAGS_YAW_LOCK
    lat, lon, ground = float(sys.argv[2]), float(sys.argv[3]), float(sys.argv[4])
    global_frame = mavutil.mavlink.MAV_FRAME_GLOBAL
    cases = [
        ("DO_GIMBAL_MANAGER_PITCHYAW", attitude,
         lambda: long(mavutil.mavlink.MAV_CMD_DO_GIMBAL_MANAGER_PITCHYAW, -30, 40, NAN, NAN,
                      lock, 0, 0),
         lambda: int_(mavutil.mavlink.MAV_CMD_DO_GIMBAL_MANAGER_PITCHYAW, global_frame, -30, 40,
                      NAN, NAN, x=lock, y=0, z=0)),
        ("DO_SET_ROI_LOCATION", attitude,
         lambda: long(mavutil.mavlink.MAV_CMD_DO_SET_ROI_LOCATION, 0, 0, 0, 0, lat, lon, ground),
         lambda: int_(mavutil.mavlink.MAV_CMD_DO_SET_ROI_LOCATION, global_frame, 0, 0, 0, 0,
                      x=round(lat * 1e7), y=round(lon * 1e7), z=ground)),
        ("SET_CAMERA_ZOOM", settings,
         lambda: long(mavutil.mavlink.MAV_CMD_SET_CAMERA_ZOOM, 2, 50),
         lambda: int_(mavutil.mavlink.MAV_CMD_SET_CAMERA_ZOOM, global_frame, 2, 50)),
        ("SET_CAMERA_MODE", settings,
         lambda: long(mavutil.mavlink.MAV_CMD_SET_CAMERA_MODE, 0, 1),
         lambda: int_(mavutil.mavlink.MAV_CMD_SET_CAMERA_MODE, global_frame, 0, 1)),
    ]
    for name, state, as_long, as_int in cases:
        reset()
        before = state()
        long_result = as_long()[0]
        after_long = state()
        reset()
        int_result = as_int()[0]
        after_int = state()
        print(json.dumps({"event": "command", "command": name, "before": before,
                          "long": [long_result, after_long], "int": [int_result, after_int]}),
              flush=True)

    # Click to track the centre of the picture of the view turned 45 degrees down, as below
    # (COMMAND_LONG), the statuses as pymavlink reads them, then stop (COMMAND_INT).
    reset()
    long(mavutil.mavlink.MAV_CMD_SET_CAMERA_ZOOM, 2, 50)
    long(mavutil.mavlink.MAV_CMD_DO_GIMBAL_MANAGER_PITCHYAW, -45, 30, NAN, NAN, 0, 0, 0)
    result, then = long(mavutil.mavlink.MAV_CMD_CAMERA_TRACK_POINT, 0.5, 0.5, 0.05)
    image = [x for x in then if x.get_type() == "CAMERA_TRACKING_IMAGE_STATUS"]
    _, then = long(mavutil.mavlink.MAV_CMD_REQUEST_MESSAGE, 276)
    geo = [x for x in then if x.get_type() == "CAMERA_TRACKING_GEO_STATUS"]
    stop, then = int_(mavutil.mavlink.MAV_CMD_CAMERA_STOP_TRACKING, global_frame)
    idle = [x for x in then if x.get_type() == "CAMERA_TRACKING_IMAGE_STATUS"]
    print(json.dumps({
        "event": "track", "result": result, "stop": stop,
        "image": [[x.tracking_status, x.tracking_mode, x.point_x, x.point_y, x.radius]
                  for x in image],
        "geo": [[x.tracking_status, x.lat / 1e7, x.lon / 1e7, x.alt, x.dist] for x in geo],
        "idle": [[x.tracking_status, x.tracking_mode] for x in idle]}), flush=True)
    # Where the view looks, 45 degrees down: CAMERA_FOV_STATUS (left so for the test to check).
    reset()
    long(mavutil.mavlink.MAV_CMD_SET_CAMERA_ZOOM, 2, 50)
    long(mavutil.mavlink.MAV_CMD_DO_GIMBAL_MANAGER_PITCHYAW, -45, 30, NAN, NAN, 0, 0, 0)
    result, then = long(mavutil.mavlink.MAV_CMD_REQUEST_MESSAGE, 271)
    fov = [x for x in then if x.get_type() == "CAMERA_FOV_STATUS"][-1]
    print(json.dumps({"event": "fov", "result": result, "lat_image": fov.lat_image / 1e7,
                      "lon_image": fov.lon_image / 1e7, "alt_image": fov.alt_image / 1e3,
                      "lat_camera": fov.lat_camera / 1e7, "hfov": fov.hfov, "vfov": fov.vfov,
                      "q": list(fov.q)}), flush=True)

    return 0


if __name__ == "__main__":
    sys.exit(main())
