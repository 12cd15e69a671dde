"""``skin-sim record OUT --scene demo-mock|demo-device``: record a scene's topics to a rosbag2 folder.

Starts the scene's processes (:class:`skin_sim_node.scenes.Scene`) on an isolated domain,
records the tool inputs (``tool/pose``, ``tool/twist``) and the node's outputs
(``tool/wrench``, ``tissue/contact``, ``tissue/height_map``, ``tissue/layer_heights``,
``diagnostics``; ``tissue/mesh`` with ``--mesh``; ``tissue/needle`` with ``--needle``) with an in-process raw recorder, each
message stamped with its receive time (``ros2 bag record`` semantics), until the tool
source finishes. The scene's process logs go to ``OUT_logs``.

A parameter file with hands (``hand_ns``, ``second_hand_ns``; issue 32) records each hand's topics under its namespace
(``right/tool/pose``, ``left/tool/wrench``, ...) beside the tissue's, with a mock tool in each hand's namespace
(``--path`` the first, ``--second-path`` and ``--second-offset-m`` the second).
"""

from __future__ import annotations

import argparse
import subprocess
import sys
import time
from pathlib import Path

from msgs_schema.parameters import validate_parameters
from msgs_schema.topics import TOPICS, hand_topic

from ..model.config import load_yaml
from ..scenes import DEFAULT_PARAMS, SCENES, Scene
from .io import STORAGES, BagWriter, register_project_type
from .offline import hands_of

START_DELAY_S = 3.0
"""Tool start delay: DDS discovery between three new processes took up to 1.6 s in our probe."""


class HandsSceneError(ValueError):
    """A parameter file with hands and a scene that cannot drive them."""


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
    second_path: str | None = None,
    second_offset_m: tuple[float, float] = (0.0, 0.0),
    rate_hz: float | None = None,
) -> dict[str, int]:
    """Record one scene run to ``out``; returns messages per topic key (per ``<hand>/<topic>`` for a node with hands).

    Parameters
    ----------
    out : Path
        New bag folder.
    scene_kind : str
        A key of :data:`skin_sim_node.scenes.SCENES`.
    path : str
        The (first) hand's trajectory or hand path.
    storage : str
    duration_s : float, optional
        Stop after this long (default: when the tool sources are done).
    mesh, images, needle : bool
        Also record ``tissue/mesh``; the display grids; ``tissue/needle`` (each hand's with hands).
    params : Path
        The node's parameter file; its ``hand_ns`` / ``second_hand_ns`` say which hands exist (issue 32).
    start_delay_s : float
        The tool sources' start delay (DDS discovery).
    second_path : str, optional
        The second hand's trajectory (default ``path``).
    second_offset_m : (float, float)
        Where the second hand's trajectory is shifted in the sheet plane (m), as the mock tool's ``offset_x_m``,
        ``offset_y_m``.
    rate_hz : float, optional
        The mock tools' publish rate (Hz; default theirs, 1 kHz).
    """
    out = Path(out)
    if out.exists():
        raise FileExistsError(f"{out} exists already; choose a new bag folder")
    flat = load_yaml(params)
    validate_parameters(flat)  # a bad parameter file: one line, and no bag folder written
    hands = hands_of(params)
    if hands != ("",) and scene_kind != "demo-mock":
        raise HandsSceneError(f"{params} names hands ({', '.join(hands)}): record them with --scene demo-mock (a mock tool each)")
    tissue_keys = ["diagnostics"] + (["height_map", "layer_heights"] if images else []) + (["mesh"] if mesh else [])
    hand_keys = ["tool_pose", "tool_twist", "tool_wrench", "contact"]
    if needle:  # tissue/needle (tool.shape 'needle'): the view draws the track from it
        if not register_project_type(TOPICS["needle"].type):  # the writer's type store must know NeedleState
            raise FileNotFoundError("skin_sim_msgs/msg/NeedleState.msg not found: cannot record tissue/needle")
        hand_keys.append("needle")
    if hands == ("",):  # the single-tool layout, as before hands existed
        keys: list = hand_keys[:4] + tissue_keys + hand_keys[4:]
    else:
        keys = [(k, hand_topic(k, ns)) for ns in hands for k in hand_keys] + tissue_keys
    custom = {"skin_sim.scene": scene_kind, "skin_sim.path": path, "skin_sim.params": Path(params).name}
    paths = [path, second_path or path][: len(hands)]
    if len(hands) > 1:
        custom |= {
            "skin_sim.hands": ",".join(hands),
            "skin_sim.second_path": paths[1],
            "skin_sim.second_offset_m": f"{second_offset_m[0]:g} {second_offset_m[1]:g}",
        }
    with Scene(out.parent / f"{out.name}_logs") as scene:
        from .recorder import Recorder, use_scene_env

        use_scene_env(scene.env)
        writer = BagWriter(out, storage, custom_data=custom)
        rec = Recorder(keys, writer, name="skin_sim_bag_recorder", executor="events")  # no publishing thread here
        try:
            node = scene.node(params=params)
            scene.wait_for_log(node, "live:", timeout_s=180)
            delay = ("--start-delay-s", f"{start_delay_s}")
            rate = ("--rate-hz", f"{rate_hz:g}") if rate_hz else ()
            if scene_kind == "demo-device":
                scene.start("bridge", "bridge")
                sources = [scene.start("device", "device", "--hand-path", path, *delay)]
            elif hands == ("",):
                sources = [scene.start("mock_tool", "mock-tool", "--trajectory", path, *delay, *rate)]
            else:  # a mock tool in each hand's namespace, the second shifted beside the first
                sources = []
                for i, (ns, p) in enumerate(zip(hands, paths)):
                    dx, dy = second_offset_m if i else (0.0, 0.0)
                    ros = ("--ros-args", "-r", f"__ns:=/{ns}", "-p", f"offset_x_m:={dx:.6f}", "-p", f"offset_y_m:={dy:.6f}")
                    sources.append(scene.start(f"mock_tool_{ns}", "mock-tool", "--trajectory", p, *delay, *rate, *ros))
            what = ", ".join(f"{ns}: {p}" for ns, p in zip(hands, paths)) if hands != ("",) else path
            print(f"recording {scene_kind} {what} (ROS_DOMAIN_ID={scene.env['ROS_DOMAIN_ID']}) -> {out}", flush=True)
            end = None if duration_s is None else time.monotonic() + duration_s
            try:
                for source in sources:
                    source.popen.wait(timeout=None if end is None else max(end - time.monotonic(), 0.0))
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
    ap.add_argument(
        "--second-path", help="the second hand's trajectory, when --params names two hands (second_hand_ns; default --path)"
    )
    ap.add_argument(
        "--second-offset-m",
        type=_vec2,
        default=(0.0, 0.0),
        help="'x y': the second hand's trajectory shifted in the sheet plane (m), as the mock tool's offset_x_m, offset_y_m",
    )
    ap.add_argument("--rate-hz", type=float, help="mock tools' publish rate (Hz; default theirs, 1000)")
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
            args.second_path,
            args.second_offset_m,
            args.rate_hz,
        )
    except (FileExistsError, HandsSceneError) as exc:
        print(f"skin-sim record: error: {exc}", file=sys.stderr)
        return 2
    print(f"{args.out}: " + ", ".join(f"{k} {v}" for k, v in counts.items()))
    poses = [v for k, v in counts.items() if k == "tool_pose" or k.endswith("/" + TOPICS["tool_pose"].name)]
    return 0 if poses and all(poses) else 1


def _vec2(text: str) -> tuple[float, float]:
    """``'x y'`` (m) as two floats."""
    try:
        x, y = (float(v) for v in text.replace(",", " ").split())
    except ValueError:
        raise argparse.ArgumentTypeError(f"{text!r}: give two numbers 'x y' (m)") from None
    return x, y


if __name__ == "__main__":
    raise SystemExit(main())
