#!/usr/bin/python3
"""Collects the evaluator's JSON and the offline runner's report of every sequence under a demo
folder into one metrics table in the layout of the paper's Table I (RMSE and median of rotation
and translation-direction RPE in deg/s), plus ATE %, tracked fraction and real-time factor.
Writes OUT/metrics.json and OUT/metrics.md and prints the Markdown table.

usage: metrics_table.py DEMO_DIR
  DEMO_DIR/<sequence>/report.json, DEMO_DIR/<sequence>/eval_<method>.json (method odom: the
  continuous odometry backend_node would publish live, vwe_vo_offline's odom.tum)"""
import glob
import json
import os
import sys


def fmt(v, digits=3):
    return "-" if v is None else ("%.*f" % (digits, v))


def main():
    root = sys.argv[1]
    rows = []
    for seq_dir in sorted(glob.glob(os.path.join(root, "*", ""))):
        seq = os.path.basename(os.path.dirname(seq_dir))
        report_path = os.path.join(seq_dir, "report.json")
        report = json.load(open(report_path)) if os.path.exists(report_path) else {}
        for ev_path in sorted(glob.glob(os.path.join(seq_dir, "eval_*.json"))):
            method = os.path.basename(ev_path)[len("eval_"):-len(".json")]
            ev = json.load(open(ev_path))
            rpe = ev["rpe"]
            stage = report.get("stages", {}).get(method, {})
            own_run = os.path.join(seq_dir, method + "_run", "report.json")  # demo.sh: the baseline's own run
            if not stage and os.path.exists(own_run):
                stage = json.load(open(own_run)).get("stages", {}).get(method, {})
            rows.append({
                "sequence": seq, "method": method,
                "rot_rmse_deg_s": rpe["rot_rmse_deg_s"], "rot_median_deg_s": rpe["rot_median_deg_s"],
                "trans_dir_rmse_deg_s": rpe["trans_dir_rmse_deg_s"],
                "trans_dir_median_deg_s": rpe["trans_dir_median_deg_s"],
                "yaw_rate_rmse_deg_s": ev.get("yaw_rate_rmse_deg_s"),
                "ate_percent": ev["ate"]["percent_of_path"], "ate_scale": ev["ate"]["scale"],
                "path_length_m": ev["path_length_m"], "tracked_fraction": ev["tracked_fraction"],
                # odom is the back-end's live output (/vwe/odom): no stage of its own. The back-end
                # runs beside the front-end, so its row gives both together by the wall clock (its
                # busy time alone, shared with the front-end, is in report.json).
                "real_time_factor": None if method == "odom" else
                report["event_pipeline"]["real_time_factor"] if method == "backend" and "event_pipeline" in report
                else stage.get("real_time_factor", report.get("real_time_factor")),
            })
    json.dump(rows, open(os.path.join(root, "metrics.json"), "w"), indent=2)
    lines = ["| sequence | method | RMSE(R) | Median(R) | RMSE(t) | Median(t) | yaw-rate RMSE | ATE % | tracked | RTF |",
             "|---|---|---|---|---|---|---|---|---|---|"]
    for r in rows:
        lines.append("| %s | %s | %s | %s | %s | %s | %s | %s | %s | %s |" % (
            r["sequence"], r["method"], fmt(r["rot_rmse_deg_s"]), fmt(r["rot_median_deg_s"]),
            fmt(r["trans_dir_rmse_deg_s"]), fmt(r["trans_dir_median_deg_s"]), fmt(r["yaw_rate_rmse_deg_s"]),
            fmt(r["ate_percent"], 2), fmt(100 * r["tracked_fraction"], 1) + " %", fmt(r["real_time_factor"])))
    text = ("RPE over 1 s in deg/s (R: rotation, t: translation direction); ATE after Sim(3) in % of path length;\n"
            "RTF: processing time / data duration, of the stage alone; backend: front-end + back-end by the wall clock.\n\n") + "\n".join(lines) + "\n"
    open(os.path.join(root, "metrics.md"), "w").write(text)
    print(text)
    return 0 if rows else 1


if __name__ == "__main__":
    sys.exit(main())
