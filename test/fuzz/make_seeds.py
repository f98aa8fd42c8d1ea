#!/usr/bin/python3
"""Writes the seed corpora of the fuzz targets into OUT/<target>/: the committed tiny text seeds
(test/fuzz/seeds/), the shipped configuration files (their calibration path made absolute, since
the fuzzed file is read from elsewhere) and serialized messages for fuzz_conversions.
  make_seeds.py OUT"""
import os
import shutil
import struct
import sys

HERE = os.path.dirname(os.path.abspath(__file__))
ROOT = os.path.dirname(os.path.dirname(HERE))


def string(s):
    b = s.encode()
    return struct.pack("<I", len(b)) + b


def header(seq=1, sec=1, nsec=500, frame="dvs"):
    return struct.pack("<III", seq, sec, nsec) + string(frame)


def doubles(v):
    return struct.pack("<I", len(v)) + struct.pack("<%dd" % len(v), *v)


def event_array():
    events = [(10, 20, 1, 1000, 1), (345, 259, 1, 2000, 0), (400, 10, 1, 3000, 1)]
    body = b"".join(struct.pack("<HHIIB", *e) for e in events)
    return b"\0" + header() + struct.pack("<II", 260, 346) + struct.pack("<I", len(events)) + body


def spline():
    degree = 3
    knots = [0, 0, 0, 0, 0.2, 0.4, 0.6, 0.6, 0.6, 0.6]
    n = len(knots) - degree - 1
    cx = [0.1 * i for i in range(n)]
    cy = [0.0] * n
    return (b"\1" + header() + struct.pack("<B", degree) + struct.pack("<II", 1, 0) + doubles(knots) +
            doubles(cx) + doubles(cy) + struct.pack("<IIIII", 1, 0, 1, 600000000, 2) + doubles([0.1]) +
            doubles([0.2]) + struct.pack("<d", 0.0) + doubles([0.1, 0.3]) + doubles([0.01, 0.02]) +
            doubles([0.0, -0.01]))


def arc():
    return (b"\2" + header() + struct.pack("<IIII", 1, 0, 1, 300000000) +
            struct.pack("<dddd", 0.1, 0.3, 1.5, 0.2) + struct.pack("<IB", 8000, 0))


def main():
    out = sys.argv[1]
    for target in os.listdir(os.path.join(HERE, "seeds")):
        dst = os.path.join(out, target)
        os.makedirs(dst, exist_ok=True)
        for name in os.listdir(os.path.join(HERE, "seeds", target)):
            shutil.copy(os.path.join(HERE, "seeds", target, name), dst)
    for target in ("config_yaml", "camera_yaml"):
        os.makedirs(os.path.join(out, target), exist_ok=True)
    config = os.path.join(ROOT, "config")
    shutil.copy(os.path.join(config, "davis346.yaml"), os.path.join(out, "camera_yaml"))
    for name in ("vwe_vo.yaml", "car.yaml"):
        with open(os.path.join(config, name)) as f:
            text = f.read().replace("camera_calibration: davis346.yaml",
                                    "camera_calibration: " + os.path.join(config, "davis346.yaml"))
        with open(os.path.join(out, "config_yaml", name), "w") as f:
            f.write(text)
    conv = os.path.join(out, "conversions")
    os.makedirs(conv, exist_ok=True)
    for name, data in (("event_array", event_array()), ("spline", spline()), ("arc", arc())):
        with open(os.path.join(conv, name), "wb") as f:
            f.write(data)


if __name__ == "__main__":
    main()
