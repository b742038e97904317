#!/usr/bin/env python3
"""A ground station written with pymavlink, steering DigiView's views on request, for
tests/it/one_path.rs. Reads one JSON object a line on stdin and answers each with one on
stdout:

    {"camera": 102, "as": "long", "command": 1000, "params": [p1, ..., p7]}
    {"camera": 103, "as": "int", "command": 195, "frame": 0, "params": [p1, p2, p3, p4],
     "x": 470000000, "y": 80000000, "z": 500.0}

`as` is "long" (COMMAND_LONG, params 1 to 7) or "int" (COMMAND_INT: params 1 to 4, then x, y
as integers and z); null in a param is NaN (what it leaves alone). The answer is {"result": "MAV_RESULT_ACCEPTED"} (the COMMAND_ACK's
result), or {"result": null} when none came within 3 s. A ground station's HEARTBEAT goes out
with every command, as QGroundControl sends one a second.

Usage: pymavlink_steer.py PORT (DigiView's MAVLink port, udpin on 127.0.0.1).
"""

import json
import math
import sys
import time

from pymavlink import mavutil

from ground_station import beat, connect


def main():
    link, system = connect(sys.argv[1])
    if system is None:
        return 1
    m = link.mav
    print(json.dumps({"ready": True, "system": system}), flush=True)
    for line in sys.stdin:
        ask = json.loads(line)
        camera, command = ask["camera"], ask["command"]
        beat(link)
        params = [math.nan if v is None else float(v) for v in ask["params"]]
        if ask["as"] == "long":
            p = params + [0.0] * (7 - len(params))
            m.command_long_send(system, camera, command, 0, *p)
        else:
            p = params + [0.0] * (4 - len(params))
            m.command_int_send(system, camera, ask.get("frame", 0), command, 0, 0, *p,
                               int(ask.get("x", 0)), int(ask.get("y", 0)),
                               float(ask.get("z", 0.0)))
        result = None
        end = time.monotonic() + 3.0
        while result is None and time.monotonic() < end:
            msg = link.recv_match(type="COMMAND_ACK", blocking=True, timeout=0.1)
            if msg is not None and msg.get_srcComponent() == camera and msg.command == command:
                result = mavutil.mavlink.enums["MAV_RESULT"][msg.result].name
        print(json.dumps({"result": result}), flush=True)
    return 0


if __name__ == "__main__":
    sys.exit(main())
