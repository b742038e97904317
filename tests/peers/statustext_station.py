#!/usr/bin/env python3
"""A ground station written with pymavlink (not DigiView's own crate) that listens for
STATUSTEXT, as QGroundControl and Mission Planner show them (tests/it/disk_full.rs).

It sends a HEARTBEAT a second as a ground station (DigiView speaks to those it hears) and
keeps every STATUSTEXT DigiView's components send. The first line out says it is ready
(DigiView's heartbeat heard); then each line in is a JSON request answered with one line:

    {"wait": "WORDS", "for": SECONDS}

the first STATUSTEXT heard since the start holding WORDS, waited for up to SECONDS:
{"text": ..., "severity": "MAV_SEVERITY_...", "component": ...}, or {"text": null}.

Usage: statustext_station.py PORT (DigiView's MAVLink port, udpin on 127.0.0.1).
"""

import json
import sys
import threading
import time

from pymavlink import mavutil

ML = mavutil.mavlink


class Station:
    def __init__(self, port):
        self.link = mavutil.mavlink_connection(f"udpout:127.0.0.1:{port}", source_system=255,
                                               source_component=190, dialect="common")
        self.lock = threading.Lock()
        self.texts = []
        self.heard = threading.Event()

    def beat(self):
        while True:
            self.link.mav.heartbeat_send(ML.MAV_TYPE_GCS, ML.MAV_AUTOPILOT_INVALID, 0, 0,
                                         ML.MAV_STATE_ACTIVE)
            time.sleep(1.0)

    def receive(self):
        while True:
            msg = self.link.recv_match(blocking=True, timeout=0.1)
            if msg is None:
                continue
            if msg.get_type() == "HEARTBEAT":
                self.heard.set()
            elif msg.get_type() == "STATUSTEXT":
                with self.lock:
                    self.texts.append({
                        "text": msg.text,
                        "severity": ML.enums["MAV_SEVERITY"][msg.severity].name,
                        "component": msg.get_srcComponent(),
                    })

    def wait(self, words, seconds):
        end = time.monotonic() + seconds
        while True:
            with self.lock:
                found = [t for t in self.texts if words in t["text"]]
            if found or time.monotonic() >= end:
                return found[0] if found else {"text": None}
            time.sleep(0.05)


def main():
    station = Station(int(sys.argv[1]))
    threading.Thread(target=station.beat, daemon=True).start()
    threading.Thread(target=station.receive, daemon=True).start()
    print(json.dumps({"ready": station.heard.wait(10)}), flush=True)
    for line in sys.stdin:
        ask = json.loads(line)
        print(json.dumps(station.wait(ask["wait"], float(ask["for"]))), flush=True)


if __name__ == "__main__":
    main()
