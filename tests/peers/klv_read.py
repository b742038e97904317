"""Reads a file of MISB ST 0601 KLV packets with klvdata (a reader written by others) and
prints one JSON line a packet: the tags in the order they came, whether the checksum
(recomputed with klvdata's own `packet_checksum`) matches tag 1, and every item's value as
klvdata decodes it (mapped values as numbers, strings as text, the time stamp as µs).

Usage: klv_read.py FILE
"""
import json
import sys

import klvdata
from klvdata.common import packet_checksum
from klvdata.klvparser import KLVParser

UAS_KEY = bytes.fromhex("060E2B34020B01010E01030101000000")


def value_of(item):
    v = item.value
    if hasattr(v, "value") and not isinstance(v, (bytes, str)):
        v = v.value
    if hasattr(v, "timestamp"):
        return round(v.timestamp() * 1e6)
    if isinstance(v, (bytes, bytearray)):
        return v.hex()
    if isinstance(v, (int, float, str)):
        return v
    return str(v)


def main(path):
    data = open(path, "rb").read()
    for key, value in KLVParser(data, key_length=16):
        if key != UAS_KEY:
            print(json.dumps({"key": key.hex()}))
            continue
        # The packet's own bytes again: key, BER length, value.
        n = len(value)
        length = bytes([n]) if n < 128 else bytes([0x80 | ((n.bit_length() + 7) // 8)]) + n.to_bytes((n.bit_length() + 7) // 8, "big")
        packet = key + length + value
        parsed = klvdata.misb0601.UASLocalMetadataSet(value)
        tags, values = [], {}
        for tag, item in parsed.items.items():
            t = int.from_bytes(tag, "big")
            tags.append(t)
            values[str(t)] = value_of(item)
        print(json.dumps({
            "tags": tags,
            "checksum_ok": packet_checksum(packet) == packet[-2:],
            "values": values,
        }))


if __name__ == "__main__":
    main(sys.argv[1])
