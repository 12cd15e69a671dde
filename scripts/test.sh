#!/usr/bin/env bash
# Set up (idempotent), lint, type-check the runtime, and run the whole test suite (unit, property and ROS integration).
set -euo pipefail
cd "$(dirname "$0")/.."
bash scripts/setup.sh
# headless Chromium for the browser tests of `skin-sim view` (tests/test_view.py skip without one)
if ! command -v chromium >/dev/null 2>&1; then
  if [ "$(id -u)" = 0 ] && command -v apt-get >/dev/null 2>&1; then
    { apt-get update -qq && DEBIAN_FRONTEND=noninteractive apt-get install -y -qq chromium >/dev/null; } \
      || echo "chromium install failed: the view's browser tests will skip"
  else
    echo "no chromium and not root (cannot apt-get install it): the view's browser tests will skip"
  fi
fi
export ROS_AUTOMATIC_DISCOVERY_RANGE=LOCALHOST
export ROS_LOG_DIR="${ROS_LOG_DIR:-$PWD/out/ros_log}"
LINT_PATHS=(skin_sim_node skin_sim_lab msgs_schema tests scripts launch_scripts)
.venv/bin/ruff check "${LINT_PATHS[@]}"
.venv/bin/ruff format --check "${LINT_PATHS[@]}"
# the type-checked paths: TYPED_PATHS, the whole runtime (mypy's settings, the stub-less packages: [tool.mypy] in
# pyproject.toml); skin_sim_lab, the figures and benchmarks, is linted but not type-checked
TYPED_PATHS=(msgs_schema skin_sim_node)
.venv/bin/mypy "${TYPED_PATHS[@]}"
.venv/bin/python -m pytest -q -p no:cacheprovider "$@"
