#!/usr/bin/python3
"""Plots the front-end's arcs over time: estimated yaw rate against the ground-truth yaw rate,
and the event rate per window with the window status (standstill, lost, low events).

usage: plot_arcs.py --arcs OUT/arcs.csv [--gt GT.tum] --out PNG"""
import argparse
import csv
import math

import matplotlib
matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402


def gt_yaw_rate(path, dt=0.1):
    rows = [list(map(float, l.split())) for l in open(path) if l.strip() and not l.startswith("#")]
    t = [r[0] for r in rows]
    yaw = [math.atan2(2 * (r[7] * r[6] + r[4] * r[5]), 1 - 2 * (r[5] ** 2 + r[6] ** 2)) for r in rows]
    out_t, out_w = [], []
    j = 0
    for i in range(len(rows)):
        while j < len(rows) - 1 and t[j] < t[i] + dt:
            j += 1
        if t[j] - t[i] < 0.5 * dt:
            break
        d = math.atan2(math.sin(yaw[j] - yaw[i]), math.cos(yaw[j] - yaw[i]))
        out_t.append(0.5 * (t[i] + t[j]))
        out_w.append(math.degrees(d / (t[j] - t[i])))
    return out_t, out_w


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("--arcs", required=True)
    ap.add_argument("--gt")
    ap.add_argument("--out", required=True)
    a = ap.parse_args()
    rows = list(csv.DictReader(open(a.arcs)))
    t = [float(r["t_ref"]) for r in rows]
    # The front-end's own yaw rate (the arc at roll 0) where the file has it, as vwe_vo_eval --arcs.
    key = "omega_without_roll" if rows and "omega_without_roll" in rows[0] else "omega"
    w = [math.degrees(float(r[key])) for r in rows]
    rate = [float(r["window_events"]) / max(1e-9, float(r["t_end"]) - float(r["t_start"])) / 1e6 for r in rows]
    status = [r["status"] for r in rows]
    fig, (ax1, ax2) = plt.subplots(2, 1, figsize=(10, 6), sharex=True)
    if a.gt:
        gt, gw = gt_yaw_rate(a.gt)
        ax1.plot(gt, gw, "k-", lw=1, label="ground truth")
    ax1.plot(t, w, "o-", ms=3, lw=1, label="front-end arcs")
    for s, c in (("STANDSTILL", "tab:gray"), ("LOST", "tab:red"), ("LOW_EVENTS", "tab:orange")):
        ts = [ti for ti, si in zip(t, status) if si == s]
        if ts:
            ax1.plot(ts, [0] * len(ts), "s", color=c, ms=4, label=s.lower())
    ax1.set_ylabel("yaw rate [deg/s]")
    ax1.legend(loc="best", fontsize=8)
    ax1.grid(alpha=0.3)
    ax2.plot(t, rate, "-", color="tab:green")
    ax2.set_ylabel("event rate [Mev/s]")
    ax2.set_xlabel("time [s]")
    ax2.grid(alpha=0.3)
    fig.tight_layout()
    fig.savefig(a.out, dpi=110)


if __name__ == "__main__":
    main()
