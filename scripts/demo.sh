#!/usr/bin/env bash
# Set up (idempotent) and run the headless demo scene. Extra arguments go to `skin-sim demo`.
set -euo pipefail
cd "$(dirname "$0")/.."
bash scripts/setup.sh
export ROS_AUTOMATIC_DISCOVERY_RANGE="${ROS_AUTOMATIC_DISCOVERY_RANGE:-LOCALHOST}"
export ROS_LOG_DIR="${ROS_LOG_DIR:-$PWD/out/ros_log}"
exec .venv/bin/skin-sim demo "$@"
