#!/usr/bin/python3
"""Plots the front-end objective over the yaw rate written by vwe_vo_objective.

usage: plot_objective.py OBJECTIVE.csv [MORE.csv ...] --out PNG

Each CSV (from `vwe_vo_objective ... --out CSV`) becomes one curve, normalised to its maximum;
its header line (window, events, speed, true yaw rate) becomes the legend, and a dashed line
marks the true yaw rate when the header gives it.
"""
import argparse
import re
import sys

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402


def read(path):
    header, omega, value = "", [], []
    with open(path) as f:
        for line in f:
            if line.startswith("#"):
                header = line[1:].strip()
            elif line[0].isdigit() or line[0] in "-.":
                a, b = line.split(",")
                omega.append(float(a))
                value.append(float(b))
    if not omega:
        sys.exit(f"plot_objective.py: {path} holds no 'omega_deg_s,contrast' rows")
    return header, omega, value


def main():
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("csv", nargs="+")
    ap.add_argument("--out", required=True)
    args = ap.parse_args()
    fig, ax = plt.subplots(figsize=(7, 4.2))
    for path in args.csv:
        header, omega, value = read(path)
        top = max(value)
        line, = ax.plot(omega, [v / top for v in value], label=header)
        m = re.search(r"true omega (-?[0-9.eE+-]+) deg/s", header)
        if m:
            ax.axvline(float(m.group(1)), color=line.get_color(), ls="--", lw=0.8)
        best = omega[value.index(top)]
        ax.plot([best], [1.0], "v", color=line.get_color())
    ax.set_xlabel("yaw rate omega [deg/s]")
    ax.set_ylabel("VWE contrast / its maximum")
    ax.set_title("front-end objective over omega (dashed: ground truth, triangle: maximum)")
    ax.grid(alpha=0.3)
    ax.legend(fontsize=6, loc="lower center")
    fig.tight_layout()
    fig.savefig(args.out, dpi=110)
    print(f"plot_objective.py: wrote {args.out}")


if __name__ == "__main__":
    main()
