"""Golden scenes: small input bags made from the mock tool's trajectories, and their replay outputs.

The mock tool's :data:`~skin_sim_node.device.trajectories.TRAJECTORIES` give the exact pose and velocity
at any time, so the input bags are written directly (no DDS, no timing noise): one
``tool/pose`` and one ``tool/twist`` per millisecond, stamps ``T0 + k ms``, bag time = stamp.
The expected-output bags are the offline replay of those inputs with the default parameters.
Both are MCAP with zstd chunk compression (``ros2 bag`` reads it natively) to stay small.

Regenerate (after a deliberate model change, then review the diff of the figures)::

    .venv/bin/python -m skin_sim_node.bags.golden --out tests/data
"""

from __future__ import annotations

import argparse
import shutil
from pathlib import Path

from msgs_schema import convert as cv
from msgs_schema.topics import FRAMES, TOPICS

from ..device.trajectories import TRAJECTORIES
from ..scenes import DEFAULT_PARAMS
from .inputs import InputOptions, read_inputs
from .io import BagWriter, new_message, qos_profiles
from .offline import bag_topic, replay_to_bag

T0_NS = 1_700_000_000 * 1_000_000_000
"""Stamp of the first sample: a fixed epoch, so the bags are reproducible byte for byte."""

SCENES = ("press_hold_release", "press_all_layers", "edge_press", "drag", "needle_oblique_30")
"""press/hold/release, all three layers, edge, drag, and a 21 G needle at 30 degrees through every layer."""
SCENE_PARAMS = {"needle_oblique_30": DEFAULT_PARAMS.parent / "needle.yaml"}
"""The parameter file of a scene that does not run the default (the needle's preset)."""

GRID_RATE_HZ = 2.0
"""Grid frames in the expected outputs: 2 per second keeps tests/data under 2 MB (a
120 x 120 x 3 float32 layer_heights frame is 173 kB before compression)."""

RATE_HZ = 1000.0


def write_trajectory_bag(
    path: Path,
    name: str,
    rate_hz: float = RATE_HZ,
    t0_ns: int = T0_NS,
    storage: str = "mcap",
    compress: bool = True,
    frame: str = FRAMES["tissue"],
    pose_topic: str | None = None,
    twist_topic: str | None = None,
    mapping=None,
) -> Path:
    """Write a mock tool trajectory as a bag of poses and twists (``mapping``: device frame).

    Parameters
    ----------
    mapping : DeviceMapping, optional
        Write device-frame poses ``mapping.to_device(p)`` (a driver's view of the same path).
    """
    traj = TRAJECTORIES[name]
    n = int(round(traj.duration_s * rate_hz)) + 1
    period_ns = int(round(1e9 / rate_hz))
    pose, twist = new_message(TOPICS["tool_pose"].type), new_message(TOPICS["tool_twist"].type)
    pt, tt = pose_topic or bag_topic("tool_pose"), twist_topic or bag_topic("tool_twist")
    custom = {"skin_sim.trajectory": name, "skin_sim.rate_hz": f"{rate_hz:g}"}
    with BagWriter(path, storage, compress=compress, custom_data=custom, overwrite=True) as w:
        for k in range(n):
            stamp = t0_ns + k * period_ns
            xyz, v = traj.sample(k * period_ns * 1e-9)
            q = traj.orientation
            if mapping is not None:
                xyz, v, q = mapping.to_device(xyz), mapping.velocity_to_device(v), mapping.orientation_to_device(q)
            w.write(pt, TOPICS["tool_pose"].type, stamp, cv.fill_pose(pose, stamp, frame, xyz, q), qos_profiles("tool_pose"))
            w.write(tt, TOPICS["tool_twist"].type, stamp, cv.fill_twist(twist, stamp, frame, v), qos_profiles("tool_twist"))
    return path


def make_golden(out_dir: Path, scenes=SCENES, params=DEFAULT_PARAMS) -> dict[str, dict]:
    """Write ``out_dir/<scene>/input`` and ``out_dir/<scene>/expected`` for each scene."""
    summaries = {}
    for name in scenes:
        d = Path(out_dir) / name
        if d.exists():
            shutil.rmtree(d)
        d.mkdir(parents=True)
        write_trajectory_bag(d / "input", name)
        res = replay_to_bag(
            read_inputs(d / "input", InputOptions()),
            d / "expected",
            SCENE_PARAMS.get(name, params),
            grid_rate_hz=GRID_RATE_HZ,
            compress=True,
        )
        summaries[name] = res.summary()
    return summaries


def main(argv=None) -> int:
    """Regenerate the golden bags in ``--out`` (default ``tests/data``) and print each scene's peak force and layers."""
    ap = argparse.ArgumentParser(prog="skin_sim_node.bags.golden", description=__doc__.splitlines()[0])
    ap.add_argument("--out", type=Path, default=Path("tests/data"), help="output folder (default tests/data)")
    ap.add_argument("--scene", action="append", choices=SCENES, help="only these scenes (repeatable)")
    args = ap.parse_args(argv)
    for name, s in make_golden(args.out, args.scene or SCENES).items():
        print(
            f"{name:20s} peak {s['peak_force_n']:.4f} N, layers {', '.join(s['layers_reached']) or '-'}, "
            f"{s['answered']} wrenches, {s['grid_frames']} grids"
        )
    total = sum(f.stat().st_size for f in args.out.rglob("*") if f.is_file())
    print(f"{args.out}: {total / 1e6:.2f} MB")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
