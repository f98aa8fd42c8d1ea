#!/bin/bash
# Replays a bag with rviz on a virtual display (Xvfb) and takes a screenshot of the whole screen.
#   scripts/rviz_screenshot.sh BAG [OUT.png] [WAIT_S=25|end] [extra replay.launch args...]
# WAIT_S=end: at the end of the replay (the bag's duration / rate:=, plus the start-up delay).
# e.g. (a short simulated bag):
#   source scripts/ros_env.sh
#   .build/ws/devel/lib/vwe_vo/vwe_vo_sim --sequence indoor_circle --format bag --duration 8 --out /tmp/sysbag
#   scripts/rviz_screenshot.sh /tmp/sysbag/indoor_circle.bag /tmp/rviz.png
# a car on a street, the view following it (rviz/vwe_vo_car.rviz):
#   scripts/rviz_screenshot.sh out/sequences/street_long/street_long.bag /tmp/street.png end \
#       platform:=car config:=$PWD/config/car.yaml use_odom:=true
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

# The first free display from :99 (another Xvfb may hold one).
n=99
while [ -e "/tmp/.X$n-lock" ] || [ -e "/tmp/.X11-unix/X$n" ]; do n=$((n + 1)); done
display=":$n"
if [ "$wait_s" = end ]; then
  rate=1
  for a in "$@"; do case "$a" in rate:=*) rate="${a#rate:=}";; esac; done
  duration=$(/usr/bin/python3 -c "import rosbag,sys; b=rosbag.Bag(sys.argv[1]); print(b.get_end_time()-b.get_start_time())" "$bag")
  wait_s=$(/usr/bin/python3 -c "print(round($duration / $rate + 3 + 8))")  # replay.launch's delay of 3 s, start-up
fi
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
