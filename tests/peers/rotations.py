"""Rotations as the autopilots and the payload SDK write them (mavlink_euler_to_quaternion,
mavlink_quaternion_to_euler): ZYX Euler angles and (w, x, y, z) quaternions. Shared by the
peers that send or read gimbal attitudes."""

import math


def quaternion(roll, pitch, yaw):
    """(w, x, y, z) of ZYX Euler angles in radians, as both autopilots' from_euler."""
    cr, sr = math.cos(roll / 2), math.sin(roll / 2)
    cp, sp = math.cos(pitch / 2), math.sin(pitch / 2)
    cy, sy = math.cos(yaw / 2), math.sin(yaw / 2)
    return [cr * cp * cy + sr * sp * sy, sr * cp * cy - cr * sp * sy,
            cr * sp * cy + sr * cp * sy, cr * cp * sy - sr * sp * cy]


def euler(q):
    """Yaw, pitch, roll in degrees of a (w, x, y, z) quaternion."""
    w, x, y, z = q
    yaw = math.atan2(2 * (w * z + x * y), 1 - 2 * (y * y + z * z))
    pitch = math.asin(max(-1.0, min(1.0, 2 * (w * y - z * x))))
    roll = math.atan2(2 * (w * x + y * z), 1 - 2 * (x * x + y * y))
    return [math.degrees(yaw), math.degrees(pitch), math.degrees(roll)]
