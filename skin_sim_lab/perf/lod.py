"""Scene CPU benchmark: the node's CPU use in four scenes with every LOD lever off and on.

Each case is a real scene (``skin_sim_node`` and ``skin-sim mock-tool`` as separate processes on
an isolated DDS domain). After a warm-up, the CPU time (user + system, psutil) of the node process
and its children (the display worker) is taken over the same wall window for every case. The
cases run interleaved (scene by scene, off then on), so the ratios come from one run under the
same machine load; ``--repeats`` passes over all cases, medians reported. Usage:
``skin-sim perf-lod [--duration-s 10] [--repeats 3] [--scenes idle,light,deep,drag]``.

Scenes (mock-tool trajectories, looped at 1 kHz):

- ``idle``: the tool hovers 5 mm above the tissue (a device connected, nobody touching);
- ``light``: ``light_touch``, 20 um deep (epidermis only);
- ``deep``: ``press_all_layers``, 4 mm deep (all three layers);
- ``drag``: ``drag``, 1.5 mm deep, 40 mm along x.
"""

from __future__ import annotations

import argparse
import os
import tempfile
import time
from pathlib import Path

import numpy as np

from skin_sim_node.scenes import Scene, pick_domain_id

from .bench_node import CASE_OVERHEAD_S, Progress

SCENE_TOOLS = {
    # scene: mock-tool arguments
    "idle": ("--trajectory", "press_hold_release", "--loop", "--start-delay-s", "1e9"),  # holds the lifted start pose
    "light": ("--trajectory", "light_touch", "--loop"),
    "deep": ("--trajectory", "press_all_layers", "--loop"),
    "drag": ("--trajectory", "drag", "--loop"),
}

LEVERS_OFF = (
    "tissue.lod.adaptive_modes:=false",  # the fixed modes.m x modes.n
    "tissue.lod.affected_layers:=false",
    "tissue.lod.patch_only:=false",
    "tissue.lod.idle:=false",
    "idle_heartbeat_hz:=0.0",
    "display_on_change:=false",
)
"""Node parameters that switch every lever off."""

LEVERS_ON = ("idle_heartbeat_hz:=100.0",)
"""Node parameters that switch every lever on: the defaults, plus the idle heartbeat (off by
default, as it answers idle poses at 100 Hz instead of every one)."""


def process_tree_cpu_s(pid: int) -> dict[int, float]:
    """CPU seconds (user + system) of a process and each of its live descendants, by pid."""
    import psutil

    out = {}
    try:
        root = psutil.Process(pid)
        procs = [root, *root.children(recursive=True)]
    except psutil.NoSuchProcess:
        return out
    for p in procs:
        try:
            t = p.cpu_times()
            out[p.pid] = t.user + t.system
        except psutil.NoSuchProcess:
            pass
    return out


def run_case(scene_name: str, levers_on: bool, duration_s: float, warmup_s: float, log_dir: Path, modes: int) -> dict:
    """One scene, one lever setting: returns CPU seconds of the node tree over ``duration_s`` of wall time."""
    params = list(LEVERS_ON if levers_on else LEVERS_OFF)
    params += [f"tissue.modes.m:={modes}", f"tissue.modes.n:={modes}"]
    tag = f"{scene_name}-{'on' if levers_on else 'off'}"
    with Scene(log_dir / tag, domain_id=pick_domain_id()) as scene:
        node = scene.node(*[a for p in params for a in ("-p", p)])
        scene.wait_for_log(node, "live:", timeout_s=180)
        scene.start("mock_tool", "mock-tool", *SCENE_TOOLS[scene_name])
        time.sleep(warmup_s)
        c0 = process_tree_cpu_s(node.popen.pid)
        w0 = time.perf_counter()
        time.sleep(duration_s)
        c1 = process_tree_cpu_s(node.popen.pid)
        wall = time.perf_counter() - w0
        log = node.log()
    cpu = sum(c1.get(pid, 0.0) - c0.get(pid, 0.0) for pid in c1)
    main_cpu = c1.get(node.popen.pid, 0.0) - c0.get(node.popen.pid, 0.0)
    return {
        "scene": scene_name,
        "levers": "on" if levers_on else "off",
        "cpu_s": cpu,
        "wall_s": wall,
        "cpu_pct": 100.0 * cpu / wall,
        "node_pct": 100.0 * main_cpu / wall,
        "children_pct": 100.0 * (cpu - main_cpu) / wall,
        "live": next((ln for ln in log.splitlines() if "live:" in ln), ""),
    }


def case_estimate_s(duration_s: float, warmup_s: float) -> float:
    """Expected wall time of one case (s): the run, its warm-up and the start-up overhead."""
    return duration_s + warmup_s + CASE_OVERHEAD_S


def run(scenes, duration_s: float, warmup_s: float, log_dir: Path, modes: int, repeats: int = 1) -> list[dict]:
    """Every scene off then on, the whole list ``repeats`` times; per case the median CPU over the repeats."""
    runs: dict[tuple[str, bool], list[dict]] = {}
    est = case_estimate_s(duration_s, warmup_s)
    progress = Progress([est] * (repeats * len(scenes) * 2), "skin-sim perf-lod")
    try:
        _passes(scenes, duration_s, warmup_s, log_dir, modes, repeats, runs, progress, est)
    finally:
        progress.close()
    rows = []
    for (name, _on), rs in runs.items():
        keys = ("cpu_s", "wall_s", "cpu_pct", "node_pct", "children_pct")
        med = {k: float(np.median([r[k] for r in rs])) for k in keys}
        pair = [r_on["cpu_s"] / r_off["cpu_s"] for r_off, r_on in zip(runs[(name, False)], runs[(name, True)])]
        rows.append({**rs[0], **med, "pair_ratio": float(np.median(pair)), "repeats": len(rs)})
    return rows


def _passes(scenes, duration_s, warmup_s, log_dir, modes, repeats, runs, progress: Progress, est: float) -> None:
    for rep in range(repeats):
        for name in scenes:
            for on in (False, True):
                progress.stage(f"pass {rep + 1}/{repeats}: {name}, levers {'on' if on else 'off'}", est)
                r = run_case(name, on, duration_s, warmup_s, log_dir / f"rep{rep}", modes)
                runs.setdefault((name, on), []).append(r)
                print(f"  pass {rep + 1}/{repeats} {name:>5} levers {r['levers']:>3}: {r['cpu_pct']:5.1f} % CPU", flush=True)


def report(rows: list[dict]) -> str:
    """The CPU table of the scenes, levers off against on, as text."""
    by = {(r["scene"], r["levers"]): r for r in rows}
    base = by.get(("idle", "off")) or rows[0]
    lines = [
        "CPU of the node process tree (node + display worker), % of one core over the same wall window",
        f"{'scene':>6} | {'off: total':>10} {'node':>6} {'display':>7} | {'on: total':>9} {'node':>6} {'display':>7} | "
        f"{'on/off':>6} | {'off/idle-off':>12} {'on/idle-off':>11}",
    ]
    lines[0] += f"; median of {rows[0].get('repeats', 1)} interleaved passes; on/off = median of the per-pass ratios"
    lines.append("-" * len(lines[1]))
    for name in dict.fromkeys(r["scene"] for r in rows):
        off, on = by[(name, "off")], by[(name, "on")]
        lines.append(
            f"{name:>6} | {off['cpu_pct']:10.1f} {off['node_pct']:6.1f} {off['children_pct']:7.1f} | "
            f"{on['cpu_pct']:9.1f} {on['node_pct']:6.1f} {on['children_pct']:7.1f} | {on['pair_ratio']:6.2f} | "
            f"{off['cpu_s'] / base['cpu_s']:12.2f} {on['cpu_s'] / base['cpu_s']:11.2f}"
        )
    return "\n".join(lines)


def main(argv=None) -> int:
    """``skin-sim perf-lod``: node CPU in four scenes with the level-of-detail levers off and on."""
    ap = argparse.ArgumentParser(
        prog="skin-sim perf-lod",
        description=__doc__.splitlines()[0],
        epilog=f"Duration: scenes x 2 x repeats cases of (duration + warm-up + ~{CASE_OVERHEAD_S:.0f} s start-up): "
        "about 9 min estimated with the defaults (24 cases of ~22 s; 6.4 min measured on 2 cores, quiet, 2026-12-02); "
        "--repeats 1 --duration-s 5 takes ~2.5 min. "
        "The estimate is printed at start, then one line per case.",
    )
    ap.add_argument("--duration-s", type=float, default=10.0, help="measured wall time per case (default 10)")
    ap.add_argument("--warmup-s", type=float, default=4.0, help="time after the tool starts before measuring (default 4)")
    ap.add_argument("--scenes", default="idle,light,deep,drag", help="comma-separated: " + ", ".join(SCENE_TOOLS))
    ap.add_argument("--repeats", type=int, default=3, help="interleaved passes over all cases (default 3)")
    ap.add_argument("--modes", type=int, default=15, help="fixed modes per axis with the levers off (default 15, the preset)")
    ap.add_argument("--log-dir", type=Path, default=None)
    args = ap.parse_args(argv)
    scenes = [s for s in args.scenes.split(",") if s]
    unknown = set(scenes) - set(SCENE_TOOLS)
    if unknown:
        ap.error(f"unknown scene(s) {sorted(unknown)}")
    log_dir = args.log_dir or Path(tempfile.mkdtemp(prefix="skin_sim_lod_"))
    os.environ.setdefault("ROS_AUTOMATIC_DISCOVERY_RANGE", "LOCALHOST")
    n_cases = len(scenes) * 2 * args.repeats
    print(
        f"skin-sim perf-lod: {n_cases} cases, about {n_cases * case_estimate_s(args.duration_s, args.warmup_s) / 60:.1f} min; "
        f"{args.duration_s:.0f} s per case after {args.warmup_s:.0f} s warm-up, levers off "
        f"(fixed {args.modes}x{args.modes} modes) vs on, {os.cpu_count()} cores; logs {log_dir}",
        flush=True,
    )
    rows = run(scenes, args.duration_s, args.warmup_s, log_dir, args.modes, args.repeats)
    print(report(rows))
    cpu = np.array([r["cpu_pct"] for r in rows])
    print(f"(cases {len(rows)}, CPU % range {cpu.min():.1f}-{cpu.max():.1f})")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
