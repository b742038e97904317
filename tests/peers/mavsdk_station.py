#!/usr/bin/env python3
"""A ground station as MAVSDK apps are, for tests/it/mavsdk.rs: MAVSDK's C++ core (the
`mavsdk` wheel in the project's .venv, which scripts/setup.sh installs) with its Camera and
Gimbal plugins, connected to DigiView's MAVLink port. It waits for the four cameras and their
gimbals, reads each camera's video stream, then turns camera 100's gimbal at 20 deg/s and
stops it, once with SendMode.ONCE and once with STREAM, and stays connected until its time
is up. It prints one JSON object per line, each with `t`, the monotonic clock (the test's
own clock too), so the test can line up what the view did with what was asked. MAVSDK's own
log goes to stderr.

With `list` for SECONDS it only connects, waits 3 s and says which cameras it lists.

Usage: mavsdk_station.py PORT SECONDS|list
"""

import json
import sys
import time

from mavsdk.component_type import ComponentType
from mavsdk.mavsdk import Configuration, Mavsdk
from mavsdk.plugins.camera.camera import Camera
from mavsdk.plugins.gimbal.gimbal import Gimbal, GimbalMode, SendMode

RATE_DEG_S = 20.0


def say(event, **fields):
    print(json.dumps({"event": event, "t": time.monotonic(), **fields}), flush=True)


def main():
    port = int(sys.argv[1])
    seconds = 0.0 if sys.argv[2] == "list" else float(sys.argv[2])
    mavsdk = Mavsdk(Configuration.create_with_component_type(ComponentType.GROUND_STATION))
    start = time.monotonic()
    mavsdk.add_any_connection(f"udpout://127.0.0.1:{port}")
    while not mavsdk.get_systems():
        if time.monotonic() - start > 10:
            say("no system")
            return 1
        time.sleep(0.02)
    system = mavsdk.get_systems()[0]
    camera, gimbal = Camera(system), Gimbal(system)
    if sys.argv[2] == "list":
        time.sleep(3.0)
        say("listed", ids=sorted(c.component_id for c in camera.camera_list().cameras))
        return 0

    cameras = gimbals = None
    while time.monotonic() - start < 10 and (cameras is None or gimbals is None):
        listed = camera.camera_list().cameras
        if cameras is None and len(listed) == 4:
            cameras = [c.component_id for c in listed]
            say("cameras", after_s=time.monotonic() - start, ids=cameras)
        named = [g for g in gimbal.gimbal_list().gimbals if g.vendor_name and g.model_name]
        if gimbals is None and len(named) == 4:
            gimbals = [[g.gimbal_id, g.gimbal_manager_component_id, g.vendor_name,
                        g.model_name] for g in named]
            say("gimbals", after_s=time.monotonic() - start, gimbals=gimbals)
        time.sleep(0.02)
    if cameras is None or gimbals is None:
        say("not found", cameras=cameras, gimbals=gimbals)
        return 1

    uris, sizes = {}, {}
    while time.monotonic() - start < 15 and len(uris) < len(cameras):
        for c in cameras:
            try:
                info = camera.get_video_stream_info(c)
            except Exception:
                continue
            if info.settings.uri:
                uris[str(c)] = info.settings.uri
                sizes[str(c)] = [info.settings.horizontal_resolution_pix,
                                 info.settings.vertical_resolution_pix]
        time.sleep(0.05)
    say("streams", after_s=time.monotonic() - start, uris=uris, sizes=sizes)

    first = next(g[0] for g in gimbals if g[1] == 100)
    for mode in (SendMode.ONCE, SendMode.STREAM):
        for rate in (RATE_DEG_S, 0.0):
            t = time.monotonic()
            try:
                gimbal.set_angular_rates(first, 0.0, 0.0, rate, GimbalMode.YAW_FOLLOW, mode)
                say("rate", at=t, mode=mode.name, yaw_deg_s=rate, result="SUCCESS")
            except Exception as e:
                say("rate", at=t, mode=mode.name, yaw_deg_s=rate, result=str(e))
            time.sleep(1.0)

    while time.monotonic() - start < seconds:
        time.sleep(0.1)
    say("done")
    return 0


if __name__ == "__main__":
    sys.exit(main())
