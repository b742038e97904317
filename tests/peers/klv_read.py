"""Reads a file of MISB ST 0601 KLV packets with klvdata (a reader written by others) and
prints one JSON line a packet: the tags in the order they came, whether the checksum
(recomputed with klvdata's own `packet_checksum`) matches tag 1, and every item's value as
klvdata decodes it (mapped values as numbers, strings as text, the time stamp as µs).

klvdata 0.0.3 cannot read a packet with tag 74 (its VMTI parser is an abstract class: "Can't
instantiate abstract class VMTILocalSet"), so that item is taken out of the value it is given
and listed as "skipped"; the checksum is checked on the packet as it came.

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


def ber(data, i, oid):
    """A BER length (or, with oid, a BER-OID tag) at data[i]: (value, next index)."""
    if oid:
        v = 0
        while data[i] & 0x80:
            v = (v << 7) | (data[i] & 0x7F)
            i += 1
        return (v << 7) | data[i], i + 1
    if data[i] < 128:
        return data[i], i + 1
    n = data[i] & 0x7F
    return int.from_bytes(data[i + 1 : i + 1 + n], "big"), i + 1 + n


def without(value, skip):
    """The local set `value` without its items whose tags are in `skip`."""
    out, i = b"", 0
    while i < len(value):
        tag, j = ber(value, i, True)
        n, k = ber(value, j, False)
        if tag not in skip:
            out += value[i : k + n]
        i = k + n
    return out


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
        readable = without(value, {74})
        parsed = klvdata.misb0601.UASLocalMetadataSet(readable)
        tags, values = [], {}
        for tag, item in parsed.items.items():
            t = int.from_bytes(tag, "big")
            tags.append(t)
            values[str(t)] = value_of(item)
        print(json.dumps({
            "tags": tags,
            "checksum_ok": packet_checksum(packet) == packet[-2:],
            "skipped": [74] if readable != value else [],
            "values": values,
        }))


if __name__ == "__main__":
    main(sys.argv[1])
