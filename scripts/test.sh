#!/usr/bin/env bash
# Set up (idempotent), lint, and run the whole test suite (unit, property and ROS integration).
set -euo pipefail
cd "$(dirname "$0")/.."
bash scripts/setup.sh
export ROS_AUTOMATIC_DISCOVERY_RANGE=LOCALHOST
export ROS_LOG_DIR="${ROS_LOG_DIR:-$PWD/out/ros_log}"
.venv/bin/ruff check skin_sim_node msgs_schema tests scripts launch_scripts
.venv/bin/python -m pytest -q -p no:cacheprovider "$@"
