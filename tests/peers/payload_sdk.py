#!/usr/bin/env python3
"""An app written with Gremsy's PayloadSdk, replayed with pymavlink from the SDK's source
(github Gremsy/PayloadSdk: the C++ SDK 3.0.0_build.04022025, libs/payloadSdkInterface.cpp and
its examples; the Python SDK 3.0.0_build.30092025, libs/payload_sdk.py), driving DigiView's
payload profile (tests/it/payload_sdk.rs, tests/alone/payload_gimbal.rs).

What the SDK does, as replayed here:
- it is system 1, component MAV_COMP_ID_ONBOARD_COMPUTER3 (193), sends from a port of its own
  to the payload's UDP port, MAVLink 2, a HEARTBEAT each second as an onboard controller
  (and a PING first, as the Python SDK);
- it takes its camera's id from the sender of every message from components 100..105 and
  its gimbal's from 154 and 171..175 (checkPayloadConnection, payload_recv_handle), and is
  "connected" on the first message from either;
- on the first message from the payload component (MAV_COMP_ID_USER2, 26) it sends one
  MAV_CMD_SET_MESSAGE_INTERVAL per status item (param1 its own index 0..27, param2 the
  interval in us, 0 where none was set, param7 1), and reads PARAM_VALUE from 26 by index;
- setPayloadCameraParam: PARAM_EXT_SET to the camera, type UINT32, the value's little-endian
  bytes copied up to the first zero (strcpy); it also takes the value as its gimbal mode
  (current_gimbal_mode), whatever the parameter;
- setGimbalSpeed: GIMBAL_DEVICE_SET_ATTITUDE to the gimbal, flags the last status's plus
  YAW_LOCK (lock), less YAW_LOCK (follow), RETRACT (off), NEUTRAL (reset) or 0x4000
  (mapping) by current_gimbal_mode; an angle (quaternion of roll, pitch, yaw, NaN rates) or
  rates in rad/s (NaN quaternion); it reads the gimbal from GIMBAL_DEVICE_ATTITUDE_STATUS,
  its mode from the flags (yaw lock: LOCK, retract: OFF, neutral: RESET, 0x4000: MAPPING,
  else FOLLOW);
- commands to the camera as COMMAND_LONG with confirmation 1: SET_CAMERA_MODE (param2),
  IMAGE_START_CAPTURE (param2 the interval; param3 0 in the C++ SDK, 1 in the Python one),
  VIDEO_START/STOP_CAPTURE, SET_CAMERA_ZOOM (param1 type, param2 value), REQUEST_MESSAGE of
  CAMERA_FOV_STATUS (param2 the camera type), REQUEST_STORAGE_INFORMATION,
  REQUEST_CAMERA_CAPTURE_STATUS, REQUEST_CAMERA_SETTINGS; the capture example checks storage,
  the capture status and the mode, captures, and polls the status until it is idle;
- tracking: MAV_CMD_USER_4 to the payload component, param1 4, param2 0, then param3 1 and
  params 4..7 a box (x, y, w, h) in 1920x1080 pixels, or param3 0 and param4 the mode (0 stop,
  1 active);
- detections: V2_EXTENSION message type 0x4001 (libs/detection_packet.h): magic 0x4744,
  version 1, the box count, a frame id, boxes of x, y, w, h, track id (uint16), class and
  confidence (uint8).

Usage: payload_sdk.py PORT [python]. The first line out says it connected: the camera and gimbal
ids it took. Each line in is a JSON request answered with one line:
  {"settings": true}             the settings list (PARAM_EXT_REQUEST_LIST): name -> value
  {"set": [NAME, VALUE]}         setPayloadCameraParam: the PARAM_EXT_ACK (result, value)
  {"read": NAME}                 PARAM_EXT_REQUEST_READ: the value
  {"command": [TARGET, CMD, p1..p7]}  a COMMAND_LONG: the ACK's result and what followed
  {"zoom": [TYPE, VALUE]}        setCameraZoom, then the FOV status: the ACK and hfov
  {"capture": true}              the capture example, once: the ACKs, statuses and images
  {"gimbal": {"angle"|"rate": [PITCH, ROLL, YAW], "for": S}}  setGimbalSpeed (degrees,
                                 deg/s) every 0.1 s for S seconds: the attitude statuses
  {"rates": [[INDEX, MS], ...]}  setParamRate for each
  {"track": [X, Y, W, H]}        setPayloadObjectTrackingMode(1) and ...Position: the ACKs
  {"track_mode": M}              setPayloadObjectTrackingMode(M): the ACK
  {"listen": S}                  what came in S seconds: status items by index (the last
                                 value and count), detection packets, attitude statuses
  {"ids": true}                  every component heard, and the ids the SDK holds now
"""

import json
import math
import os
import struct
import sys
import threading
import time

os.environ["MAVLINK20"] = "1"
from pymavlink import mavutil  # noqa: E402
from rotations import euler, quaternion  # noqa: E402

ML = mavutil.mavlink
NAN = math.nan
PAYLOAD = ML.MAV_COMP_ID_USER2
MAPPING_FLAG = 0x4000
GB_MODES = {0: "OFF", 1: "LOCK", 2: "FOLLOW", 3: "MAPPING", 4: "RESET"}


class Sdk:
    def __init__(self, port, python):
        self.python = python
        self.m = mavutil.mavlink_connection(
            f"udpout:127.0.0.1:{port}", source_system=1,
            source_component=ML.MAV_COMP_ID_ONBOARD_COMPUTER3)
        self.camera, self.gimbal = 100, 154
        self.heard = set()
        self.rates = [0] * 28
        self.stream_requested = False
        self.gimbal_mode = None  # current_gimbal_mode: the last parameter value set
        self.attitude_flags = 0
        self.lock = threading.Lock()
        self.inbox = []
        self.connected = threading.Event()
        threading.Thread(target=self.beat, daemon=True).start()
        threading.Thread(target=self.receive, daemon=True).start()

    def beat(self):
        self.m.mav.ping_send(int(time.time() * 1e6), 0, 0, 0)
        while True:
            self.m.mav.heartbeat_send(ML.MAV_TYPE_ONBOARD_CONTROLLER, ML.MAV_AUTOPILOT_INVALID,
                                      0, 0, ML.MAV_STATE_ACTIVE)
            time.sleep(1.0)

    def receive(self):
        while True:
            msg = self.m.recv_match(blocking=True, timeout=0.5)
            if msg is None or msg.get_type() == "BAD_DATA":
                continue
            comp = msg.get_srcComponent()
            with self.lock:
                self.heard.add(comp)
                if 100 <= comp <= 105:
                    self.camera = comp
                    self.connected.set()
                if comp == 154 or 171 <= comp <= 175:
                    self.gimbal = comp
                    self.connected.set()
                if msg.get_type() == "GIMBAL_DEVICE_ATTITUDE_STATUS":
                    self.attitude_flags = msg.flags
                self.inbox.append((time.monotonic(), msg))
            if comp == PAYLOAD and not self.stream_requested:
                self.stream_requested = True
                for i, ms in enumerate(self.rates):
                    self.interval(i, ms)

    def interval(self, index, ms):
        self.m.mav.command_long_send(1, PAYLOAD, ML.MAV_CMD_SET_MESSAGE_INTERVAL, 0,
                                     index, ms * 1000, 0, 0, 0, 0, 1)

    def take(self, since, kind, until=None):
        with self.lock:
            return [(t, m) for t, m in self.inbox
                    if t >= since and m.get_type() == kind and (until is None or t <= until)]

    def wait(self, since, kind, test=lambda m: True, timeout=3.0):
        end = time.monotonic() + timeout
        while time.monotonic() < end:
            for _, m in self.take(since, kind):
                if test(m):
                    return m
            time.sleep(0.01)
        return None

    def command(self, target, cmd, *p):
        p = list(p) + [0] * (7 - len(p))
        t = time.monotonic()
        self.m.mav.command_long_send(1, target, cmd, 1, *p)
        ack = self.wait(t, "COMMAND_ACK", lambda a: a.command == cmd)
        return None if ack is None else ack.result

    def set_param(self, name, value):
        self.gimbal_mode = value
        raw = struct.pack("<I", value).split(b"\0")[0]  # strcpy of the value's bytes
        t = time.monotonic()
        self.m.mav.param_ext_set_send(1, self.camera, name.encode(), raw,
                                      ML.MAV_PARAM_EXT_TYPE_UINT32)
        ack = self.wait(t, "PARAM_EXT_ACK", lambda a: a.param_id == name)
        if ack is None:
            return None
        v = struct.unpack("<I", bytes(ack.param_value.encode("latin1")[:4]).ljust(4, b"\0"))[0]
        return {"result": ack.param_result, "value": v}

    def settings(self):
        t = time.monotonic()
        self.m.mav.param_ext_request_list_send(1, self.camera)
        time.sleep(1.0)
        return {m.param_id: value_of(m) for _, m in self.take(t, "PARAM_EXT_VALUE")}

    def read(self, name):
        t = time.monotonic()
        self.m.mav.param_ext_request_read_send(1, self.camera, name.encode(), -1)
        m = self.wait(t, "PARAM_EXT_VALUE", lambda v: v.param_id == name)
        return None if m is None else value_of(m)

    def zoom(self, kind, value):
        ack = self.command(self.camera, ML.MAV_CMD_SET_CAMERA_ZOOM, kind, value)
        t = time.monotonic()
        self.m.mav.command_long_send(1, self.camera, ML.MAV_CMD_REQUEST_MESSAGE, 1,
                                     ML.MAVLINK_MSG_ID_CAMERA_FOV_STATUS, 0, 0, 0, 0, 0, 0)
        fov = self.wait(t, "CAMERA_FOV_STATUS")
        return {"ack": ack, "hfov": None if fov is None else fov.hfov}

    def capture(self):
        """camera_eo_capture_image.cpp's sequence, once."""
        out = {}
        out["mode_ack"] = self.command(self.camera, ML.MAV_CMD_SET_CAMERA_MODE, 0, 0)
        t = time.monotonic()
        self.command(self.camera, ML.MAV_CMD_REQUEST_STORAGE_INFORMATION)
        s = self.wait(t, "STORAGE_INFORMATION")
        out["available_mib"] = None if s is None else s.available_capacity
        t = time.monotonic()
        self.command(self.camera, ML.MAV_CMD_REQUEST_CAMERA_CAPTURE_STATUS)
        before = self.wait(t, "CAMERA_CAPTURE_STATUS")
        if before is None:
            return out  # no status: the example would ask again for ever
        out["images_before"] = before.image_count
        t = time.monotonic()
        self.command(self.camera, ML.MAV_CMD_REQUEST_CAMERA_SETTINGS)
        settings = self.wait(t, "CAMERA_SETTINGS")
        out["mode"] = None if settings is None else settings.mode_id
        count = 1 if self.python else 0
        out["capture_ack"] = self.command(self.camera, ML.MAV_CMD_IMAGE_START_CAPTURE, 0, 0, count)
        end = time.monotonic() + 10
        while time.monotonic() < end:
            time.sleep(0.3)
            t = time.monotonic()
            self.command(self.camera, ML.MAV_CMD_REQUEST_CAMERA_CAPTURE_STATUS)
            st = self.wait(t, "CAMERA_CAPTURE_STATUS")
            if st is not None and st.image_status == 0 and st.image_count > before.image_count:
                out["images_after"] = st.image_count
                break
        return out

    def gimbal_flags(self):
        f = self.attitude_flags
        mode = self.gimbal_mode
        if mode == 0:
            return f | ML.GIMBAL_DEVICE_FLAGS_RETRACT
        if mode == 4:
            return f | ML.GIMBAL_DEVICE_FLAGS_NEUTRAL
        if mode == 1:
            return f | ML.GIMBAL_DEVICE_FLAGS_YAW_LOCK
        if mode == 2:
            return f & ~ML.GIMBAL_DEVICE_FLAGS_YAW_LOCK
        if mode == 3:
            return f | MAPPING_FLAG
        return f

    def set_gimbal(self, pitch, roll, yaw, angle):
        flags = self.gimbal_flags() & 0xFFFF
        if angle:
            q = quaternion(math.radians(roll), math.radians(pitch), math.radians(yaw))
            self.m.mav.gimbal_device_set_attitude_send(1, self.gimbal, flags, q, NAN, NAN, NAN)
        else:
            r = [math.radians(v) for v in (roll, pitch, yaw)]
            self.m.mav.gimbal_device_set_attitude_send(1, self.gimbal, flags, [NAN] * 4, *r)

    def listen(self, seconds):
        t = time.monotonic()
        time.sleep(seconds)
        items = {}
        for _, m in self.take(t, "PARAM_VALUE"):
            if m.get_srcComponent() == PAYLOAD:
                last = items.setdefault(str(m.param_index), {"count": 0})
                last["count"] += 1
                last["value"] = None if math.isnan(m.param_value) else m.param_value
        packets = [detections(m) for _, m in self.take(t, "V2_EXTENSION") if m.message_type == 0x4001]
        return {"items": items, "detections": packets, "attitudes": self.attitudes(t)}

    def attitudes(self, since):
        out = []
        for t, m in self.take(since, "GIMBAL_DEVICE_ATTITUDE_STATUS"):
            yaw, pitch, roll = euler(m.q)
            out.append({"t": t - since, "yaw": yaw, "pitch": pitch, "roll": roll,
                        "flags": m.flags, "mode": mode_of(m.flags)})
        return out


def value_of(m):
    raw = m.param_value.encode("latin1")[:4].ljust(4, b"\0")
    return struct.unpack("<I", raw)[0]


def mode_of(flags):
    """The SDK's _handle_msg_device_attitude."""
    if flags & ML.GIMBAL_DEVICE_FLAGS_YAW_LOCK:
        return "LOCK_MODE"
    if flags & ML.GIMBAL_DEVICE_FLAGS_RETRACT:
        return "OFF_MODE"
    if flags & ML.GIMBAL_DEVICE_FLAGS_NEUTRAL:
        return "RESET_MODE"
    if flags & MAPPING_FLAG:
        return "MAPPING_MODE"
    return "FOLLOW_MODE"


def detections(m):
    p = bytes(m.payload)
    magic, version, n, frame = struct.unpack_from("<HBBI", p, 0)
    boxes = []
    for k in range(n):
        x, y, w, h, track, cls, conf = struct.unpack_from("<HHHHHBB", p, 8 + 12 * k)
        boxes.append({"x": x, "y": y, "w": w, "h": h, "track": track, "class": cls, "conf": conf})
    return {"magic": magic, "version": version, "frame": frame, "boxes": boxes,
            "to": [m.target_system, m.target_component]}


def answer(sdk, ask):
    if "settings" in ask:
        return sdk.settings()
    if "set" in ask:
        return sdk.set_param(*ask["set"])
    if "read" in ask:
        return sdk.read(ask["read"])
    if "command" in ask:
        target, cmd, *p = ask["command"]
        return sdk.command(target, cmd, *p)
    if "zoom" in ask:
        return sdk.zoom(*ask["zoom"])
    if "capture" in ask:
        return sdk.capture()
    if "gimbal" in ask:
        g = ask["gimbal"]
        angle = "angle" in g
        pitch, roll, yaw = g["angle"] if angle else g["rate"]
        t, end = time.monotonic(), time.monotonic() + g["for"]
        while time.monotonic() < end:
            sdk.set_gimbal(pitch, roll, yaw, angle)
            time.sleep(0.1)
        return sdk.attitudes(t)
    if "rates" in ask:
        for index, ms in ask["rates"]:
            sdk.rates[index] = ms
            sdk.interval(index, ms)
        # Their ACKs come before the next command is sent, so none is taken for its answer.
        time.sleep(0.5)
        return True
    if "track" in ask:
        active = sdk.command(PAYLOAD, ML.MAV_CMD_USER_4, 4, 0, 0, 1)
        x, y, w, h = ask["track"]
        return {"mode": active, "box": sdk.command(PAYLOAD, ML.MAV_CMD_USER_4, 4, 0, 1, x, y, w, h)}
    if "track_mode" in ask:
        return sdk.command(PAYLOAD, ML.MAV_CMD_USER_4, 4, 0, 0, ask["track_mode"])
    if "listen" in ask:
        return sdk.listen(ask["listen"])
    if "ids" in ask:
        with sdk.lock:
            return {"heard": sorted(sdk.heard), "camera": sdk.camera, "gimbal": sdk.gimbal}
    return {"error": f"unknown request {ask}"}


def main():
    port = int(sys.argv[1])
    sdk = Sdk(port, len(sys.argv) > 2 and sys.argv[2] == "python")
    ok = sdk.connected.wait(10)
    # The status requests the payload component's first message sets off, answered before
    # anything else is asked (so no ACK of theirs is taken for another's).
    end = time.monotonic() + 5
    while ok and not sdk.stream_requested and time.monotonic() < end:
        time.sleep(0.05)
    time.sleep(0.5)
    print(json.dumps({"ready": ok, "camera": sdk.camera, "gimbal": sdk.gimbal}), flush=True)
    for line in sys.stdin:
        print(json.dumps(answer(sdk, json.loads(line))), flush=True)


if __name__ == "__main__":
    main()
