#!/usr/bin/env bash
# Debian's ROS 1 for `agrisim ros --ros 1` (and its tests): roscore, rospy, rostopic, rosservice
# and the message packages the bridge speaks. Debian builds them for its own python3; agrisim
# imports them from a Python of the same version (agrisim.plugins.ros.rospy_env).
set -euo pipefail

PACKAGES="ros-core python3-actionlib python3-sensor-msgs python3-tf2-msgs python3-trajectory-msgs python3-std-srvs"
if command -v roscore >/dev/null 2>&1 && /usr/bin/python3 -c "import rospy, actionlib, sensor_msgs.msg, tf2_msgs.msg, trajectory_msgs.msg, std_srvs.srv" 2>/dev/null; then
  exit 0
fi
if ! command -v apt-get >/dev/null 2>&1; then
  echo "agrisim ROS set-up: no apt-get; install ROS 1 ($PACKAGES on Debian 12) for agrisim ros --ros 1" >&2
  exit 0
fi
if [ "$(id -u)" -eq 0 ]; then SUDO=""; else SUDO="sudo"; fi
echo "agrisim ROS set-up: installing Debian's ROS 1 ($PACKAGES)"
$SUDO apt-get update -qq
DEBIAN_FRONTEND=noninteractive $SUDO apt-get install -y -qq --no-install-recommends $PACKAGES >/dev/null
