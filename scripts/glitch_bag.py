#!/usr/bin/python3
"""Makes a glitched copy of a bag, as real recordings come: event timestamps that jump back (a
DAVIS driver stamps a packet ~0.1 s in the past now and then), duplicated or reordered event
packets, or a file cut short by a killed `rosbag record` (no index, FILE.bag.active).

  glitch_bag.py IN.bag OUT.bag [--topic /dvs/events] [--jump-s 0.099 --period-s 0.5]
                [--duplicate-every N] [--reorder-every N]
  glitch_bag.py IN.bag OUT.bag --truncate-mb M

--jump-s/--period-s: the events (and header stamp) of one packet every PERIOD seconds are
stamped JUMP seconds earlier; with --persist the shift stays from the first glitch on (a looped
bag, a restarted driver). --duplicate-every N: every Nth packet is recorded twice.
--reorder-every N: every Nth packet swaps places (and receipt times) with the next one.
--truncate-mb M: the first M MB of the file, raw, with the file header's index fields zeroed as
`rosbag record` leaves them until it closes; OUT gets the suffix .active if it lacks it.
Other topics are copied unchanged. Prints what it did as one JSON line.
"""
import argparse
import json
import os
import shutil
import struct
import sys

import genpy
import rosbag


def truncate(src, dst, mb):
    if not dst.endswith(".active"):
        dst += ".active"
    size = int(mb * 1024 * 1024)
    with open(src, "rb") as fin, open(dst, "wb") as fout:
        remaining = size
        while remaining > 0:
            block = fin.read(min(remaining, 1 << 20))
            if not block:
                break
            fout.write(block)
            remaining -= len(block)
    with open(dst, "r+b") as f:
        magic = f.read(13)
        if magic != b"#ROSBAG V2.0\n":
            sys.exit("glitch_bag: %s is not a version 2.0 bag" % src)
        (header_len,) = struct.unpack("<I", f.read(4))
        start = f.tell()
        while f.tell() < start + header_len:
            (field_len,) = struct.unpack("<I", f.read(4))
            field_start = f.tell()
            field = f.read(field_len)
            name, _, value = field.partition(b"=")
            if name in (b"index_pos", b"conn_count", b"chunk_count"):
                f.seek(field_start + len(name) + 1)
                f.write(b"\0" * len(value))
            f.seek(field_start + field_len)
    return {"truncated_to_bytes": os.path.getsize(dst), "out": dst}


def shifted(pytype, data, jump):
    msg = pytype()
    msg.deserialize(data)
    d = genpy.Duration.from_sec(jump)
    for e in msg.events:
        e.ts = e.ts - d
    msg.header.stamp = msg.header.stamp - d
    return msg


def main():
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("inbag")
    ap.add_argument("outbag")
    ap.add_argument("--topic", default="/dvs/events")
    ap.add_argument("--jump-s", type=float, default=0.0, help="stamp a packet this much earlier [s]")
    ap.add_argument("--period-s", type=float, default=0.5, help="one glitched packet per this much data [s]")
    ap.add_argument("--persist", action="store_true", help="keep the shift from the first glitch on")
    ap.add_argument("--duplicate-every", type=int, default=0)
    ap.add_argument("--reorder-every", type=int, default=0)
    ap.add_argument("--truncate-mb", type=float, default=0.0)
    a = ap.parse_args()
    if os.path.abspath(a.inbag) == os.path.abspath(a.outbag):
        sys.exit("glitch_bag: OUT must differ from IN")
    if a.truncate_mb > 0:
        if a.jump_s or a.duplicate_every or a.reorder_every:
            sys.exit("glitch_bag: --truncate-mb goes alone (glitch first, then truncate the glitched copy)")
        print(json.dumps(truncate(a.inbag, a.outbag, a.truncate_mb)))
        return
    if a.jump_s < 0 or a.period_s <= 0 or a.duplicate_every < 0 or a.reorder_every < 0:
        sys.exit("glitch_bag: --jump-s >= 0, --period-s > 0, --duplicate-every/--reorder-every >= 0")
    stats = {"packets": 0, "shifted": 0, "duplicated": 0, "reordered": 0}
    next_glitch = None
    held = None  # a packet waiting to be written after its successor (reordering)
    with rosbag.Bag(a.inbag) as inbag, rosbag.Bag(a.outbag + ".tmp", "w", compression=inbag.get_compression_info().compression) as out:
        for topic, raw, t, header in inbag.read_messages(raw=True, return_connection_header=True):
            if topic != a.topic:
                out.write(topic, raw, t, raw=True, connection_header=header)
                continue
            k = stats["packets"]
            stats["packets"] += 1
            msg = raw
            is_raw = True
            if a.jump_s > 0:
                if next_glitch is None:
                    next_glitch = t.to_sec() + a.period_s
                if (a.persist and stats["shifted"] > 0) or t.to_sec() >= next_glitch:
                    msg = shifted(raw[4], raw[1], a.jump_s)
                    is_raw = False
                    stats["shifted"] += 1
                    next_glitch += a.period_s
            if held is not None:
                # The held packet goes after this one, each at the other's receipt time.
                out.write(topic, msg, held[2], raw=is_raw, connection_header=header)
                out.write(topic, held[0], t, raw=held[1], connection_header=held[3])
                held = None
                continue
            if a.reorder_every and k % a.reorder_every == a.reorder_every - 1:
                held = (msg, is_raw, t, header)
                stats["reordered"] += 1
                continue
            out.write(topic, msg, t, raw=is_raw, connection_header=header)
            if a.duplicate_every and k % a.duplicate_every == a.duplicate_every - 1:
                out.write(topic, msg, t, raw=is_raw, connection_header=header)
                stats["duplicated"] += 1
        if held is not None:
            out.write(a.topic, held[0], held[2], raw=held[1], connection_header=held[3])
    shutil.move(a.outbag + ".tmp", a.outbag)
    stats["out"] = a.outbag
    print(json.dumps(stats))


if __name__ == "__main__":
    main()
