#!/usr/bin/python3
"""Replays a bag through launch/replay.launch (rviz off) and reports how the live system did:
the rotation RMSE of /vwe/odom against the bag's /gt/pose (relative pose error over 1 s, by the
core evaluator vwe_vo_eval), the ATE in % of the path, the counters of what each node dropped
(front-end windows skipped behind, input queues full, event packets that never reached a node,
mapper events dropped, resets) and the CPU each process used per second of data: with nodelets
(replay.launch's default) the manager process runs every node, and the CPU of each node's worker
thread is told apart by its name; with `-- nodelet:=false` each node is its own process.

    source scripts/ros_env.sh
    scripts/replay_check.py BAG [--rate 1.0] [--out DIR] [-- extra replay.launch args, e.g. use_odom:=true]

It starts its own roslaunch (and a master if none runs), waits until the bag has played and the
nodes are done, reads each node's final status line from /rosout (by its "NAME: " prefix: in a
nodelet manager every node logs under the manager's name), stops the launch and prints a summary; DIR (default: a temporary directory) keeps odom.tum, gt.tum, eval.json, summary.json
and roslaunch.log. Exit code 0 when the evaluation ran, 1 otherwise.
"""
import argparse
import json
import os
import re
import signal
import subprocess
import sys
import tempfile
import threading
import time

import rosbag
import rosgraph
import rospy
from geometry_msgs.msg import PoseStamped
from nav_msgs.msg import Odometry
from rosgraph_msgs.msg import Log

NODES = ("frontend_node", "backend_node", "mapping_node")
MANAGER = "vwe_vo_manager"  # launch/nodes.launch's nodelet manager
STATUS_PERIOD_S = 2.0

# Counters of the nodes' status lines (src/ros/*_node.cpp logStatus()).
PATTERNS = {
    "frontend_node": {
        "windows": r"frontend_node: (\d+) windows \(",
        "windows_split": r"\((\d+) split in two\)",
        "windows_one_sided": r"\((\d+) one-sided,",
        "windows_one_sided_near": r"one-sided, (\d+) one-sided but near\)",
        "arcs": r"-> (\d+) arcs",
        "arcs_ok": r"\((\d+) ok,",
        "windows_lost": r"(\d+) lost,",
        "windows_skipped_behind": r"(\d+) windows skipped behind",
        "windows_thinned_behind": r"(\d+) thinned behind",
        "resets": r"(\d+) resets",
        "real_time_factor": r"real-time factor ([0-9.]+)",
    },
    "backend_node": {
        "refinements": r"backend_node: (\d+) refinements",
        "arcs_in": r"(\d+) arcs in",
        "arcs_lost_held": r"(\d+) lost/low held",
        "resets": r"(\d+) resets",
    },
    "mapping_node": {
        "keyframes": r"mapping_node: (\d+) keyframes",
        "keyframes_left_out": r"(\d+) left out by the rate limit",
        "events_thinned_waiting": r"(\d+) thinned waiting",
        "events_not_covered": r"(\d+) not covered by the trajectory",
        "events_thinned": r"(\d+) thinned",
        "resets": r"(\d+) resets",
    },
}


def parse_input(text):
    """The input counters of a status line (NodeInputBase::statusLine(): "input: events in=120
    lost=0 ... dropped=0; odom in=60 ...; camera_info refused=0") as {kind: {key: value}}."""
    m = re.search(r"input: (.*)$", text)
    kinds = {}
    for part in (m.group(1).split(";") if m else []):
        tokens = part.split()
        if len(tokens) < 2:
            continue
        fields = {}
        for kv in tokens[1:]:
            k, _, v = kv.partition("=")
            if v.isdigit():
                fields[k] = int(v)
        kinds[tokens[0]] = fields
    return kinds


def parse_status(node, text):
    out = {}
    for key, pattern in PATTERNS[node].items():
        m = re.search(pattern, text)
        if m:
            out[key] = float(m.group(1)) if "." in m.group(1) else int(m.group(1))
    kinds = parse_input(text)
    events = kinds.get("events", {})
    if "in" in events:
        out["packets_in"] = events["in"]
    if "lost" in events:
        out["packets_lost_seq"] = events["lost"]  # header.seq gaps: lost before the callback
    # Inputs lost to a full queue, every kind together (events: packets).
    out["queue_full"] = sum(k.get("dropped", 0) for name, k in kinds.items() if name != "camera_info")
    out["input"] = kinds
    return out


class Recorder:
    def __init__(self):
        self.lock = threading.Lock()
        self.odom, self.gt = [], []
        self.status = {}  # node -> (wall time, text) of its newest status line
        self.last_odom_wall = time.time()
        rospy.Subscriber("/vwe/odom", Odometry, self.on_odom, queue_size=1000)
        rospy.Subscriber("/gt/pose", PoseStamped, self.on_gt, queue_size=1000)
        rospy.Subscriber("/rosout", Log, self.on_log, queue_size=1000)

    def on_odom(self, m):
        with self.lock:
            self.odom.append((m.header.stamp.to_sec(), m.pose.pose))
            self.last_odom_wall = time.time()

    def on_gt(self, m):
        with self.lock:
            self.gt.append((m.header.stamp.to_sec(), m.pose))

    def on_log(self, m):
        # By the message's own prefix: nodelets log under the manager's node name.
        node = m.msg.split(":", 1)[0]
        if node in NODES and re.search(list(PATTERNS[node].values())[0], m.msg):  # a status line
            with self.lock:
                self.status[node] = (time.time(), m.msg)


def node_pid(node):
    """The process id of a ROS node on this machine, or None."""
    try:
        import rosnode
        import xmlrpc.client
        uri = rosnode.get_api_uri(rosgraph.Master("/replay_check"), "/" + node, skip_cache=True)
        _, _, pid = xmlrpc.client.ServerProxy(uri).getPid("/replay_check")
        return pid
    except Exception:  # the node is gone or on another machine
        return None


def stat_cpu_s(path):
    """CPU seconds (user + system) of a /proc/.../stat file (a process: all its threads)."""
    with open(path) as f:
        fields = f.read().rsplit(")", 1)[1].split()
    return (int(fields[11]) + int(fields[12])) / os.sysconf("SC_CLK_TCK")


def process_cpu(pid):
    """{"cpu_s": the process's CPU seconds, "threads": {thread name: CPU seconds}} or None."""
    try:
        threads = {}
        for tid in os.listdir("/proc/%d/task" % pid):
            with open("/proc/%d/task/%s/comm" % (pid, tid)) as f:
                name = f.read().strip()
            threads[name] = threads.get(name, 0.0) + stat_cpu_s("/proc/%d/task/%s/stat" % (pid, tid))
        return {"cpu_s": stat_cpu_s("/proc/%d/stat" % pid), "threads": threads}
    except (OSError, ValueError):
        return None


def write_tum(path, poses):
    with open(path, "w") as f:
        last = None
        for t, p in poses:
            if last is not None and t <= last:
                continue  # the evaluator wants strictly increasing time
            last = t
            f.write("%.9f %.6f %.6f %.6f %.9f %.9f %.9f %.9f\n" % (
                t, p.position.x, p.position.y, p.position.z,
                p.orientation.x, p.orientation.y, p.orientation.z, p.orientation.w))


def wait(pred, timeout_s):
    end = time.time() + timeout_s
    while time.time() < end and not rospy.is_shutdown():
        if pred():
            return True
        time.sleep(0.1)
    return pred()


def main():
    argv = sys.argv[1:]
    extra = []
    if "--" in argv:
        extra = argv[argv.index("--") + 1:]
        argv = argv[:argv.index("--")]
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("bag")
    ap.add_argument("--rate", type=float, default=1.0, help="playback rate (default 1.0)")
    ap.add_argument("--out", help="output directory (default: a new temporary one)")
    ap.add_argument("--timeout", type=float, default=120.0,
                    help="wall seconds allowed beyond the bag's duration / rate (default 120)")
    a = ap.parse_args(argv)
    bag_path = os.path.abspath(a.bag)
    out = a.out or tempfile.mkdtemp(prefix="replay_check_")
    os.makedirs(out, exist_ok=True)

    with rosbag.Bag(bag_path) as bag:
        packets = bag.get_message_count("/dvs/events")
        gt_count = bag.get_message_count("/gt/pose")
        duration_s = bag.get_end_time() - bag.get_start_time()
        gt_end = max((t.to_sec() for _, _, t in bag.read_messages(topics=["/gt/pose"])), default=None)
    if gt_end is None:
        sys.exit("replay_check: %s has no /gt/pose (ground truth) to evaluate against" % bag_path)

    log = open(os.path.join(out, "roslaunch.log"), "w")
    launch = subprocess.Popen(
        ["roslaunch", "vwe_vo", "replay.launch", "bag:=" + bag_path, "rviz:=false", "rate:=%g" % a.rate,
         "status_period_s:=%g" % STATUS_PERIOD_S] + extra,
        stdout=log, stderr=subprocess.STDOUT, start_new_session=True)
    try:
        if not wait(rosgraph.is_master_online, 30.0):
            sys.exit("replay_check: no ROS master came up (see %s/roslaunch.log)" % out)
        rospy.init_node("replay_check", anonymous=True, disable_signals=True)
        rec = Recorder()
        wall0 = time.time()
        print("replay_check: playing %s (%.1f s, %d event packets) at rate %g; output in %s"
              % (bag_path, duration_s, packets, a.rate, out), flush=True)
        played = wait(lambda: launch.poll() is not None or (rec.gt and rec.gt[-1][0] >= gt_end - 1e-3),
                      duration_s / a.rate + a.timeout)
        # The nodes finish their backlog: no new odometry for 3 s, then one more status line each.
        wait(lambda: time.time() - rec.last_odom_wall > 3.0, a.timeout)
        done = time.time()
        wait(lambda: all(n in rec.status and rec.status[n][0] > done for n in NODES), 3 * STATUS_PERIOD_S + 5)
        wall = done - wall0
        pids = {n: node_pid(n) for n in NODES + (MANAGER,)}
        cpu = {pid: process_cpu(pid) for pid in set(pids.values()) if pid is not None}
        load = os.getloadavg()
    finally:
        if launch.poll() is None:
            os.killpg(launch.pid, signal.SIGINT)
            try:
                launch.wait(20)
            except subprocess.TimeoutExpired:
                os.killpg(launch.pid, signal.SIGKILL)
        log.close()

    with rec.lock:
        odom, gt, status = list(rec.odom), list(rec.gt), dict(rec.status)
    write_tum(os.path.join(out, "odom.tum"), odom)
    write_tum(os.path.join(out, "gt.tum"), gt)
    summary = {"bag": bag_path, "rate": a.rate, "played_to_end": played, "wall_s": round(wall, 2),
               "bag_duration_s": round(duration_s, 3), "bag_event_packets": packets,
               "gt_poses": {"bag": gt_count, "received": len(gt)}, "odom_messages": len(odom),
               "load_average": [round(x, 2) for x in load], "nodes": {}}
    # With nodelets the nodes run in the manager, and each node's name is its small `nodelet load`
    # process (counted in the total too).
    nodelets = pids.get(MANAGER) is not None
    summary["nodelet"] = nodelets
    summary["processes"] = {}
    for n in (MANAGER,) + NODES:
        if pids[n] is not None and cpu.get(pids[n]) is not None:
            summary["processes"][n] = {"cpu_s": round(cpu[pids[n]]["cpu_s"], 1),
                                       "cpu_per_data_s": round(cpu[pids[n]]["cpu_s"] / duration_s, 3)}
    summary["total_cpu_per_data_s"] = round(sum(p["cpu_s"] for p in summary["processes"].values())
                                            / duration_s, 3)
    for n in NODES:
        if n in status:
            c = parse_status(n, status[n][1])
            if "packets_in" in c:
                c["packets_lost_before_node"] = packets - c["packets_in"]
            proc = cpu.get(pids[MANAGER] if nodelets else pids[n])
            if not nodelets and proc is not None:  # the node's process, all its threads
                c["cpu_s"] = round(proc["cpu_s"], 1)
                c["cpu_per_data_s"] = round(proc["cpu_s"] / duration_s, 3)
            if proc is not None and n in proc["threads"]:  # its worker thread (named after it)
                c["worker_cpu_per_data_s"] = round(proc["threads"][n] / duration_s, 3)
            summary["nodes"][n] = c
        else:
            summary["nodes"][n] = None

    ok = True
    eval_json = os.path.join(out, "eval.json")
    if len(odom) < 2:
        print("replay_check: no /vwe/odom received: nothing to evaluate")
        ok = False
    else:
        r = subprocess.run(["rosrun", "vwe_vo", "vwe_vo_eval", "--gt", os.path.join(out, "gt.tum"),
                            "--est", os.path.join(out, "odom.tum"), "--json", eval_json],
                           stdout=subprocess.PIPE, stderr=subprocess.STDOUT, universal_newlines=True)
        if r.returncode != 0:
            print("replay_check: vwe_vo_eval failed:\n" + r.stdout)
            ok = False
        else:
            e = json.load(open(eval_json))
            summary["rpe_rot_rmse_deg_s"] = e["rpe"]["rot_rmse_deg_s"]
            summary["rpe_rot_median_deg_s"] = e["rpe"]["rot_median_deg_s"]
            summary["ate_percent_of_path"] = e["ate"]["percent_of_path"]
            summary["tracked_fraction"] = e["tracked_fraction"]
    with open(os.path.join(out, "summary.json"), "w") as f:
        json.dump(summary, f, indent=2)

    print("replay_check: %s at rate %g: %s in %.1f s wall (load average %.2f %.2f %.2f)" % (
        os.path.basename(bag_path), a.rate, "played to the end" if played else "DID NOT play to the end", wall,
        *load))
    if "rpe_rot_rmse_deg_s" in summary:
        print("  /vwe/odom vs /gt/pose: rotation RMSE %.3f deg/s (median %.3f) over 1 s, ATE %.2f %% of path, "
              "tracked %.0f %%" % (summary["rpe_rot_rmse_deg_s"], summary["rpe_rot_median_deg_s"],
                                   summary["ate_percent_of_path"], 100 * summary["tracked_fraction"]))
    print("  CPU per data-second, all nodes: %.3f core-s (%s)" % (
        summary["total_cpu_per_data_s"], ", ".join("%s %.3f" % (n, p["cpu_per_data_s"])
                                                    for n, p in summary["processes"].items())))
    for n in NODES:
        c = summary["nodes"][n]
        print("  %-14s %s" % (n, "no status line seen" if c is None else
                              ", ".join("%s %s" % (k, v) for k, v in c.items() if k != "input")))
    return 0 if ok else 1


if __name__ == "__main__":
    sys.exit(main())
