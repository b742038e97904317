"""ArduPilot as DigiView's MAVLink link meets it, replayed from its source with pymavlink.

What it sends is read from ArduPilot (libraries/GCS_MAVLink, AP_Camera):
- a HEARTBEAT each second: a quadrotor (MAV_TYPE_QUADROTOR) flown by MAV_AUTOPILOT_ARDUPILOTMEGA,
  armed, in AUTO (custom mode 3);
- ATTITUDE and GLOBAL_POSITION_INT (with its velocity, cm/s) at 4 Hz, each at the rate a
  MAV_CMD_SET_MESSAGE_INTERVAL asks once one does (answered with COMMAND_ACK), stamped with
  its boot time; TIMESYNC requests answered on that clock, in nanoseconds;
- its MAVLink camera backend (AP_Camera_MAVLinkCamV2): finds the camera by its HEARTBEAT
  (MAV_TYPE_CAMERA, component 100), asks for CAMERA_INFORMATION, and for each picture
  (trigger_pic) sends COMMAND_LONG MAV_CMD_IMAGE_START_CAPTURE with param3 1 (one image) and
  param4 the image's sequence number (image_index + 1); with a trigger distance
  (CAM1_TRIGG_DIST, DO_SET_CAM_TRIGG_DIST) AP_Camera_Backend::update, at 50 Hz, takes a
  picture once the vehicle is that far from where it took the last.

With `px4` after the arguments it is PX4 instead (MAV_AUTOPILOT_PX4), whose camera trigger in
MAVLink mode (src/modules/mavlink/streams/CAMERA_TRIGGER.hpp) sends for each picture
CAMERA_TRIGGER, MAV_CMD_IMAGE_START_CAPTURE (param1 0, param2 0, param3 1, param4 its sequence
from 1, the rest NaN) to camera 100 through its command sender, which sends it again after
0.5 s without an ACK (three times at most), and a COMMAND_LONG MAV_CMD_DO_DIGICAM_CONTROL
(param5 1, the rest NaN) to system 0, camera 100.

The vehicle flies a straight line (heading, ground speed, climb) from a starting point; its
position at any time is the line's, so a test can say where it was when a frame was taken.

Usage: autopilot.py PORT SYSTEM LAT LON ALT HEADING_DEG [px4]. The first line out says it is ready
(DigiView heard, its camera found) with what it was asked; then each line in is a JSON request
answered with one line:
  {"fly": {"speed": m/s, "climb": m/s, "for": s, "trigg_dist": m}}  fly the line (from where
      the vehicle is), triggering by distance; answers the triggers, each CAMERA_IMAGE_CAPTURED
      with where the line had the vehicle at the image's time, and the ACKs;
  {"shoot": true}  one picture, as the shoot command (DO_DIGICAM_CONTROL) takes it;
  {"heard": true}  the STATUSTEXTs and rate requests heard so far.
"""

import json
import math
import os
import sys
import threading
import time

# MAVLink 2, as ArduPilot speaks to MAVLink cameras (CAMERA_INFORMATION's id is over 255).
os.environ["MAVLINK20"] = "1"
from pymavlink import mavutil  # noqa: E402

ML = mavutil.mavlink
R = 6378137.0
CAMERA = 100


class Line:
    """Where the vehicle is at a UTC time: a list of legs, each from its start (time, place)
    at its velocity until the next; hovering at the first place before it."""

    def __init__(self, lat, lon, alt, heading):
        self.heading = math.radians(heading)
        self.legs = [(0.0, lat, lon, alt, 0.0, 0.0)]  # (t0, lat, lon, alt, speed, climb)

    def velocity(self, leg=None):
        """North, east, down in m/s."""
        _, _, _, _, speed, climb = leg or self.legs[-1]
        return (speed * math.cos(self.heading), speed * math.sin(self.heading), -climb)

    def at(self, t):
        leg = self.legs[0]
        for later in self.legs[1:]:
            if later[0] <= t:
                leg = later
        t0, lat, lon, alt = leg[:4]
        dt = max(0.0, t - t0)
        vn, ve, vd = self.velocity(leg)
        lat1 = lat + math.degrees(vn * dt / R)
        lon1 = lon + math.degrees(ve * dt / (R * math.cos(math.radians(lat))))
        return lat1, lon1, alt - vd * dt

    def fly(self, speed, climb, now):
        lat, lon, alt = self.at(now)
        self.legs.append((now, lat, lon, alt, speed, climb))


def distance(a, b):
    """Metres between two (lat, lon) points, as Location::get_distance (flat earth)."""
    dlat = math.radians(b[0] - a[0])
    dlon = math.radians(b[1] - a[1]) * math.cos(math.radians(a[0]))
    return R * math.hypot(dlat, dlon)


class Autopilot:
    def __init__(self, port, system, line, px4=False):
        self.px4 = px4
        self.link = mavutil.mavlink_connection(f"udpout:127.0.0.1:{port}", source_system=system,
                                               source_component=1, dialect="common")
        self.line = line
        self.boot = time.monotonic()
        # UTC as the monotonic clock's reading plus this, so that a position and the boot
        # time it is stamped with are the same instant.
        self.offset = time.time() - self.boot
        self.lock = threading.Lock()
        self.rates = {ML.MAVLINK_MSG_ID_ATTITUDE: 4.0, ML.MAVLINK_MSG_ID_GLOBAL_POSITION_INT: 4.0}
        self.asked = []  # (message id, Hz, target system, target component)
        self.texts = []
        self.digiview = None  # DigiView's system, once heard
        self.camera_flags = None
        self.captured = []
        self.acks = []

    def utc(self):
        return time.monotonic() + self.offset

    def boot_ms(self):
        return int((time.monotonic() - self.boot) * 1000)

    def receive(self):
        while True:
            msg = self.link.recv_match(blocking=True, timeout=0.1)
            if msg is None:
                continue
            kind, component = msg.get_type(), msg.get_srcComponent()
            with self.lock:
                self.handle(msg, kind, component)

    def handle(self, msg, kind, component):
        if kind == "HEARTBEAT" and component == 191:
            self.digiview = msg.get_srcSystem()
        elif kind == "COMMAND_LONG" and msg.command == ML.MAV_CMD_SET_MESSAGE_INTERVAL:
            hz = 1e6 / msg.param2 if msg.param2 > 0 else 0.0
            self.asked.append((int(msg.param1), hz, msg.target_system, msg.target_component))
            if (msg.target_system, msg.target_component) == (self.link.source_system, 1):
                self.rates[int(msg.param1)] = hz
                self.link.mav.command_ack_send(msg.command, ML.MAV_RESULT_ACCEPTED, 0, 0,
                                               msg.get_srcSystem(), component)
        elif kind == "TIMESYNC" and msg.tc1 == 0:
            now_ns = int((time.monotonic() - self.boot) * 1e9)
            self.link.mav.timesync_send(now_ns, msg.ts1)
        elif kind == "CAMERA_INFORMATION" and component == CAMERA:
            self.camera_flags = msg.flags
        elif kind == "CAMERA_IMAGE_CAPTURED" and component == CAMERA:
            self.captured.append((self.utc(), msg))
        elif kind == "COMMAND_ACK" and msg.command == ML.MAV_CMD_IMAGE_START_CAPTURE:
            self.acks.append(msg.result)
        elif kind == "STATUSTEXT":
            self.texts.append(msg.text)

    def send(self):
        """The heartbeat each second and the streams at their rates, until the process ends."""
        due = {}
        beat = 0.0
        while True:
            now = time.monotonic()
            if now >= beat:
                beat = now + 1.0
                self.link.mav.heartbeat_send(
                    ML.MAV_TYPE_QUADROTOR,
                    ML.MAV_AUTOPILOT_PX4 if self.px4 else ML.MAV_AUTOPILOT_ARDUPILOTMEGA,
                    ML.MAV_MODE_FLAG_SAFETY_ARMED | ML.MAV_MODE_FLAG_CUSTOM_MODE_ENABLED, 3,
                    ML.MAV_STATE_ACTIVE)
            with self.lock:
                rates = dict(self.rates)
            for msg_id, hz in rates.items():
                if hz > 0 and now >= due.get(msg_id, 0.0):
                    due[msg_id] = max(due.get(msg_id, now) + 1.0 / hz, now)
                    self.stream(msg_id)
            time.sleep(0.002)

    def stream(self, msg_id):
        if msg_id == ML.MAVLINK_MSG_ID_ATTITUDE:
            self.link.mav.attitude_send(self.boot_ms(), 0.0, 0.0, self.line.heading, 0.0, 0.0, 0.0)
            return
        boot_ms = self.boot_ms()
        with self.lock:
            # Where the line has the vehicle at the very millisecond it is stamped with.
            lat, lon, alt = self.line.at(self.boot + boot_ms / 1000 + self.offset)
            vn, ve, vd = self.line.velocity()
        hdg = int(round(math.degrees(self.line.heading) % 360 * 100))
        self.link.mav.global_position_int_send(
            boot_ms, round(lat * 1e7), round(lon * 1e7), round(alt * 1000),
            round((alt - 20.0) * 1000), round(vn * 100), round(ve * 100), round(vd * 100), hdg)

    def find_camera(self, limit):
        """As AP_Camera_MAVLinkCamV2::find_camera: DigiView's camera 100, then its information."""
        end = time.monotonic() + limit
        while time.monotonic() < end:
            with self.lock:
                system, flags = self.digiview, self.camera_flags
            if flags is not None:
                return True
            if system is not None:
                self.link.mav.command_long_send(system, CAMERA, ML.MAV_CMD_REQUEST_MESSAGE, 0,
                                                ML.MAVLINK_MSG_ID_CAMERA_INFORMATION,
                                                0, 0, 0, 0, 0, 0)
            time.sleep(0.5)
        return False

    def trigger(self, index):
        """One picture, numbered from 1: ArduPilot's trigger_pic, or PX4's CAMERA_TRIGGER stream."""
        if not self.px4:
            self.link.mav.command_long_send(self.digiview, CAMERA, ML.MAV_CMD_IMAGE_START_CAPTURE,
                                            0, 0, 0, 1, index + 1, 0, 0, 0)
            return
        nan = math.nan
        self.link.mav.camera_trigger_send(int(self.utc() * 1e6), index + 1)
        self.start_capture(index)
        self.link.mav.command_long_send(0, CAMERA, ML.MAV_CMD_DO_DIGICAM_CONTROL, 0,
                                        nan, nan, nan, nan, 1, nan, nan)

    def start_capture(self, index):
        nan = math.nan
        self.link.mav.command_long_send(self.digiview, CAMERA, ML.MAV_CMD_IMAGE_START_CAPTURE, 0,
                                        0, 0, 1, index + 1, nan, nan, nan)

    def resend_unanswered(self, triggers, acks_before):
        """PX4's command sender: again after 0.5 s without an ACK, three times at most."""
        with self.lock:
            acked = len(self.acks) - acks_before
        for i, t in enumerate(triggers):
            if i >= acked and t["sent"] < 3 and self.utc() - t["last"] >= 0.5:
                self.start_capture(i)
                t["sent"] += 1
                t["last"] = self.utc()

    def fly(self, speed, climb, seconds, trigg_dist):
        """Flies the line, at 50 Hz checking the distance from the last picture's place."""
        with self.lock:
            self.line.fly(speed, climb, self.utc())
            first, acks_before = len(self.captured), len(self.acks)
        triggers, last = [], None
        end = time.monotonic() + seconds
        while time.monotonic() < end:
            here = self.line.at(self.utc())
            if last is None:
                last = here
            elif trigg_dist > 0 and distance(last, here) >= trigg_dist:
                self.trigger(len(triggers))
                now = self.utc()
                triggers.append({"t": now, "lat": here[0], "lon": here[1], "sent": 1, "last": now})
                last = here
            if self.px4:
                self.resend_unanswered(triggers, acks_before)
            time.sleep(0.02)
        with self.lock:
            self.line.fly(0.0, 0.0, self.utc())
        time.sleep(3.0)  # the last stills written and announced
        with self.lock:
            acks = self.acks[acks_before:]
        return {"triggers": triggers, "captured": self.captured_since(first), "acks": acks}

    def captured_since(self, first):
        with self.lock:
            captured = self.captured[first:]
        out = []
        for arrived, c in captured:
            t = c.time_utc / 1e6
            lat, lon, alt = self.line.at(t)
            out.append({"arrived": arrived, "time_utc": c.time_utc, "lat": c.lat / 1e7,
                        "lon": c.lon / 1e7, "alt": c.alt / 1000, "q": list(c.q),
                        "image_index": c.image_index, "result": c.capture_result,
                        "url": c.file_url, "truth": {"lat": lat, "lon": lon, "alt": alt}})
        return out

    def shoot(self):
        with self.lock:
            first = len(self.captured)
        self.trigger(first)
        end = time.monotonic() + 10
        while time.monotonic() < end:
            got = self.captured_since(first)
            if got:
                return got[0]
            time.sleep(0.05)
        return None


def main():
    port, system = int(sys.argv[1]), int(sys.argv[2])
    lat, lon, alt, heading = (float(v) for v in sys.argv[3:7])
    ap = Autopilot(port, system, Line(lat, lon, alt, heading), sys.argv[7:8] == ["px4"])
    threading.Thread(target=ap.receive, daemon=True).start()
    threading.Thread(target=ap.send, daemon=True).start()
    found = ap.find_camera(20.0)
    print(json.dumps({"ready": found, "digiview": ap.digiview}), flush=True)
    if not found:
        return 1
    for line in sys.stdin:
        ask = json.loads(line)
        if "fly" in ask:
            f = ask["fly"]
            answer = ap.fly(f["speed"], f.get("climb", 0.0), f["for"], f.get("trigg_dist", 0.0))
        elif "shoot" in ask:
            answer = {"captured": ap.shoot()}
        else:
            with ap.lock:
                answer = {"texts": list(ap.texts), "asked": list(ap.asked)}
        print(json.dumps(answer), flush=True)
    return 0


if __name__ == "__main__":
    sys.exit(main())
