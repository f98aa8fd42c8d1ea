# Sourced (bash) by the Makefile and scripts: a shell in which ROS 1 tools work.
# - The machine's default python3 may be a pyenv interpreter without the ROS Python modules;
#   catkin and rosbag's helpers call the first python3 on PATH, so the system one goes first.
# - On Ubuntu 20.04 + Noetic, /opt/ros/noetic is sourced; Debian 12 needs nothing more.
# - When the workspace is built, its devel space is sourced too (rosrun vwe_vo ...).
export PATH=/usr/bin:/bin:/usr/sbin:/sbin:$PATH
if [ -f /opt/ros/noetic/setup.bash ]; then
  # shellcheck disable=SC1091
  source /opt/ros/noetic/setup.bash
fi
_vwe_root="$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)"
VWE_WS="${VWE_WS:-$_vwe_root/.build/ws}"
if [ -f "$VWE_WS/devel/setup.bash" ]; then
  # shellcheck disable=SC1091
  source "$VWE_WS/devel/setup.bash"
fi
export VWE_WS
unset _vwe_root
