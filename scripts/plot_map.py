#!/usr/bin/python3
"""Renders a binary PLY point cloud (vwe_vo_offline's map.ply) to PNG: a top view (x-y, odom)
and a perspective view, coloured by height, with the trajectory (TUM) overlaid when given.

usage: plot_map.py MAP.ply OUT_PREFIX [--tum TRAJ.tum] [--max-points N]
writes OUT_PREFIX_top.png and OUT_PREFIX_persp.png
"""
import argparse
import sys

import numpy as np
import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402

PLY_TYPES = {"float": "<f4", "float32": "<f4", "double": "<f8", "uchar": "u1", "uint8": "u1",
             "int": "<i4", "uint": "<u4", "short": "<i2", "ushort": "<u2", "char": "i1"}


def read_ply(path):
    with open(path, "rb") as f:
        if f.readline().strip() != b"ply":
            raise ValueError(f"{path}: not a PLY file")
        count, props, fmt = 0, [], None
        while True:
            line = f.readline()
            if not line:
                raise ValueError(f"{path}: header without end_header")
            words = line.decode("ascii").split()
            if not words:
                continue
            if words[0] == "format":
                fmt = words[1]
            elif words[0] == "element" and words[1] == "vertex":
                count = int(words[2])
            elif words[0] == "property":
                props.append((words[2], PLY_TYPES[words[1]]))
            elif words[0] == "end_header":
                break
        if fmt != "binary_little_endian":
            raise ValueError(f"{path}: only binary_little_endian is supported, not {fmt}")
        data = np.frombuffer(f.read(np.dtype(props).itemsize * count), dtype=np.dtype(props), count=count)
    return data


def main():
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("ply")
    ap.add_argument("out_prefix")
    ap.add_argument("--tum", help="trajectory (TUM) to overlay")
    ap.add_argument("--max-points", type=int, default=200000)
    a = ap.parse_args()
    v = read_ply(a.ply)
    xyz = np.stack([v["x"], v["y"], v["z"]], axis=1).astype(np.float64)
    xyz = xyz[np.isfinite(xyz).all(axis=1)]
    if len(xyz) == 0:
        print(f"{a.ply}: no points", file=sys.stderr)
        return 1
    if len(xyz) > a.max_points:
        xyz = xyz[np.random.default_rng(0).choice(len(xyz), a.max_points, replace=False)]
    traj = np.loadtxt(a.tum, ndmin=2)[:, 1:4] if a.tum else None
    lo, hi = np.percentile(xyz[:, 2], [2, 98])

    fig, ax = plt.subplots(figsize=(9, 9))
    ax.scatter(xyz[:, 0], xyz[:, 1], c=xyz[:, 2], s=0.5, cmap="viridis", vmin=lo, vmax=hi)
    if traj is not None:
        ax.plot(traj[:, 0], traj[:, 1], "r-", lw=1.5, label="trajectory")
        ax.legend()
    ax.set_aspect("equal")
    ax.set_xlabel("x [m] (odom)")
    ax.set_ylabel("y [m] (odom)")
    ax.set_title(f"{a.ply}: top view, {len(xyz)} points, colour = height")
    fig.tight_layout()
    fig.savefig(a.out_prefix + "_top.png", dpi=120)

    fig = plt.figure(figsize=(10, 8))
    ax = fig.add_subplot(projection="3d")
    ax.scatter(xyz[:, 0], xyz[:, 1], xyz[:, 2], c=xyz[:, 2], s=0.3, cmap="viridis", vmin=lo, vmax=hi)
    if traj is not None:
        ax.plot(traj[:, 0], traj[:, 1], traj[:, 2], "r-", lw=1.5)
    c, r = xyz.mean(axis=0), np.percentile(np.abs(xyz - xyz.mean(axis=0)), 98, axis=0).max()
    ax.set_xlim(c[0] - r, c[0] + r)
    ax.set_ylim(c[1] - r, c[1] + r)
    ax.set_zlim(c[2] - r, c[2] + r)
    ax.view_init(elev=25, azim=-60)
    ax.set_xlabel("x [m]")
    ax.set_ylabel("y [m]")
    ax.set_zlabel("z [m]")
    ax.set_title("perspective view")
    fig.tight_layout()
    fig.savefig(a.out_prefix + "_persp.png", dpi=120)
    print(f"wrote {a.out_prefix}_top.png and {a.out_prefix}_persp.png ({len(xyz)} points)")
    return 0


if __name__ == "__main__":
    sys.exit(main())
