#!/usr/bin/env bash
# Installs what vwe_vo needs to build, test and run: ROS 1 (Debian's own packages on Debian 12,
# or an existing /opt/ros/noetic on Ubuntu 20.04), Ceres, OpenCV, Eigen, GoogleTest, Google
# Benchmark, matplotlib. Idempotent: installs only the packages that are missing, and says so.
set -euo pipefail

log() { printf '[install_deps] %s\n' "$*"; }

SUDO=""
if [ "$(id -u)" != 0 ]; then
  if command -v sudo >/dev/null 2>&1; then SUDO="sudo"; else
    log "not root and no sudo: install the packages below by hand"; fi
fi

common_pkgs=(libceres-dev libopencv-dev libeigen3-dev libgtest-dev libbenchmark-dev
             python3-matplotlib python3-numpy python3-yaml zlib1g-dev libyaml-cpp-dev nlohmann-json3-dev xvfb imagemagick clang-format clang)

if [ -f /opt/ros/noetic/setup.bash ]; then
  log "found /opt/ros/noetic: using it (Ubuntu 20.04 + Noetic)"
  pkgs=("${common_pkgs[@]}" ros-noetic-ros-base ros-noetic-rosbag ros-noetic-tf2-ros
        ros-noetic-tf2-eigen ros-noetic-tf2-geometry-msgs ros-noetic-nav-msgs
        ros-noetic-sensor-msgs ros-noetic-rostest ros-noetic-rviz ros-noetic-nodelet
        ros-noetic-pluginlib)
else
  log "using Debian's ROS 1 packages (no /opt/ros/noetic)"
  pkgs=("${common_pkgs[@]}" ros-core-dev catkin libroscpp-dev librosbag-dev
        libtf2-ros-dev libtf2-eigen-dev libtf2-geometry-msgs-dev
        libsensor-msgs-dev libnav-msgs-dev libgeometry-msgs-dev libvisualization-msgs-dev
        libstd-msgs-dev ros-message-generation python3-rostest python3-rosbag rosbash
        rviz ros-robot-state-publisher python3-geometry-msgs python3-nav-msgs
        python3-tf2-ros libclang-rt-14-dev libnodeletlib-dev libnodeletlib-tools python3-nodelet
        pluginlib-dev)
fi

missing=()
for p in "${pkgs[@]}"; do
  if ! dpkg-query -W -f='${Status}' "$p" 2>/dev/null | grep -q "install ok installed"; then
    missing+=("$p")
  fi
done

if [ ${#missing[@]} -eq 0 ]; then
  log "all ${#pkgs[@]} packages already installed"
  exit 0
fi

log "installing ${#missing[@]} missing packages: ${missing[*]}"
export DEBIAN_FRONTEND=noninteractive
$SUDO apt-get update -qq
$SUDO apt-get install -y -qq "${missing[@]}" \
  > /tmp/vwe_vo_install_deps.log 2>&1 || {
    log "apt-get install failed; last lines of /tmp/vwe_vo_install_deps.log:"
    tail -n 30 /tmp/vwe_vo_install_deps.log; exit 1; }
log "done"
