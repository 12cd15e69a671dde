#!/usr/bin/env bash
# Headless CI scene: skin_sim_node + mock tool publisher following a scripted trajectory.
set -euo pipefail
cd "$(dirname "$0")/.."
exec .venv/bin/skin-sim scene demo-mock --path "${1:-press_hold_release}"
