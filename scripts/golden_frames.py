#!/usr/bin/env python3
"""Builds the golden 80-byte frames of src/protocol/golden.rs straight from protocol.md's
tables, with its own CRC-8/BLUETOOTH, independent of the Rust encoder. Run it to check or
regenerate the hex in that file: python3 scripts/golden_frames.py"""
import struct

def crc8_bluetooth(data):
    # Poly 0xA7 reflected is 0xE5; init 0, refin/refout, xorout 0.
    crc = 0
    for b in data:
        crc ^= b
        for _ in range(8):
            crc = (crc >> 1) ^ 0xE5 if crc & 1 else crc >> 1
    return crc

assert crc8_bluetooth(b"123456789") == 0x26

def frame(msg, param, fields, ts=0x0005F5E1_00C0FFEE):
    data = bytearray(64)
    for off, fmt, value in fields:
        b = struct.pack("<" + fmt, value)
        data[off:off + len(b)] = b
    head = struct.pack("<QBBB", ts, 0, msg, param) + bytes(data)
    return head + bytes([crc8_bluetooth(head)]) + bytes(4)

GET, SET, CUR = 2, 3, 4

def video_output(layout, views):
    fields = [(0, "H", 1920), (2, "H", 1080), (4, "B", 30), (5, "B", len(views) << 4 | layout),
              (6, "B", 2)]
    at = 7
    for box in views + [(1800, 0, 120, 1080)]:
        for i, n in enumerate(box):
            fields.append((at + 2 * i, "H", n))
        at += 8
    return fields + [(at, "H", 120)]

CASES = [
    ("SYSTEM_STATUS", CUR, 0, [(0, "B", 1), (1, "B", 0)]),
    # VIDEO_OUTPUT replies at 1920x1080 with the overlay column at the right (mode 2): the
    # high four bits of layout_mode @5 count the views, exactly that many boxes follow @7,
    # then the overlay box and single_detection_size.
    ("VIDEO_OUTPUT layout 0", CUR, 1, video_output(0, [(360, 0, 1080, 1080)])),
    ("VIDEO_OUTPUT layout 1", CUR, 1, video_output(1, [(630, 0, 540, 540), (630, 540, 540, 540)])),
    ("VIDEO_OUTPUT layout 4", CUR, 1, video_output(4, [
        (360, 0, 540, 540), (900, 0, 540, 540), (360, 540, 540, 540), (900, 540, 540, 540)])),
    ("VIDEO_OUTPUT layout 6", CUR, 1, video_output(6, [(0, 0, 1800, 1080)])),
    ("CAPTURE", CUR, 2, [(0, "B", 2), (1, "H", 7), (3, "H", 3)]),
    ("DETECTION", SET, 3, [
        (0, "B", 0), (1, "B", 2), (2, "B", 128), (3, "B", 102), (4, "H", 100), (6, "H", 500),
        (8, "B", 51), (9, "B", 76), (10, "B", 10), (11, "B", 255), (12, "B", 5), (13, "B", 255),
        (14, "B", 20)]),
    ("DETECTED_ROI", CUR, 4, [
        (0, "B", 1), (1, "B", 200), (2, "B", 3), (3, "i", -1571), (7, "i", -785), (11, "i", 100),
        (15, "i", -1000), (19, "i", 58001), (23, "i", -15001), (27, "i", 100000),
        (31, "i", 70711)]),
    ("LENS", SET, 5, [(0, "B", 2)]),
    ("CAM_EULER", SET, 6, [(0, "B", 2), (1, "B", 1), (2, "i", 785), (6, "i", -524), (10, "i", 0)]),
    ("CAM_ZOOM", SET, 7, [(0, "B", 1), (1, "b", -32)]),
    ("CAM_LOCK_FLAGS", SET, 8, [(0, "B", 3), (1, "B", 5)]),
    ("CAM_CONTROL_MODE", SET, 9, [(0, "B", 0), (1, "B", 2)]),
    ("CAM_CROP_MODE", SET, 10, [(0, "B", 1), (1, "B", 4)]),
    ("CAM_OFFSET", CUR, 11, [(0, "B", 0), (1, "h", 16384), (3, "h", -32767), (5, "B", 1),
                             (6, "i", 400), (10, "i", -300)]),
    ("CAM_FOV", SET, 12, [(0, "B", 2), (1, "h", 1571)]),
    ("CAM_TARGET", SET, 13, [(0, "B", 1), (1, "h", 0), (3, "h", 0), (5, "i", 58000000),
                             (9, "i", -15000000), (13, "i", 100000)]),
    ("CAM_SENSOR", SET, 14, [(0, "B", 1), (1, "B", 128), (2, "I", 33333), (6, "I", 1200)]),
    ("GENERAL_SETTINGS", SET, 15, [(0, "H", 3840), (2, "H", 2160), (4, "H", 0), (6, "H", 0),
                                   (8, "B", 30), (9, "i", 0), (13, "i", -1571), (17, "i", 0),
                                   (21, "B", 1)]),
    ("GET CAM_EULER", GET, 6, [(0, "B", 3)]),
    # Extensions: THERMAL (ironbow, a span of 290.5 to 340 K, a blend of 128/255, zoom 4x)
    # and CAM_THERMAL (camera 1, picture in picture).
    ("THERMAL", SET, 18, [(0, "B", 2), (1, "B", 1), (2, "H", 2905), (4, "H", 3400),
                          (6, "B", 128), (7, "B", 4)]),
    ("CAM_THERMAL", SET, 19, [(0, "B", 1), (1, "B", 2)]),
]

if __name__ == "__main__":
    for name, msg, param, fields in CASES:
        print(f"// {name}\n\"{frame(msg, param, fields).hex(' ')}\",")
