"""Micro-benchmark of ``SkinModel.step``: force path alone and with the full grid.

Runs the same scripted press-hold-release-relax path through the numba model and the
pure-NumPy model (:class:`~skin_sim_node.model.reference.NumpySkinModel`) at several mode
counts in one process, and prints median, p99 and max per tick with the NumPy/numba
ratio. Usage: ``skin-sim bench-model [--ticks N]``.
"""

from __future__ import annotations

import argparse
import math
import time

import numpy as np

from .model import SkinModel, preset
from .model.reference import NumpySkinModel


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
    return float(np.median(us)), float(np.percentile(us, 99)), float(us.max())


def run(ticks: int, numpy_ticks: int, modes_list=(1, 3, 20)) -> list[dict]:
    base = preset("default")
    rows = []
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
            rows.append(
                {
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
            )
    return rows


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(prog="skin-sim bench-model", description=__doc__.splitlines()[0])
    ap.add_argument("--ticks", type=int, default=6000, help="numba ticks per case (default 6000)")
    ap.add_argument("--numpy-ticks", type=int, default=600, help="NumPy baseline ticks per case (default 600)")
    args = ap.parse_args(argv)
    cfg = preset("default")
    ny, nx = cfg.grid_shape
    print(f"skin-sim model micro-benchmark: sheet grid {ny}x{nx}, patch {cfg.patch_size_m[0] * 1e3:.0f} mm, 3 layers")
    print("per tick, microseconds; ratio = NumPy median / numba median (same path, same run)")
    hdr = f"{'modes':>6} {'active':>6} {'path':>10} | {'median':>8} {'p99':>8} {'max':>8} | "
    hdr += f"{'numpy med':>10} {'numpy p99':>10} | ratio"
    print(hdr)
    print("-" * len(hdr))
    for r in run(args.ticks, args.numpy_ticks):
        print(
            f"{r['modes']:>6} {r['active']:>6} {r['path']:>10} | {r['numba_median_us']:8.1f} {r['numba_p99_us']:8.1f} "
            f"{r['numba_max_us']:8.1f} | {r['numpy_median_us']:10.1f} {r['numpy_p99_us']:10.1f} | {r['speedup_median']:6.1f}x"
        )
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
