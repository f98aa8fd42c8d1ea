#!/bin/bash
# Replays a bag with rviz on a virtual display (Xvfb) and takes a screenshot of the whole screen.
#   scripts/rviz_screenshot.sh BAG [OUT.png] [WAIT_S=25] [extra replay.launch args...]
# e.g. (a short simulated bag):
#   source scripts/ros_env.sh
#   .build/ws/devel/lib/vwe_vo/vwe_vo_sim --sequence indoor_circle --format bag --duration 8 --out /tmp/sysbag
#   scripts/rviz_screenshot.sh /tmp/sysbag/indoor_circle.bag /tmp/rviz.png
# Needs xvfb and imagemagick. Ends only the processes it started (Xvfb, roscore, roslaunch).
bag="${1:?usage: $0 BAG [OUT.png] [WAIT_S] [replay.launch args...]}"
out="${2:-rviz_screenshot.png}"
wait_s="${3:-25}"
shift $(( $# < 3 ? $# : 3 ))
root="$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)"
# shellcheck disable=SC1091
source "$root/scripts/ros_env.sh"
set -u  # after the ROS set-up scripts, which read unset variables
for tool in Xvfb import roslaunch; do
  command -v "$tool" >/dev/null || { echo "rviz_screenshot: $tool not found (apt-get install xvfb imagemagick)"; exit 1; }
done
[ -f "$bag" ] || { echo "rviz_screenshot: no bag $bag"; exit 1; }
bag="$(realpath "$bag")"  # rosbag play runs in ~/.ros: a relative path would not open

display=":99"
port=$(( 11700 + RANDOM % 200 ))  # a private master: never the user's roscore
export ROS_MASTER_URI="http://localhost:$port"
log_dir="$(mktemp -d /tmp/rviz_screenshot.XXXXXX)"
pids=()
cleanup() {
  # Newest first: roslaunch ends its nodes (SIGINT), then the master, then Xvfb.
  for (( i=${#pids[@]}-1; i>=0; i-- )); do
    kill -INT "${pids[$i]}" 2>/dev/null
    for _ in $(seq 1 50); do kill -0 "${pids[$i]}" 2>/dev/null || break; sleep 0.2; done
    kill -KILL "${pids[$i]}" 2>/dev/null
  done
}
trap cleanup EXIT

Xvfb "$display" -screen 0 1280x800x24 >"$log_dir/xvfb.log" 2>&1 &
pids+=($!)
sleep 1
roscore -p "$port" >"$log_dir/roscore.log" 2>&1 &
pids+=($!)
for _ in $(seq 1 50); do rostopic list >/dev/null 2>&1 && break; sleep 0.2; done
DISPLAY="$display" roslaunch vwe_vo replay.launch bag:="$bag" "$@" >"$log_dir/roslaunch.log" 2>&1 &
pids+=($!)
echo "rviz_screenshot: replaying $bag for ${wait_s} s (logs in $log_dir)"
sleep "$wait_s"
DISPLAY="$display" import -window root "$out" && echo "rviz_screenshot: wrote $out"
