#!/usr/bin/env bash
# Replay scene: a recorded bag's tool inputs streamed at recorded timing to a fresh skin_sim_node,
# its outputs recorded and compared with the offline replay of the same bag.
# Usage: launch_scripts/replay_scene.sh BAG [OUT]
set -euo pipefail
cd "$(dirname "$0")/.."
exec .venv/bin/skin-sim replay "$1" --out "${2:-out/replay}" --live
