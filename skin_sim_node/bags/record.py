"""``skin-sim record OUT --scene demo-mock|demo-device``: record a scene's topics to a rosbag2 folder.

Starts the scene's processes (:class:`skin_sim_node.scenes.Scene`) on an isolated domain,
records the tool inputs (``tool/pose``, ``tool/twist``) and the node's outputs
(``tool/wrench``, ``tissue/contact``, ``tissue/height_map``, ``tissue/layer_heights``,
``diagnostics``; ``tissue/mesh`` with ``--mesh``; ``tissue/needle`` with ``--needle``) with an in-process raw recorder, each
message stamped with its receive time (``ros2 bag record`` semantics), until the tool
source finishes. The scene's process logs go to ``OUT_logs``.
"""

from __future__ import annotations

import argparse
import subprocess
import sys
import time
from pathlib import Path

from msgs_schema.parameters import validate_parameters
from msgs_schema.topics import TOPICS

from ..model.config import load_yaml
from ..scenes import DEFAULT_PARAMS, SCENES, Scene
from .io import STORAGES, BagWriter, register_project_type

START_DELAY_S = 3.0
"""Tool start delay: DDS discovery between three new processes took up to 1.6 s in our probe."""


def record_scene(
    out: Path,
    scene_kind: str,
    path: str,
    storage: str = "mcap",
    duration_s: float | None = None,
    mesh: bool = False,
    images: bool = True,
    params: Path = DEFAULT_PARAMS,
    start_delay_s: float = START_DELAY_S,
    needle: bool = False,
) -> dict[str, int]:
    """Record one scene run to ``out``; returns messages per topic key."""
    out = Path(out)
    if out.exists():
        raise FileExistsError(f"{out} exists already; choose a new bag folder")
    keys = ["tool_pose", "tool_twist", "tool_wrench", "contact", "diagnostics"]
    keys += ["height_map", "layer_heights"] if images else []
    keys += ["mesh"] if mesh else []
    if needle:  # tissue/needle (tool.shape 'needle'): the view draws the track from it
        if not register_project_type(TOPICS["needle"].type):  # the writer's type store must know NeedleState
            raise FileNotFoundError("skin_sim_msgs/msg/NeedleState.msg not found: cannot record tissue/needle")
        keys.append("needle")
    custom = {"skin_sim.scene": scene_kind, "skin_sim.path": path, "skin_sim.params": Path(params).name}
    validate_parameters(load_yaml(params))  # a bad parameter file: one line, and no bag folder written
    with Scene(out.parent / f"{out.name}_logs") as scene:
        from .recorder import Recorder, use_scene_env

        use_scene_env(scene.env)
        writer = BagWriter(out, storage, custom_data=custom)
        rec = Recorder(keys, writer, name="skin_sim_bag_recorder", executor="events")  # no publishing thread here
        try:
            node = scene.node(params=params)
            scene.wait_for_log(node, "live:", timeout_s=180)
            delay = ("--start-delay-s", f"{start_delay_s}")
            if scene_kind == "demo-device":
                scene.start("bridge", "bridge")
                source = scene.start("device", "device", "--hand-path", path, *delay)
            else:
                source = scene.start("mock_tool", "mock-tool", "--trajectory", path, *delay)
            print(f"recording {scene_kind} {path} (ROS_DOMAIN_ID={scene.env['ROS_DOMAIN_ID']}) -> {out}", flush=True)
            try:
                source.popen.wait(timeout=duration_s)
            except (subprocess.TimeoutExpired, KeyboardInterrupt):
                pass
            time.sleep(0.3)  # the node's answers to the last poses
        finally:
            rec.close()
            writer.close()
            codes = scene.stop_all()
    print("exit codes:", codes)
    return rec.counts


def main(argv=None) -> int:
    """``skin-sim record OUT``: run a scene and record its tool inputs and node outputs to the rosbag2 folder ``OUT``."""
    ap = argparse.ArgumentParser(prog="skin-sim record", description=__doc__.splitlines()[0])
    ap.add_argument("out", type=Path, help="new rosbag2 folder")
    ap.add_argument(
        "--scene", choices=sorted(SCENES), default="demo-mock", help="; ".join(f"{k}: {v}" for k, v in SCENES.items())
    )
    ap.add_argument("--path", default="press_hold_release", help="hand path / trajectory name (see skin-sim mock-tool --list)")
    ap.add_argument("--storage", choices=sorted(STORAGES), default="mcap", help="mcap (Jazzy's default) or sqlite3")
    ap.add_argument("--duration-s", type=float, help="stop after this long (default: when the tool is done)")
    ap.add_argument("--mesh", action="store_true", help="also record tissue/mesh (large)")
    ap.add_argument(
        "--needle", action="store_true", help="also record tissue/needle (a node with tissue.tool.shape 'needle'; skin-sim view)"
    )
    ap.add_argument("--no-images", action="store_true", help="skip tissue/height_map and tissue/layer_heights")
    ap.add_argument("--params", type=Path, default=DEFAULT_PARAMS)
    ap.add_argument("--start-delay-s", type=float, default=START_DELAY_S, help="tool start delay (DDS discovery)")
    args = ap.parse_args(argv)
    try:
        counts = record_scene(
            args.out,
            args.scene,
            args.path,
            args.storage,
            args.duration_s,
            args.mesh,
            not args.no_images,
            args.params,
            args.start_delay_s,
            args.needle,
        )
    except FileExistsError as exc:
        print(f"skin-sim record: error: {exc}", file=sys.stderr)
        return 2
    print(f"{args.out}: " + ", ".join(f"{k} {v}" for k, v in counts.items()))
    return 0 if counts.get("tool_pose") else 1


if __name__ == "__main__":
    raise SystemExit(main())
