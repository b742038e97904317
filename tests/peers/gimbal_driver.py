#!/usr/bin/env python3
"""An autopilot's MAVLink gimbal driver, replayed with pymavlink from its source, managing
DigiView's views as gimbal devices (tests/it/gimbal_device.rs). Two drivers:

- `ardupilot` (libraries/AP_Mount/AP_Mount_Gremsy.cpp, the driver of MAVLink gimbal-v2
  devices): finds the gimbal by a HEARTBEAT of type MAV_TYPE_GIMBAL from component 154,
  asks for GIMBAL_DEVICE_INFORMATION with MAV_CMD_REQUEST_MESSAGE to it each second until
  it comes, then sends GIMBAL_DEVICE_SET_ATTITUDE on every update (50 Hz): an angle as a
  quaternion from roll, pitch and yaw with NaN rates, flags ROLL|PITCH|YAW_LOCK when yaw is
  in the earth frame and 0 when it is from the vehicle's nose; a rate with a NaN quaternion
  and the same flags; retract as a NaN quaternion, zero rates and RETRACT.
- `px4` (src/modules/gimbal/output_mavlink.cpp, MNT_MODE_OUT = 2): asks everyone (target
  0/0) for GIMBAL_DEVICE_INFORMATION each second until one comes, takes the component of the
  last to answer as its device, and sends GIMBAL_DEVICE_SET_ATTITUDE to (its own system, that
  component) on every update, 0 before it found one; before any setpoint a NaN quaternion
  and rates with ROLL|PITCH_LOCK (roll and pitch on the horizon, yaw following the vehicle);
  an angle with a lock flag for each absolute axis and no frame flag.

Both send AUTOPILOT_STATE_FOR_GIMBAL_DEVICE at 50 Hz (the vehicle level, heading YAW degrees)
and a HEARTBEAT a second as the autopilot (system 1, component 1).

Reads one JSON object a line on stdin and answers each with one line on stdout:

    {"do": "angle", "roll": 0, "pitch": -30, "yaw": 20, "earth": false, "for": 1.5}
    {"do": "rate", "pitch": 0, "yaw": 30, "earth": true, "for": 2.0, "settle": 0.5}
    {"do": "retract", "for": 1.0}
    {"do": "zero", "for": 0.5}   (the all-zero quaternion, which no driver sends)

Each is sent as the driver sends it for `for` seconds; the answer is the last
GIMBAL_DEVICE_ATTITUDE_STATUS of the device then and the last `settle` seconds (default 0)
after it started ({"first": {...}, "last": {...}, "seconds": s}, each with the view's yaw,
pitch and roll in degrees in the earth frame, its flags and the device's time `t` in
seconds), and the statuses' count and longest pause so far.

Usage: gimbal_driver.py PORT ardupilot|px4 YAW (DigiView's MAVLink port, udpin on 127.0.0.1).
YAW is the vehicle's heading in degrees, or `spin`: the vehicle is the spinning demo's (yawing
90°/s and rolling ±20° at 1 Hz by the monotonic clock, `[demo] spin`), so the attitude the
driver reports is the one the demo's frames are taken with.
"""

import json
import math
import os
import sys
import threading
import time

# MAVLink 2, as both autopilots speak to gimbals (the gimbal messages' ids are over 255).
os.environ["MAVLINK20"] = "1"
from pymavlink import mavutil  # noqa: E402
from rotations import euler, quaternion  # noqa: E402

NAN = math.nan
ML = mavutil.mavlink
LOCKS = ML.GIMBAL_DEVICE_FLAGS_ROLL_LOCK | ML.GIMBAL_DEVICE_FLAGS_PITCH_LOCK


class Driver:
    def __init__(self, port, flavour, heading):
        self.link = mavutil.mavlink_connection(f"udpout:127.0.0.1:{port}", source_system=1,
                                               source_component=1, dialect="common")
        self.flavour = flavour
        self.spin = heading == "spin"
        self.heading = 0.0 if self.spin else math.radians(float(heading))
        self.lock = threading.Lock()
        self.system, self.device = None, 0
        self.gimbals = set()
        self.info = None
        self.statuses = []  # (arrival, status)
        # What goes out on every update: a quaternion, rates, flags (PX4's first).
        self.setpoint = ([NAN] * 4, [NAN] * 3, LOCKS)
        self.sending = flavour == "px4"

    def beat(self):
        autopilot = (ML.MAV_AUTOPILOT_ARDUPILOTMEGA if self.flavour == "ardupilot"
                     else ML.MAV_AUTOPILOT_PX4)
        self.link.mav.heartbeat_send(ML.MAV_TYPE_QUADROTOR, autopilot, 0, 0, 4)

    def receive(self):
        while True:
            msg = self.link.recv_match(blocking=True, timeout=0.1)
            if msg is None:
                continue
            kind, component = msg.get_type(), msg.get_srcComponent()
            with self.lock:
                if kind == "HEARTBEAT" and msg.type == ML.MAV_TYPE_GIMBAL:
                    self.gimbals.add(component)
                    self.system = msg.get_srcSystem()
                elif kind == "GIMBAL_DEVICE_INFORMATION":
                    # PX4 keeps the last to answer; ArduPilot only its own device's.
                    if self.flavour == "px4" or component == self.device:
                        self.info = msg.to_dict()
                        self.info["component"] = component
                        self.system = msg.get_srcSystem()
                        if self.flavour == "px4":
                            self.device = component
                elif kind == "GIMBAL_DEVICE_ATTITUDE_STATUS" and component == self.device:
                    self.statuses.append((time.monotonic(), msg))

    def tick(self):
        """Every 20 ms: the vehicle's state, the setpoint once sending, a heartbeat a second."""
        n = 0
        while True:
            if n % 50 == 0:
                self.beat()
            now = time.monotonic()
            q = quaternion(0.0, 0.0, self.heading)
            if self.spin:
                roll = math.radians(20.0) * math.sin(2 * math.pi * (now % 1.0))
                q = quaternion(roll, 0.0, math.radians((90.0 * now) % 360.0))
            boot_us = int(now * 1e6)
            self.link.mav.autopilot_state_for_gimbal_device_send(
                self.system or 0, self.device, boot_us, q, 0, 0.0, 0.0, 0.0, 0, NAN, 0, 0)
            with self.lock:
                q, rates, flags = self.setpoint
                sending, system, device = self.sending, self.system or 1, self.device
            if sending:
                target = system if self.flavour == "ardupilot" else 1
                self.link.mav.gimbal_device_set_attitude_send(target, device, flags, q, *rates)
            n += 1
            time.sleep(0.02)

    def find(self):
        """The driver's search: its device's information, asked each second."""
        start = time.monotonic()
        while time.monotonic() - start < 20:
            with self.lock:
                if self.info is not None:
                    return True
                seen = 154 in self.gimbals
            if self.flavour == "ardupilot" and seen:
                self.device = 154
                self.link.mav.command_long_send(self.system, 154, ML.MAV_CMD_REQUEST_MESSAGE, 0,
                                                283, 0, 0, 0, 0, 0, 0)
            elif self.flavour == "px4":
                self.link.mav.command_long_send(0, 0, ML.MAV_CMD_REQUEST_MESSAGE, 0, 283, 0, 0,
                                                0, 0, 0, 0)
            time.sleep(1.0)
        return False

    def status(self, at):
        """The last status that came by `at`: the view in the earth frame, and its flags."""
        with self.lock:
            before = [s for t, s in self.statuses if t <= at]
        if not before:
            return None
        s = before[-1]
        yaw, pitch, roll = euler(s.q)
        return {"yaw": yaw, "pitch": pitch, "roll": roll, "flags": s.flags,
                "delta_yaw": math.degrees(s.delta_yaw), "t": s.time_boot_ms / 1000.0}

    def pauses(self):
        with self.lock:
            times = [t for t, _ in self.statuses]
        gaps = [b - a for a, b in zip(times, times[1:])]
        return len(times), max(gaps, default=0.0)

    def setpoint_of(self, ask):
        d = math.radians
        frame = (LOCKS | ML.GIMBAL_DEVICE_FLAGS_YAW_LOCK) if ask.get("earth") else 0
        if self.flavour == "px4":
            # A lock flag for each absolute axis: roll and pitch always, yaw when asked.
            frame = LOCKS | (ML.GIMBAL_DEVICE_FLAGS_YAW_LOCK if ask.get("earth") else 0)
        if ask["do"] == "angle":
            q = quaternion(d(ask.get("roll", 0)), d(ask.get("pitch", 0)), d(ask.get("yaw", 0)))
            return q, [NAN] * 3, frame
        if ask["do"] == "rate":
            return [NAN] * 4, [0.0, d(ask.get("pitch", 0)), d(ask.get("yaw", 0))], frame
        if ask["do"] == "zero":
            # No driver sends it: the all-zero quaternion, which is no rotation.
            return [0.0] * 4, [NAN] * 3, 0
        return [NAN] * 4, [0.0] * 3, ML.GIMBAL_DEVICE_FLAGS_RETRACT


def main():
    driver = Driver(int(sys.argv[1]), sys.argv[2], sys.argv[3])
    threading.Thread(target=driver.receive, daemon=True).start()
    threading.Thread(target=driver.tick, daemon=True).start()
    found = driver.find()
    with driver.lock:
        driver.sending = True
        ready = {"ready": found, "info": driver.info, "gimbals": sorted(driver.gimbals),
                 "device": driver.device}
    print(json.dumps(ready), flush=True)
    if not found:
        return 1
    for line in sys.stdin:
        ask = json.loads(line)
        with driver.lock:
            driver.setpoint = driver.setpoint_of(ask)
        start = time.monotonic()
        time.sleep(float(ask.get("for", 1.0)))
        end = time.monotonic()
        count, longest = driver.pauses()
        first = driver.status(start + float(ask.get("settle", 0.0)))
        print(json.dumps({"first": first, "last": driver.status(end),
                          "seconds": end - start, "statuses": count, "longest_pause": longest}),
              flush=True)
    return 0


if __name__ == "__main__":
    sys.exit(main())
