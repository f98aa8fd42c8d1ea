#!/usr/bin/python3
"""Live benchmark: the whole system (launch/replay.launch, rviz off) replayed by
scripts/replay_check.py at rate 1 and rate 2 on the simulated sequences, written to
OUT/live.json: per run the CPU per data-second of every process (with nodelets: the manager, and
each node's worker thread by name), everything dropped (front-end windows skipped behind, event
packets lost before a node, inputs lost to full queues, mapper events thinned waiting, resets) and
the accuracy of /vwe/odom against /gt/pose (rotation RMSE over 1 s and ATE in % of the path, by
vwe_vo_eval). The keys are documented in docs/evaluation.md. street_* sequences run with
config/car.yaml (car_rigid.yaml where the simulated car has no suspension), and every sequence with use_odom:=true (the wheel odometry of the bag), as the
offline benchmark does. Each run replays the whole bag in real time (40 s of data: 45-80 s of
wall time per run), so run it on an otherwise idle machine; the load average is recorded.

    source scripts/ros_env.sh
    scripts/bench_live.py [--out out/bench] [--rates 1,2] [--nodelet true|false|both]
        [--sequences-dir DIR] [SEQUENCE ...]      (default: indoor_long street_long)
"""
import argparse
import json
import os
import platform
import subprocess
import sys
import time

from bench_pipeline import config_for  # the vehicle's configuration, as offline

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))


def launch_args(seq, nodelet):
    args = ["use_odom:=true", "nodelet:=%s" % ("true" if nodelet else "false")]
    if seq.startswith("street"):
        args.append("config:=" + config_for(seq))
    return args


def drops(summary):
    """What the system lost, summed over the nodes (None where a node sent no status line)."""
    nodes = summary.get("nodes", {})
    out = {"windows_skipped": 0, "packets_lost": 0, "queue_full": 0, "resets": 0,
           "mapping_events_thinned_waiting": 0, "mapping_events_thinned": 0, "nodes_without_status": []}
    for name, c in nodes.items():
        if c is None:
            out["nodes_without_status"].append(name)
            continue
        out["windows_skipped"] += c.get("windows_skipped_behind", 0)
        out["packets_lost"] += max(c.get("packets_lost_seq", 0), c.get("packets_lost_before_node", 0))
        out["queue_full"] += c.get("queue_full", 0)
        out["resets"] += c.get("resets", 0)
        if name == "mapping_node":
            out["mapping_events_thinned_waiting"] = c.get("events_thinned_waiting", 0)
            out["mapping_events_thinned"] = c.get("events_thinned", 0)
    return out


def run(seq, bag, rate, nodelet, out_dir):
    cmd = [sys.executable, os.path.join(ROOT, "scripts", "replay_check.py"), bag, "--rate", "%g" % rate,
           "--out", out_dir, "--"] + launch_args(seq, nodelet)
    print("[bench_live] %s" % " ".join(cmd), flush=True)
    t0 = time.time()
    r = subprocess.run(cmd, stdout=subprocess.PIPE, stderr=subprocess.STDOUT, universal_newlines=True)
    print(r.stdout, end="", flush=True)
    path = os.path.join(out_dir, "summary.json")
    if not os.path.exists(path):
        return {"error": "replay_check wrote no summary (exit %d)" % r.returncode}
    s = json.load(open(path))
    nodes = s.get("nodes", {})
    result = {
        "sequence": seq, "rate": rate, "nodelet": s.get("nodelet", nodelet), "ok": r.returncode == 0,
        "played_to_end": s.get("played_to_end"), "wall_s": round(time.time() - t0, 1),
        "bag_duration_s": s.get("bag_duration_s"), "load_average": s.get("load_average"),
        "cpu_per_data_s": {"total": s.get("total_cpu_per_data_s"),
                           "processes": {n: p["cpu_per_data_s"] for n, p in s.get("processes", {}).items()},
                           "workers": {n: c.get("worker_cpu_per_data_s") for n, c in nodes.items() if c}},
        "drops": drops(s),
        "odom": {"rot_rmse_deg_s": s.get("rpe_rot_rmse_deg_s"), "rot_median_deg_s": s.get("rpe_rot_median_deg_s"),
                 "ate_percent_of_path": s.get("ate_percent_of_path"), "tracked_fraction": s.get("tracked_fraction")},
        "launch_args": launch_args(seq, nodelet), "summary": os.path.relpath(path, ROOT),
    }
    return result


def main():
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("sequences", nargs="*", default=["indoor_long", "street_long"])
    ap.add_argument("--out", default=os.path.join(ROOT, "out", "bench"))
    ap.add_argument("--rates", default="1,2", help="playback rates, comma-separated (default 1,2)")
    ap.add_argument("--nodelet", default="true", choices=["true", "false", "both"],
                    help="nodes as nodelets in one manager, as separate processes, or both (default true)")
    ap.add_argument("--sequences-dir", default=os.path.join(ROOT, "out", "sequences"),
                    help="where NAME/NAME.bag are (default out/sequences, generated when missing)")
    a = ap.parse_args()
    rates = [float(x) for x in a.rates.split(",")]
    modes = {"true": [True], "false": [False], "both": [True, False]}[a.nodelet]
    missing = [s for s in a.sequences if not os.path.exists(os.path.join(a.sequences_dir, s, s + ".bag"))]
    if missing:
        if os.path.abspath(a.sequences_dir) != os.path.join(ROOT, "out", "sequences"):
            sys.exit("bench_live: no bag for %s in %s" % (", ".join(missing), a.sequences_dir))
        subprocess.run(["bash", os.path.join(ROOT, "scripts", "make_sequences.sh")] + missing, check=True)
    os.makedirs(a.out, exist_ok=True)
    result = {"machine": {"cpus": os.cpu_count(), "platform": platform.platform()},
              "load_average_start": [round(x, 2) for x in os.getloadavg()], "runs": []}
    for seq in a.sequences:
        bag = os.path.join(a.sequences_dir, seq, seq + ".bag")
        for nodelet in modes:
            for rate in rates:
                name = "%s_rate%g_%s" % (seq, rate, "nodelet" if nodelet else "processes")
                result["runs"].append(run(seq, bag, rate, nodelet, os.path.join(a.out, "live", name)))
    path = os.path.join(a.out, "live.json")
    with open(path, "w") as f:
        json.dump(result, f, indent=2)
    print("[bench_live] %-12s %4s %-9s %9s %7s %7s %6s %6s %6s %9s %7s" % (
        "sequence", "rate", "mode", "core-s/s", "skipped", "lost", "qfull", "resets", "mapthin",
        "rot deg/s", "ATE %"))
    for r in result["runs"]:
        if "error" in r:
            print("[bench_live] %s" % r["error"])
            continue
        d, o = r["drops"], r["odom"]
        fmt = lambda v, f: (f % v) if v is not None else "-"
        print("[bench_live] %-12s %4g %-9s %9s %7d %7d %6d %6d %6d %9s %7s" % (
            r["sequence"], r["rate"], "nodelet" if r["nodelet"] else "processes",
            fmt(r["cpu_per_data_s"]["total"], "%.3f"), d["windows_skipped"], d["packets_lost"], d["queue_full"],
            d["resets"], d["mapping_events_thinned_waiting"], fmt(o["rot_rmse_deg_s"], "%.3f"),
            fmt(o["ate_percent_of_path"], "%.2f")))
    print("[bench_live] JSON in %s" % path)
    return 0 if all(r.get("ok") for r in result["runs"]) else 1


if __name__ == "__main__":
    sys.exit(main())
