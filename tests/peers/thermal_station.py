#!/usr/bin/env python3
"""A ground station written with pymavlink, reading a view's thermal range as QGroundControl's
thermal overlay asks for it, for tests/it/thermal_serve.rs. Reads one JSON object a line on
stdin, {"camera": 100}, sends MAV_CMD_REQUEST_MESSAGE for CAMERA_THERMAL_RANGE (277) to that
camera, and answers with one line on stdout:

    {"result": "MAV_RESULT_ACCEPTED", "range": {"max": .., "max_point_x": .., "max_point_y": ..,
     "min": .., "min_point_x": .., "min_point_y": .., "stream_id": 1}}

`result` is the COMMAND_ACK's (null when none came within 3 s), `range` the
CAMERA_THERMAL_RANGE that camera sent after it (null when none came); NaN goes out as null.
The first line says whether camera 100 was heard and the CAMERA_INFORMATION flags it gives.
A line {"camera": 100, "thermal": V} sets that camera's THERMAL setting to V instead
(PARAM_EXT_SET) and answers {"ack": PARAM_EXT_ACK's result, "value": the value in force};
{"camera": 100, "setting": NAME, "value": V} sets the camera setting NAME alike;
{"camera": 100, "streams": true} answers {"flags": {"1": .., "2": ..}, "hfov": {..}}, each
stream's VIDEO_STREAM_INFORMATION flags and horizontal field of view (degrees); {"camera": 100, "source": [P, S], "device": D} sends
MAV_CMD_SET_CAMERA_SOURCE and answers {"result": the COMMAND_ACK's result}.

Usage: thermal_station.py PORT (DigiView's MAVLink port, udpin on 127.0.0.1).
"""

import json
import math
import sys
import time

from pymavlink import mavutil

from ground_station import connect, drain

REQUEST_MESSAGE = mavutil.mavlink.MAV_CMD_REQUEST_MESSAGE
FIELDS = ("max", "max_point_x", "max_point_y", "min", "min_point_x", "min_point_y", "stream_id")


def number(v):
    return None if isinstance(v, float) and math.isnan(v) else v


def request(link, system, camera, message_id, reply):
    """REQUEST_MESSAGE of `message_id` from `camera`: the ACK's result and the `reply` that
    camera sent, each None when it did not come within 3 s."""
    link.mav.command_long_send(system, camera, REQUEST_MESSAGE, 0, message_id, 0, 0, 0, 0, 0, 0)
    result, answer = None, None
    end = time.monotonic() + 3.0
    while (result is None or answer is None) and time.monotonic() < end:
        msg = link.recv_match(type=["COMMAND_ACK", reply], blocking=True, timeout=0.1)
        if msg is None or msg.get_srcComponent() != camera:
            continue
        if msg.get_type() == "COMMAND_ACK" and msg.command == REQUEST_MESSAGE:
            result = mavutil.mavlink.enums["MAV_RESULT"][msg.result].name
            if result != "MAV_RESULT_ACCEPTED":
                break
        elif msg.get_type() == reply:
            answer = msg
    return result, answer


def set_setting(link, system, camera, name, value):
    """PARAM_EXT_SET of the camera setting `name`, one byte as QGroundControl writes a camera
    definition's option: the PARAM_EXT_ACK's result and value (None when none came within
    3 s)."""
    link.mav.param_ext_set_send(system, camera, name.encode(), bytes([value]) + bytes(127),
                                mavutil.mavlink.MAV_PARAM_EXT_TYPE_UINT8)
    end = time.monotonic() + 3.0
    while time.monotonic() < end:
        msg = link.recv_match(type="PARAM_EXT_ACK", blocking=True, timeout=0.1)
        if msg is not None and msg.get_srcComponent() == camera:
            value = msg.param_value
            first = value[0] if isinstance(value, (bytes, bytearray)) else ord(value[:1] or "\0")
            return {"ack": msg.param_result, "value": first}
    return {"ack": None, "value": None}


def set_source(link, system, camera, asked):
    """MAV_CMD_SET_CAMERA_SOURCE (534) to `camera`: param 1 `asked["device"]` (0 by default),
    2 and 3 `asked["source"]`'s primary and secondary: the COMMAND_ACK's result."""
    primary, secondary = asked["source"]
    link.mav.command_long_send(system, camera, 534, 0, asked.get("device", 0), primary,
                               secondary, 0, 0, 0, 0)
    end = time.monotonic() + 3.0
    while time.monotonic() < end:
        msg = link.recv_match(type="COMMAND_ACK", blocking=True, timeout=0.1)
        if msg is not None and msg.get_srcComponent() == camera and msg.command == 534:
            return {"result": mavutil.mavlink.enums["MAV_RESULT"][msg.result].name}
    return {"result": None}


def stream_flags(link, system, camera):
    """REQUEST_MESSAGE of VIDEO_STREAM_INFORMATION (269), every stream: each stream's flags
    and hfov by its id, as heard within 3 s."""
    link.mav.command_long_send(system, camera, REQUEST_MESSAGE, 0, 269, 0, 0, 0, 0, 0, 0)
    flags, hfov = {}, {}
    end = time.monotonic() + 3.0
    while len(flags) < 2 and time.monotonic() < end:
        msg = link.recv_match(type="VIDEO_STREAM_INFORMATION", blocking=True, timeout=0.1)
        if msg is not None and msg.get_srcComponent() == camera:
            flags[str(msg.stream_id)] = msg.flags
            hfov[str(msg.stream_id)] = msg.hfov
    return {"flags": flags, "hfov": hfov}


def main():
    link, system = connect(sys.argv[1])
    if system is None:
        return 1
    _, info = request(link, system, 100, 259, "CAMERA_INFORMATION")
    print(json.dumps({"ready": True, "system": system,
                      "flags": None if info is None else info.flags}), flush=True)
    for line in sys.stdin:
        asked = json.loads(line)
        drain(link)
        camera = asked["camera"]
        if "source" in asked:
            print(json.dumps(set_source(link, system, camera, asked)), flush=True)
            continue
        if "streams" in asked:
            print(json.dumps(stream_flags(link, system, camera)), flush=True)
            continue
        if "thermal" in asked or "setting" in asked:
            name, value = asked.get("setting", "THERMAL"), asked.get("value", asked.get("thermal"))
            print(json.dumps(set_setting(link, system, camera, name, value)), flush=True)
            continue
        result, got = request(link, system, camera, 277, "CAMERA_THERMAL_RANGE")
        found = None if got is None else {k: number(getattr(got, k)) for k in FIELDS}
        print(json.dumps({"result": result, "range": found}), flush=True)
    return 0


if __name__ == "__main__":
    sys.exit(main())
