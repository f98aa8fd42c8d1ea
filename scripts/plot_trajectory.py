#!/usr/bin/python3
"""Plots estimated trajectories against ground truth.

  plot_trajectory.py --gt GT.tum --est NAME=EST.tum [--est NAME2=EST2.tum ...]
                     [--series SERIES.csv] --out PREFIX

writes PREFIX_topview.png (x-y of the ground truth and of each estimate after a Sim(3) Umeyama
alignment to it, the same alignment as vwe_vo_eval: positions at the ground truth's times inside
the overlap) and, with --series (the CSV of `vwe_vo_eval --series`), PREFIX_errors.png (rotation
and translation-direction relative pose error over time).
"""
import argparse
import os
import sys

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402


def read_tum(path):
    """(N,) times and (N, 3) positions; exits with the file and line of a malformed line."""
    times, positions = [], []
    with open(path) as f:
        for number, line in enumerate(f, 1):
            text = line.split("#", 1)[0].strip()
            if not text:
                continue
            try:
                values = [float(v) for v in text.split()]
            except ValueError:
                values = []
            if len(values) != 8:
                sys.exit("%s:%d: expected 8 numbers 't px py pz qx qy qz qw'" % (path, number))
            times.append(values[0])
            positions.append(values[1:4])
    if not times:
        sys.exit("%s: no poses" % path)
    return np.array(times), np.array(positions)


def umeyama(src, dst, with_scale=True):
    """Similarity (s, R, t) with dst ~ s R src + t, least squares, R a rotation (reflection fix)."""
    mu_src, mu_dst = src.mean(axis=0), dst.mean(axis=0)
    a, b = src - mu_src, dst - mu_dst
    var_src = (a * a).sum() / len(src)
    if not var_src > 0:
        raise ValueError("source points have no spread")
    cov = b.T @ a / len(src)
    u, d, vt = np.linalg.svd(cov)
    s_fix = np.ones(3)
    if np.linalg.det(u) * np.linalg.det(vt) < 0:
        s_fix[2] = -1.0
    r = u @ np.diag(s_fix) @ vt
    scale = float(d @ s_fix / var_src) if with_scale else 1.0
    return scale, r, mu_dst - scale * r @ mu_src


def interpolate_positions(times, positions, at):
    return np.column_stack([np.interp(at, times, positions[:, k]) for k in range(3)])


def align_to(gt_t, gt_p, est_t, est_p, step=0.05, max_gap=0.5):
    """The estimate's positions mapped into the ground-truth frame, and the scale used. Samples
    every `step` s over the overlap, leaving out times inside estimate gaps > max_gap (as C++)."""
    t0, t1 = max(gt_t[0], est_t[0]), min(gt_t[-1], est_t[-1])
    if t1 <= t0:
        raise ValueError("no time overlap with the ground truth")
    at = np.arange(t0, t1 + 1e-9, step)
    after = np.clip(np.searchsorted(est_t, at, side="right"), 1, len(est_t) - 1)
    inside_gap = (est_t[after] - est_t[after - 1] > max_gap) & (at > est_t[after - 1]) & (at < est_t[after])
    at = at[~inside_gap]
    if len(at) < 3:
        raise ValueError("overlap too short to align")
    scale, r, t = umeyama(interpolate_positions(est_t, est_p, at), interpolate_positions(gt_t, gt_p, at))
    return (scale * (r @ est_p.T)).T + t, scale


def plot_topview(gt_t, gt_p, estimates, path):
    fig, ax = plt.subplots(figsize=(7, 7))
    ax.plot(gt_p[:, 0], gt_p[:, 1], "k-", lw=2, label="ground truth")
    ax.plot(gt_p[0, 0], gt_p[0, 1], "ko", ms=8, label="start")
    for name, (est_t, est_p) in estimates:
        try:
            aligned, scale = align_to(gt_t, gt_p, est_t, est_p)
        except ValueError as err:
            print("plot_trajectory: %s: %s, not drawn" % (name, err), file=sys.stderr)
            continue
        line, = ax.plot(aligned[:, 0], aligned[:, 1], "-", lw=1.2, label="%s (Sim(3), scale %.3f)" % (name, scale))
        ax.plot(aligned[0, 0], aligned[0, 1], "o", color=line.get_color(), ms=6)
    ax.set_aspect("equal", adjustable="datalim")
    ax.set_xlabel("x [m]")
    ax.set_ylabel("y [m]")
    ax.set_title("top view (odom)")
    ax.grid(True, alpha=0.3)
    ax.legend(loc="best", fontsize=8)
    fig.tight_layout()
    fig.savefig(path, dpi=120)
    plt.close(fig)


def read_series(path):
    data = np.genfromtxt(path, delimiter=",", names=True)
    for column in ("t_s", "rot_err_deg_s", "trans_dir_err_deg_s"):
        if column not in data.dtype.names:
            sys.exit("%s: no column '%s' (expected the CSV of vwe_vo_eval --series)" % (path, column))
    return np.atleast_1d(data)


def break_at_gaps(t, *columns):
    """Inserts NaN rows where pairs are missing (untracked), so lines do not bridge the gap."""
    if len(t) < 3:
        return (t,) + columns
    breaks = np.nonzero(np.diff(t) > 1.5 * np.median(np.diff(t)))[0] + 1
    return tuple(np.insert(np.asarray(c, dtype=float), breaks, np.nan) for c in (t,) + columns)


def plot_errors(series, path):
    t, rot, direction = break_at_gaps(series["t_s"], series["rot_err_deg_s"], series["trans_dir_err_deg_s"])
    fig, (ax_rot, ax_dir) = plt.subplots(2, 1, figsize=(9, 6), sharex=True)
    ax_rot.plot(t, rot, "-", lw=1, label="3D rotation")
    names = series.dtype.names
    if "yaw_err_deg_s" in names and "tilt_err_deg_s" in names:  # the yaw and tilt parts
        _, yaw, tilt = break_at_gaps(series["t_s"], series["yaw_err_deg_s"], series["tilt_err_deg_s"])
        ax_rot.plot(t, yaw, "-", lw=0.8, label="yaw part")
        ax_rot.plot(t, tilt, "-", lw=0.8, label="tilt part")
        ax_rot.legend(loc="best", fontsize=8)
    ax_rot.set_ylabel("rotation RPE [deg/s]")
    ax_dir.plot(t, direction, "-", lw=1)  # NaN (standstill) leaves gaps
    ax_dir.set_ylabel("transl. direction RPE [deg/s]")
    ax_dir.set_xlabel("time since ground-truth start [s]")
    for ax in (ax_rot, ax_dir):
        ax.grid(True, alpha=0.3)
    fig.tight_layout()
    fig.savefig(path, dpi=120)
    plt.close(fig)


def main():
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--gt", required=True, help="ground-truth TUM file")
    parser.add_argument("--est", action="append", required=True, metavar="NAME=FILE", help="estimated TUM file")
    parser.add_argument("--series", help="per-pair CSV written by vwe_vo_eval --series")
    parser.add_argument("--out", required=True, help="output prefix")
    args = parser.parse_args()

    gt_t, gt_p = read_tum(args.gt)
    estimates = []
    for item in args.est:
        name, sep, path = item.partition("=")
        if not sep or not name or not path:
            sys.exit("plot_trajectory: --est expects NAME=FILE, got '%s'" % item)
        if not os.path.isfile(path):
            sys.exit("plot_trajectory: %s: no such file" % path)
        estimates.append((name, read_tum(path)))
    if args.series and not os.path.isfile(args.series):
        sys.exit("plot_trajectory: %s: no such file" % args.series)
    out_dir = os.path.dirname(args.out)
    if out_dir:
        os.makedirs(out_dir, exist_ok=True)

    plot_topview(gt_t, gt_p, estimates, args.out + "_topview.png")
    written = [args.out + "_topview.png"]
    if args.series:
        plot_errors(read_series(args.series), args.out + "_errors.png")
        written.append(args.out + "_errors.png")
    print("wrote " + " ".join(written))


if __name__ == "__main__":
    main()
