"""Micro-benchmark of ``SkinModel.step``: force path alone and with the full grid.

Runs the same scripted press-hold-release-relax path at 1 kHz through both tissue forms in one
process: the ``layered`` default (all level-of-detail levers as configured, the "1 kHz setting")
beside the ``paper`` form, then fixed mode counts (``lod.adaptive_modes`` and the other levers off,
so "1x1" is one mode per axis) through the numba model and the pure-NumPy paper-form model
(:class:`~skin_sim_lab.oracles.reference.NumpySkinModel`). Prints median, p99 and max per tick, a
row as soon as it is measured, with ratios. Usage: ``skin-sim bench-model [--ticks N]``.

Also the needle's force step (issue 22: ``NeedleModel.step`` and ``law`` per tick, 21 G, vertical and at 30 degrees,
through every layer and back) beside the flat punch's force path in the same run, with the ratio, and the needle's
pure-NumPy reference.

``skin-sim bench-model --physics`` prints the issue-11 physics figures (:mod:`skin_sim_lab.perf.bench_physics`).
``skin-sim bench-model --against /work/main`` times the force path of each form on the same
tissue in another checkout (its own ``.venv``) and in this one, alternating in one run, and prints
the ratios: the before/after of a kernel change.

``skin-sim bench-model --lod`` instead measures each level-of-detail lever (issue 7): the four
scene trajectories (idle hover, light touch, deep press, drag) at 1 kHz with jittered tick
intervals, every lever off, each lever alone on, and all on; thread CPU time per tick of the force path and the
grid work amortised over the ticks (the display builds at 60 Hz), with ratios against the
all-off run of the same scene in the same run.
"""

from __future__ import annotations

import argparse
import math
import time

import numpy as np

from skin_sim_node.model import SkinModel, preset

from ..oracles.reference import NumpySkinModel


def scripted_path(n_ticks: int, dt: float = 1e-3):
    """Press to 3 mm over the first third, hold while dragging, release, then relax."""
    out = []
    third = n_ticks // 3
    for i in range(n_ticks):
        if i < third:
            d, vz, x, vx = 3e-3 * i / third, -3e-3 / (third * dt), 0.0, 0.0
        elif i < 2 * third:
            d, vz, x, vx = 3e-3, 0.0, 0.005 * math.sin((i - third) * dt * 6), 0.03 * math.cos((i - third) * dt * 6)
        else:
            d, vz, x, vx = -0.01, 0.0, 0.0, 0.0
        out.append(((x, 0.001, -d), (vx, 0.0, vz)))
    return out, dt


def time_path(model, path, dt, with_grid: bool) -> np.ndarray:
    """Wall time of each ``model.step`` along ``path`` (``(pos, vel)`` per tick), plus ``build_grid`` if ``with_grid`` (us)."""
    times = np.empty(len(path))
    clock = time.perf_counter_ns
    for i, (pos, vel) in enumerate(path):
        t0 = clock()
        model.step(pos, vel, dt)
        if with_grid:
            model.build_grid()
        times[i] = clock() - t0
    return times * 1e-3  # microseconds


def summarize(us: np.ndarray) -> tuple[float, float, float]:
    """Median, 99th percentile and maximum of ``us``."""
    return float(np.median(us)), float(np.percentile(us, 99)), float(us.max())


def needle_path(n_ticks: int, angle_deg: float, depth_m: float = 6.5e-3):
    """A needle's tip positions at 1 kHz: from 0.2 mm above the surface in along the axis ``angle_deg`` below it, to
    ``depth_m`` below the surface (through every layer: the default stack ruptures by 5.3 mm), and back out.

    Returns the tip positions (m) and the unit axis."""
    th = math.radians(angle_deg)
    u = np.array([math.cos(th), 0.0, -math.sin(th)])
    deep = depth_m / math.sin(th)
    half = n_ticks // 2
    s = np.concatenate([np.linspace(-0.2e-3, deep, half), np.linspace(deep, -0.2e-3, n_ticks - half)])
    return [tuple(float(c) for c in si * u) for si in s], tuple(float(c) for c in u)


def time_needle(model, path, axis) -> np.ndarray:
    """Wall time of the needle's force step per tick (us): ``model.step`` and ``model.law`` (what the session sends)."""
    times = np.empty(len(path))
    clock = time.perf_counter_ns
    for i, p in enumerate(path):
        t0 = clock()
        tick = model.step(p, axis)
        model.law(tick, p)
        times[i] = clock() - t0
    return times * 1e-3


def time_model_tangent(model, path, dt: float) -> np.ndarray:
    """Wall time per tick (us) over ``path`` (position, velocity pairs) of a :class:`SkinModel`'s ``step``, and
    ``tangent`` in contact."""
    times = np.empty(len(path))
    clock = time.perf_counter_ns
    for i, (p, v) in enumerate(path):
        t0 = clock()
        model.step(p, v, dt)
        if model.in_contact:
            model.tangent()
        times[i] = clock() - t0
    return times * 1e-3


def time_tool(tool, path, dt: float, axis) -> np.ndarray:
    """Wall time per tick (us) over ``path`` (position, velocity pairs) of what the session asks of a tool
    (:meth:`skin_sim_node.tools.Tool.step`, its tangent in contact included): for the needle, the needle, its law and
    the layered kernel's display drive of the dimple."""
    from skin_sim_node.tools import ToolPose

    times = np.empty(len(path))
    clock = time.perf_counter_ns
    for i, (p, v) in enumerate(path):
        t0 = clock()
        tool.step(ToolPose(p, v, axis, dt, False))
        times[i] = clock() - t0
    return times * 1e-3


def needle_rows(ticks: int, numpy_ticks: int, repeats: int = 3):
    """The needle's force step (21 G, vertical and 30 degrees, in through every layer and out) beside the flat punch's
    force path (the default preset's ``SkinModel.step`` on :func:`scripted_path`), interleaved ``repeats`` times, the
    best kept; then the needle's pure-NumPy reference on a path of ``numpy_ticks`` ticks, with the ratio of its median to
    the kernels' on that path. Yields one row each, the flat punch first."""
    from skin_sim_node.model.needle import NeedleModel, NeedleParams
    from skin_sim_node.tools import make_tool

    from ..oracles.needle_reference import NumpyNeedleModel

    cfg = preset("default")
    params = NeedleParams.gauge(21)
    flat_path, dt = scripted_path(ticks)
    cases = {f"needle {a:.0f} deg": needle_path(ticks, a) for a in (90.0, 30.0)}
    best: dict[str, np.ndarray] = {}

    def keep(name: str, t: np.ndarray) -> None:
        if name not in best or np.median(t) < np.median(best[name]):
            best[name] = t

    needle_cfg = cfg.replace(**{"tool.shape": "needle", "needle.outer_diameter_m": params.outer_diameter_m})
    for _ in range(repeats):
        m = SkinModel(cfg)
        time_path(m, flat_path[:200], dt, False)
        m.reset()
        keep("flat punch", time_path(m, flat_path, dt, False))
        m.reset()
        keep("flat punch, step + tangent", time_model_tangent(m, flat_path, dt))
        tips, axis = cases["needle 90 deg"]
        path = [(p, (0.0, 0.0, 0.0)) for p in tips]
        ns = make_tool(needle_cfg)
        time_tool(ns, path[: len(path) // 2 : 10], dt, axis)
        ns.reset()
        keep("needle 90 deg, tool step + tangent", time_tool(ns, path, dt, axis))
        for name, (path, axis) in cases.items():
            needle = NeedleModel(cfg, params)
            time_needle(needle, path[: len(path) // 2 : 10], axis)  # compile / load the kernels, then start over
            needle.reset()
            keep(name, time_needle(needle, path, axis))
    speedup = {}
    for a in (90.0, 30.0):  # the reference on a shorter path (its track start alone takes tens of ms), numba on it too
        path, axis = needle_path(numpy_ticks, a)
        slow = time_needle(NumpyNeedleModel(cfg, params), path, axis)
        needle = NeedleModel(cfg, params)
        fast = time_needle(needle, path, axis)
        best[f"needle {a:.0f} deg, NumPy reference"] = slow
        speedup[f"needle {a:.0f} deg, NumPy reference"] = float(np.median(slow) / np.median(fast))
    for name, t in best.items():
        med, p99, mx = summarize(t)
        row = {"case": name, "ticks": t.size, "median_us": med, "p99_us": p99, "max_us": mx}
        yield {**row, "numpy_over_numba": speedup.get(name)}


TWO_TOOL_DISTANCE_M = 4e-3
"""The second tool's centre distance from the first in the two-tool rows (m): close enough that each reads a field the
other has deformed (issue 32's nearest two-punch distance), so the coupling's point evaluation does its whole work."""


def two_tool_rows(ticks: int, repeats: int = 3) -> list[dict]:
    """One tool's step per tick against two tools on one tissue (:class:`skin_sim_node.tools.SharedSkin`), both stepping
    each tick (issue 32): two flat punches, and the needle beside a fingertip pad. Interleaved, best of ``repeats``;
    each two-tool row's ratio is its median over its one-tool row's median.

    Parameters
    ----------
    ticks : int
    repeats : int

    Returns
    -------
    list of dict
        ``case``, ``median_us``, ``p99_us``, ``ratio`` (None for a one-tool row).
    """
    from dataclasses import replace

    from skin_sim_node.tools import DOWN, ToolPose, make_tool, make_tools

    cfg = preset("default")
    needle_cfg = preset("needle")
    finger_cfg = replace(cfg, tool_radius_m=5e-3)
    punch_path, _ = scripted_path(ticks)
    tips, axis = needle_path(ticks, 90.0)
    needle_tips = [(tip, (0.0, 0.0, 0.0)) for tip in tips]

    def one(cfg_a, path_a, axis_a):
        tool = make_tool(cfg_a)
        times = np.empty(len(path_a))
        clock = time.perf_counter_ns
        for i, (p, v) in enumerate(path_a):
            t0 = clock()
            tool.step(ToolPose(p, v, axis_a, 1e-3, i == 0))
            times[i] = clock() - t0
        return times * 1e-3

    def two(cfg_a, path_a, axis_a, cfg_b):
        a, b = make_tools([cfg_a, cfg_b])
        times = np.empty(len(path_a))
        clock = time.perf_counter_ns
        for i, (p, v) in enumerate(path_a):
            q = (p[0] + TWO_TOOL_DISTANCE_M, p[1], min(p[2], 0.0) * 0.5)  # the other presses half as deep beside it
            t0 = clock()
            a.step(ToolPose(p, v, axis_a, 1e-3, i == 0))
            b.step(ToolPose(q, v, DOWN, 1e-3, i == 0))
            times[i] = clock() - t0
        return times * 1e-3

    cases = {
        "flat punch alone": lambda: one(cfg, punch_path, DOWN),
        f"two flat punches {TWO_TOOL_DISTANCE_M * 1e3:g} mm apart": lambda: two(cfg, punch_path, DOWN, cfg),
        "needle alone": lambda: one(needle_cfg, needle_tips, axis),
        f"needle + finger {TWO_TOOL_DISTANCE_M * 1e3:g} mm apart": lambda: two(needle_cfg, needle_tips, axis, finger_cfg),
    }
    for f in cases.values():  # compile / load every kernel first
        f()
    best: dict[str, np.ndarray] = {}
    for _ in range(repeats):
        for name, f in cases.items():
            t = f()
            if name not in best or np.median(t) < np.median(best[name]):
                best[name] = t
    rows, base = [], None
    for name, t in best.items():
        med, p99, _ = summarize(t)
        if "alone" in name:
            base = med
        rows.append({"case": name, "median_us": med, "p99_us": p99, "ratio": None if "alone" in name else med / base})
    return rows


FIXED_MODES = {"lod.adaptive_modes": False, "lod.affected_layers": False, "lod.patch_only": False, "lod.idle": False}
"""Fixed-mode rows: every level-of-detail lever off, so the row's mode count is what runs."""


def form_rows(ticks: int, repeats: int = 3):
    """Force path of the ``default`` preset in each form, same path, interleaved ``repeats`` times (best kept).

    Yields one row per form: the layered form first, then the paper form on the same tissue.
    """
    base = preset("default")
    cfgs = {"layered": base, "paper": base.replace(form="paper")}
    path, dt = scripted_path(ticks)
    best: dict[str, np.ndarray] = {}
    for _ in range(repeats):
        for form, cfg in cfgs.items():
            m = SkinModel(cfg)
            time_path(m, path[:200], dt, False)  # compile / warm caches
            m.reset()
            t = time_path(m, path, dt, False)
            if form not in best or np.median(t) < np.median(best[form]):
                best[form] = t
    for form in cfgs:
        med, p99, mx = summarize(best[form])
        yield {"form": form, "median_us": med, "p99_us": p99, "max_us": mx}


def run(ticks: int, numpy_ticks: int, modes_list=(1, 3, 20)):
    """Fixed mode counts (levers off), numba against NumPy (paper form); yields each row as it is measured."""
    base = preset("default").replace(form="paper", **FIXED_MODES)
    for modes in modes_list:
        cfg = base.replace(**{"modes.m": modes, "modes.n": modes})
        for with_grid in (False, True):
            fast = SkinModel(cfg)
            path, dt = scripted_path(ticks)
            time_path(fast, path[:50], dt, with_grid)  # JIT compile + warm caches
            fast.reset()
            t_fast = time_path(fast, path, dt, with_grid)
            slow_path, _ = scripted_path(numpy_ticks)
            t_slow = time_path(NumpySkinModel(cfg), slow_path, dt, with_grid)
            f_med, f_p99, f_max = summarize(t_fast)
            s_med, s_p99, _ = summarize(t_slow)
            yield {
                "modes": f"{modes}x{modes}",
                "active": fast.basis.n_modes,
                "path": "force+grid" if with_grid else "force",
                "numba_median_us": f_med,
                "numba_p99_us": f_p99,
                "numba_max_us": f_max,
                "numpy_median_us": s_med,
                "numpy_p99_us": s_p99,
                "speedup_median": s_med / f_med,
            }


AGAINST_SNIPPET = """
import json, sys
import numpy as np
from skin_sim_node.model import SkinModel, preset
try:
    from skin_sim_lab.perf.bench_model import scripted_path, time_path
except ImportError:  # a checkout from before the lab left the runtime package (issue 28)
    from skin_sim_node.perf.bench_model import scripted_path, time_path
cfg = preset("default")
flat = cfg.as_flat()
forms = {"paper": cfg}
if "form" in flat:  # this checkout has the layered form: the paper form with the tissue the other one had
    r = cfg.tool_radius_m
    moduli = {"epidermis": 1.5e6, "dermis": 20e3, "fat": 2.5e3}
    k = {f"layers.{n}.stiffness_n_per_m": 2 * e * r / (1 - 0.48**2) for n, e in moduli.items()}
    forms = {"paper": cfg.replace(form="paper", **k), "layered": cfg.replace(form="layered")}
ticks = int(sys.argv[1])
path, dt = scripted_path(ticks)
res = {}
for form, c in forms.items():
    m = SkinModel(c)
    time_path(m, path[:200], dt, False)
    m.reset()
    t = time_path(m, path, dt, False)
    res[form] = {"median": float(np.median(t)), "p99": float(np.percentile(t, 99))}
print(json.dumps(res))
"""


def run_against(other: str, ticks: int, rounds: int = 5) -> None:
    """Force path of each form in ``other`` (a checkout with its own .venv) and here, alternating; prints each round.

    The paper form runs on the tissue both checkouts share (checkouts before the layered form have only it);
    the layered form (the default) where both have it.
    """
    import json
    import subprocess
    import sys
    from pathlib import Path

    here = Path(__file__).resolve().parents[2]
    exe = {"other": str(Path(other) / ".venv" / "bin" / "python"), "this": sys.executable}
    cwd = {"other": str(other), "this": str(here)}
    print(f"force path (SkinModel.step), default tissue, {ticks} ticks at 1 kHz; 'other' = {other}, 'this' = {here}", flush=True)
    print(f"{'round':>5} {'form':>8} | {'other med':>9} {'p99':>7} | {'this med':>8} {'p99':>7} | this/other median", flush=True)
    ratios: dict[str, list[float]] = {}
    for i in range(rounds):
        res = {}
        for who in ("other", "this"):
            out = subprocess.run([exe[who], "-c", AGAINST_SNIPPET, str(ticks)], cwd=cwd[who], capture_output=True, text=True)
            if out.returncode != 0:
                print(f"{who}: failed: {out.stderr.strip().splitlines()[-1] if out.stderr.strip() else out.returncode}")
                return
            res[who] = json.loads(out.stdout.strip().splitlines()[-1])
        for form in [f for f in res["this"] if f in res["other"]]:
            o, t = res["other"][form], res["this"][form]
            ratios.setdefault(form, []).append(t["median"] / o["median"])
            print(
                f"{i:>5} {form:>8} | {o['median']:9.2f} {o['p99']:7.2f} | {t['median']:8.2f} {t['p99']:7.2f} | "
                f"{ratios[form][-1]:.3f}",
                flush=True,
            )
    for form, r in ratios.items():
        print(
            f"{form}: median of the per-round ratios this/other {float(np.median(r)):.3f} (machine shared: ratios, not absolutes)"
        )


LOD_OFF = {"lod.adaptive_modes": False, "lod.affected_layers": False, "lod.patch_only": False, "lod.idle": False}
DISPLAY_HZ = 60.0  # the node's display_rate_hz default
LOD_CASES = {
    # case: (tissue parameter changes over LOD_OFF, grid: "tick" every tick, "frame" every display frame,
    #        "change" every display frame when the state moved by more than the tolerance)
    "all off, grid every tick": ({}, "tick"),
    "all off": ({}, "frame"),
    "all off, 59x59 modes": ({"modes.m": 59, "modes.n": 59}, "frame"),
    "+ adaptive modes": ({"lod.adaptive_modes": True}, "frame"),
    "+ affected layers": ({"lod.affected_layers": True}, "frame"),
    "+ patch only": ({"lod.patch_only": True}, "frame"),
    "+ idle": ({"lod.idle": True}, "frame"),
    "+ grid on change": ({}, "change"),
    "all on": ({"lod.adaptive_modes": True, "lod.affected_layers": True, "lod.patch_only": True, "lod.idle": True}, "change"),
}
LOD_SCENES = {"idle": None, "light": "light_touch", "deep": "press_all_layers", "drag": "drag"}


def scene_path(trajectory: str | None, rate_hz: float = 1000.0, jitter_s: float = 20e-6, seed: int = 7, idle_s: float = 3.0):
    """Tool samples ``(pos, vel, dt)`` of a mock-tool trajectory at ``rate_hz`` with Gaussian tick jitter.

    Jitter: the node's tick interval is a pose-stamp difference and differs every tick, so the
    propagator is recomputed every tick; 20 us is a stated choice, well inside the measured DDS jitter.
    ``trajectory`` None: the tool hovers 5 mm above the tissue for ``idle_s``.
    """
    from skin_sim_node.device.trajectories import LIFT_Z_M, TRAJECTORIES

    rng = np.random.default_rng(seed)
    duration = TRAJECTORIES[trajectory].duration_s if trajectory else idle_s
    n = int(duration * rate_hz)
    dts = np.clip(1.0 / rate_hz + rng.normal(0.0, jitter_s, n), 1e-5, None)
    t = np.cumsum(dts)
    out = []
    for ti, dt in zip(t, dts):
        pos, vel = TRAJECTORIES[trajectory].sample(ti) if trajectory else ((0.0, 0.0, LIFT_Z_M), (0.0, 0.0, 0.0))
        out.append((pos, vel, float(dt)))
    return out


def time_lod_case(cfg, path, grid_mode: str) -> dict:
    """Force-path and grid thread CPU time per tick (us) over ``path`` for one configuration."""
    from skin_sim_node.server.display import _moved

    model = SkinModel(cfg)
    for pos, vel, dt in path[:200]:  # compile / warm caches, then start from rest
        model.step(pos, vel, dt)
        model.build_grid()
    model.reset()
    model.build_grid()
    calls0 = model.kernel_calls
    force = np.empty(len(path))
    grid = np.zeros(len(path))
    clock = time.thread_time_ns  # CPU time of this thread: other processes on the shared cores do not count
    frame_s = 1.0 / DISPLAY_HZ
    next_frame = 0.0
    t = 0.0
    last = (None, None, None)
    builds = 0
    for i, (pos, vel, dt) in enumerate(path):
        t0 = clock()
        model.step(pos, vel, dt)
        t1 = clock()
        force[i] = t1 - t0
        t += dt
        if grid_mode == "tick" or t >= next_frame:
            next_frame += frame_s if grid_mode != "tick" else 0.0
            t2 = clock()
            if grid_mode != "change" or _moved(model, *last):
                model.build_grid()
                builds += 1
                if grid_mode == "change":
                    last = (model.q.copy(), model.centre.copy(), model.active.copy())
            grid[i] = clock() - t2
    force *= 1e-3
    grid *= 1e-3
    return {
        "force_med": float(np.median(force)),
        "force_p99": float(np.percentile(force, 99)),
        "force_mean": float(force.mean()),
        "grid_per_tick": float(grid.mean()),
        "total_per_tick": float(force.mean() + grid.mean()),
        "builds": builds,
        "kernel_calls": model.kernel_calls - calls0,
        "ticks": len(path),
    }


def run_lod(scenes=tuple(LOD_SCENES), cases=tuple(LOD_CASES), repeats: int = 3) -> list[dict]:
    """Every case of every scene, ``repeats`` times interleaved; per case the least disturbed repeat.

    Other processes share the cores: a repeat that was descheduled has a larger mean, so the
    repeat with the smallest mean total per tick is kept (its median and p99 are reported with it).
    """
    from tqdm import tqdm

    base = preset("default").replace(**LOD_OFF)
    rows = []
    with tqdm(total=len(scenes) * repeats * len(cases), desc="lod cases", leave=False) as bar:
        for scene in scenes:
            path = scene_path(LOD_SCENES[scene])
            best: dict[str, dict] = {}
            for _ in range(repeats):
                for case in cases:
                    changes, grid_mode = LOD_CASES[case]
                    r = time_lod_case(base.replace(**changes), path, grid_mode)
                    if case not in best or r["total_per_tick"] < best[case]["total_per_tick"]:
                        best[case] = r
                    bar.update()
            rows += [{"scene": scene, "case": case, **best[case]} for case in cases]
    return rows


def print_lod(rows: list[dict]) -> None:
    """Print the level-of-detail table of :func:`run_lod`: force and grid cost per tick, and the ratio to all levers off."""
    print("skin-sim level-of-detail levers: thread CPU time per 1 kHz tick, microseconds (model only, no ROS), one run")
    print("force: SkinModel.step; grid: build_grid time averaged over all ticks (60 Hz display frames);")
    print("ratio = mean total per tick / the same scene's 'all off' (fixed 15x15 modes, grid every display frame);")
    print("each case run 3 times interleaved, the least disturbed (smallest mean) kept")
    hdr = (
        f"{'scene':>6} {'case':>25} | {'force med':>9} {'p99':>7} {'mean':>7} | {'grid/tick':>9} {'builds':>6} | "
        f"{'total':>7} {'ratio':>6} | {'kernel calls':>12}"
    )
    print(hdr)
    print("-" * len(hdr))
    base = {r["scene"]: r for r in rows if r["case"] == "all off"}
    for r in rows:
        ratio = r["total_per_tick"] / base[r["scene"]]["total_per_tick"] if r["scene"] in base else float("nan")
        print(
            f"{r['scene']:>6} {r['case']:>25} | {r['force_med']:9.2f} {r['force_p99']:7.2f} {r['force_mean']:7.2f} | "
            f"{r['grid_per_tick']:9.2f} {r['builds']:6d} | {r['total_per_tick']:7.2f} {ratio:6.3f} | "
            f"{r['kernel_calls']:>5}/{r['ticks']:<6}"
        )


def main(argv=None) -> int:
    """``skin-sim bench-model``: the model-step benchmark (default), ``--lod``, ``--physics`` or ``--against CHECKOUT``."""
    ap = argparse.ArgumentParser(prog="skin-sim bench-model", description=__doc__.splitlines()[0])
    ap.add_argument("--ticks", type=int, default=6000, help="numba ticks per case (default 6000)")
    ap.add_argument("--numpy-ticks", type=int, default=600, help="NumPy baseline ticks per case (default 600)")
    ap.add_argument("--lod", action="store_true", help="measure the level-of-detail levers instead (issue 7)")
    ap.add_argument("--physics", action="store_true", help="print the physics figures of the tissue forms (issue 11)")
    ap.add_argument("--against", metavar="CHECKOUT", help="force path here vs another checkout (its .venv), each form")
    args = ap.parse_args(argv)
    if args.physics:
        from .bench_physics import main as physics_main

        return physics_main()
    if args.against:
        run_against(args.against, args.ticks)
        return 0
    if args.lod:
        print("skin-sim level-of-detail levers: measuring 4 scenes x 9 cases x 3 repeats (progress below)...", flush=True)
        print_lod(run_lod())
        return 0
    cfg = preset("default")
    ny, nx = cfg.grid_shape
    print(
        f"skin-sim model micro-benchmark: sheet grid {ny}x{nx}, patch {cfg.patch_size_m[0] * 1e3:.0f} mm, 3 layers; "
        f"{args.ticks} ticks per row at 1 kHz (machine shared: compare ratios within this run)",
        flush=True,
    )
    print("1. force path per tick, default preset in each form (level-of-detail levers as configured), best of 3 interleaved:")
    rows = {}
    for r in form_rows(args.ticks):
        rows[r["form"]] = r
        print(
            f"  {r['form']:>8}: median {r['median_us']:7.2f} us, p99 {r['p99_us']:7.2f} us, max {r['max_us']:8.1f} us", flush=True
        )
    print(f"  layered/paper median ratio {rows['layered']['median_us'] / rows['paper']['median_us']:.2f}", flush=True)
    print(
        "2. the needle's force step per tick (step + law, 21 G, in through every layer and out at 1 kHz) beside the flat "
        "punch's force path (default preset), best of 3 interleaved; ratio = median / the flat punch's median:",
        flush=True,
    )
    flat = None
    for r in needle_rows(args.ticks, args.numpy_ticks):
        flat = flat or r["median_us"]
        print(
            f"  {r['case']:>30}: median {r['median_us']:8.2f} us, p99 {r['p99_us']:8.2f} us, max {r['max_us']:9.1f} us, "
            f"ratio {r['median_us'] / flat:6.2f} ({r['ticks']} ticks)"
            + (f"; NumPy / numba median on this path {r['numpy_over_numba']:.0f}x" if r["numpy_over_numba"] else ""),
            flush=True,
        )
    print(
        "3. two tools on one tissue (issue 32), both stepping each tick, against one tool, best of 3 interleaved; "
        "ratio = median / the same tool's alone:",
        flush=True,
    )
    for r in two_tool_rows(args.ticks):
        ratio = f", ratio {r['ratio']:5.2f}" if r["ratio"] is not None else ""
        print(f"  {r['case']:>30}: median {r['median_us']:8.2f} us, p99 {r['p99_us']:8.2f} us{ratio}", flush=True)
    print("4. fixed mode counts (every level-of-detail lever off), paper form; ratio = NumPy median / numba median:")
    hdr = f"{'modes':>6} {'active':>6} {'path':>10} | {'median':>8} {'p99':>8} {'max':>8} | "
    hdr += f"{'numpy med':>10} {'numpy p99':>10} | ratio"
    print(hdr)
    print("-" * len(hdr), flush=True)
    for r in run(args.ticks, args.numpy_ticks):
        print(
            f"{r['modes']:>6} {r['active']:>6} {r['path']:>10} | {r['numba_median_us']:8.1f} {r['numba_p99_us']:8.1f} "
            f"{r['numba_max_us']:8.1f} | {r['numpy_median_us']:10.1f} {r['numpy_p99_us']:10.1f} | {r['speedup_median']:6.1f}x",
            flush=True,
        )
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
