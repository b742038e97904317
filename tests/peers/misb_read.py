"""Reads a file of MISB ST 0601 KLV packets with stanag4609 (a reader written by others, strict
about every field it knows, ST 0903 VMTI included) and prints one JSON line a packet: its
tags in order, every ST 0601 value stanag4609 decodes (numbers as numbers, time stamps as µs
since 1970, the rest as text),
and the tracked objects of the VMTI local set nested in tag 74, if there is one. A packet the
reader refuses prints {"error": "..."}; the checksum is verified by the reader itself.

Usage: misb_read.py FILE
"""
import dataclasses
import json
import sys
from datetime import datetime, timedelta, timezone
from fractions import Fraction

from stanag4609.klv.stream import iter_klv
from stanag4609.st0601 import decode_uas_local_set
from stanag4609.st0903 import VMTILocalSet

UAS_KEY = bytes.fromhex("060E2B34020B01010E01030101000000")


def plain(v):
    if isinstance(v, bool) or v is None:
        return v
    if isinstance(v, (int, float, str)):
        return v
    if isinstance(v, Fraction):
        return float(v)
    if isinstance(v, datetime):  # the time stamps, as µs since 1970
        return (v - datetime(1970, 1, 1, tzinfo=timezone.utc)) // timedelta(microseconds=1)
    if hasattr(v, "latitude"):
        return {"lat": plain(v.latitude), "lon": plain(v.longitude), "hae": plain(v.hae)}
    if isinstance(v, (tuple, list)):
        return [plain(x) for x in v]
    if dataclasses.is_dataclass(v):
        return {
            f.name: plain(getattr(v, f.name))
            for f in dataclasses.fields(v)
            if f.name not in ("local_set", "extensions", "raw", "item")
        }
    if hasattr(v, "value") and not isinstance(v, (bytes, bytearray)):
        return plain(v.value)
    if isinstance(v, (bytes, bytearray)):
        return v.hex()
    try:
        return float(v)
    except (TypeError, ValueError):
        return str(v)


def vmti(v: VMTILocalSet):
    targets = []
    for t in v.targets:
        fields = {f.name: plain(f.value) for f in t.fields}
        targets.append({"id": t.target_id, **fields})
    return {
        "fields": {f.name: plain(f.value) for f in v.fields if f.tag != 101},
        "ontologies": [
            {"id": o.ontology_id, "iri": o.ontology_iri, "entity": o.entity_iri, "label": o.label}
            for o in v.ontologies
        ],
        "targets": targets,
    }


def main(path):
    with open(path, "rb") as f:
        packets = list(iter_klv(f))
    for packet in packets:
        if packet.key != UAS_KEY:
            print(json.dumps({"key": packet.key.hex()}))
            continue
        try:
            decoded = decode_uas_local_set(packet)
        except Exception as e:  # the reader's refusal, whatever its kind
            print(json.dumps({"error": f"{type(e).__name__}: {e}"}))
            continue
        out = {"tags": [i.tag for i in decoded.local_set.items], "values": {}}
        for f in decoded.fields:
            tag = f.definition.tag
            if isinstance(f.value, VMTILocalSet):
                out["vmti"] = vmti(f.value)
            else:
                out["values"][str(tag)] = plain(f.value)
        print(json.dumps(out))


if __name__ == "__main__":
    main(sys.argv[1])
