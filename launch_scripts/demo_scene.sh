#!/usr/bin/env bash
# Demo scene as separate processes: skin_sim_node + device bridge + simulated Touch.
# Usage: launch_scripts/demo_scene.sh [hand_path]   (see: .venv/bin/skin-sim mock-tool --list)
set -euo pipefail
cd "$(dirname "$0")/.."
exec .venv/bin/skin-sim scene demo-device --path "${1:-press_all_layers}"
