"""What the pymavlink ground stations of tests/peers share: the link to DigiView as a ground
station opens it (a GCS HEARTBEAT, then camera 100's heard)."""

import json

from pymavlink import mavutil


def beat(link):
    """A ground station's HEARTBEAT, as QGroundControl sends one a second."""
    link.mav.heartbeat_send(mavutil.mavlink.MAV_TYPE_GCS, mavutil.mavlink.MAV_AUTOPILOT_INVALID,
                            0, 0, 4)


def connect(port):
    """The link to DigiView's MAVLink port `port` (udpin on 127.0.0.1) and its system id, once
    camera 100's HEARTBEAT is heard; None for the system (and {"ready": false} printed) when
    it is not within 10 s."""
    link = mavutil.mavlink_connection(f"udpout:127.0.0.1:{port}", source_system=255,
                                      source_component=190, dialect="common")
    beat(link)
    first = link.recv_match(type="HEARTBEAT", blocking=True, timeout=10,
                            condition="HEARTBEAT.get_srcComponent() == 100")
    if first is None:
        print(json.dumps({"ready": False}), flush=True)
        return link, None
    return link, first.get_srcSystem()


def drain(link):
    """Reads every message already waiting, as a ground station that reads its link all the
    time would have: a peer that sat on its socket while its test decoded video finds it
    full, and the reply it waits for next would be dropped by the kernel."""
    while link.recv_match(blocking=False) is not None:
        pass
