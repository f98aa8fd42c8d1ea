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
    # Axes from the 1-99 % percentiles, boxed in proportion; a flat scene (a room, a street) has
    # its height exaggerated to a third of the longest side, and the title says by how much.
    lo_q, hi_q = np.percentile(xyz, 1, axis=0), np.percentile(xyz, 99, axis=0)
    span = np.maximum(hi_q - lo_q, 1e-3)
    inside = np.all((xyz >= lo_q) & (xyz <= hi_q), axis=1)  # 3D axes do not clip
    p = xyz[inside]
    ax.scatter(p[:, 0], p[:, 1], p[:, 2], c=p[:, 2], s=0.3, cmap="viridis", vmin=lo, vmax=hi)
    if traj is not None:
        ax.plot(traj[:, 0], traj[:, 1], traj[:, 2], "r-", lw=1.5)
    ax.set_xlim(lo_q[0], hi_q[0])
    ax.set_ylim(lo_q[1], hi_q[1])
    ax.set_zlim(lo_q[2], hi_q[2])
    z_gain = max(1.0, span[:2].max() / 3.0 / span[2])
    ax.set_box_aspect((span[0], span[1], span[2] * z_gain))
    ax.view_init(elev=25, azim=-60)
    ax.set_xlabel("x [m]")
    ax.set_ylabel("y [m]")
    ax.set_zlabel("z [m]")
    ax.set_title("perspective view" + (" (height exaggerated x%.1f)" % z_gain if z_gain > 1.05 else ""))
    fig.tight_layout()
    fig.savefig(a.out_prefix + "_persp.png", dpi=120)
    print(f"wrote {a.out_prefix}_top.png and {a.out_prefix}_persp.png ({len(xyz)} points)")
    return 0


if __name__ == "__main__":
    sys.exit(main())
