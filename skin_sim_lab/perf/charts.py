"""Cost growth charts (issue 7 part 2): step time against the mode count and the grid size.

``skin-sim chart performance`` times :meth:`SkinModel.step` alone (the force path) and
``step`` + ``build_grid`` every tick (the full grid) over a press-drag-release path at 1 kHz
with jittered tick intervals (the node's case: the propagator is recomputed every tick), with
every level-of-detail lever off so that the mode count is the fixed ``M x M``:

- against the modes per axis ``M`` = 1..60 on the default 120 x 120 grid;
- against the grid ``n x n``, n = 20..256, with the default 15 x 15 modes.

Times are thread CPU times (other processes on the shared cores do not count), each point the
least disturbed of three interleaved passes. It fits ``t = a + b x^p`` (``a``: the fixed per-call
cost, about 5-8 us of numba dispatch), prints ``p`` next to the expected order, and writes
``docs/performance/cost_vs_modes.png`` and ``docs/performance/cost_vs_grid.png``.
"""

from __future__ import annotations

import argparse
import time
from pathlib import Path

import numpy as np
from tqdm import tqdm

from skin_sim_node.model import SkinModel, preset

from .bench_model import LOD_OFF

DOCS = Path(__file__).resolve().parents[2] / "docs" / "performance"
MODES = (1, 2, 3, 4, 5, 6, 8, 10, 12, 15, 20, 25, 30, 35, 40, 45, 50, 55, 60)
GRIDS = (20, 32, 48, 64, 80, 96, 128, 160, 192, 224, 256)
FIT_MODES_FROM = 1  # fit the whole sweeps: the offset a in a + b x^p absorbs the per-call cost
FIT_GRID_FROM = 20


def growth_path(n_ticks: int, seed: int = 3):
    """Press to 3 mm (all layers), drag 10 mm, lift and relax; ``(pos, vel, dt)`` with 20 us tick jitter."""
    rng = np.random.default_rng(seed)
    third = n_ticks // 3
    out = []
    for i in range(n_ticks):
        dt = 1e-3 + float(rng.normal(0.0, 20e-6))
        if i < third:
            pos, vel = (0.0, 0.0, -3e-3 * i / third), (0.0, 0.0, -3e-3 / (third * 1e-3))
        elif i < 2 * third:
            pos, vel = (0.01 * (i - third) / third, 0.0, -3e-3), (0.01 / (third * 1e-3), 0.0, 0.0)
        else:
            pos, vel = (0.01, 0.0, 0.005), (0.0, 0.0, 0.0)
        out.append((pos, vel, dt))
    return out


def time_steps(cfg, path, with_grid: bool) -> np.ndarray:
    """Per-tick thread CPU time (us) of ``step`` (and ``build_grid`` when asked) along ``path``."""
    model = SkinModel(cfg)
    for pos, vel, dt in path[:30]:  # compile / warm caches
        model.step(pos, vel, dt)
        if with_grid:
            model.build_grid()
    model.reset()
    out = np.empty(len(path))
    clock = time.thread_time_ns  # CPU time of this thread: other processes on the shared cores do not count
    for i, (pos, vel, dt) in enumerate(path):
        t0 = clock()
        model.step(pos, vel, dt)
        if with_grid:
            model.build_grid()
        out[i] = clock() - t0
    return out * 1e-3


def _least_disturbed(runs: list[np.ndarray]) -> np.ndarray:
    return min(runs, key=np.median)


def sweep(force_ticks: int, grid_ticks: int, repeats: int = 3) -> dict:
    """Both sweeps, ``repeats`` passes interleaved; per point the pass with the smallest median."""
    base = preset("default").replace(**LOD_OFF)
    cfgs = {
        "modes": [(m, base.replace(**{"modes.m": m, "modes.n": m})) for m in MODES],
        "grid": [(n, base.replace(**{"grid.nx": n, "grid.ny": n})) for n in GRIDS],
    }
    runs = {(axis, x): ([], []) for axis, lst in cfgs.items() for x, _ in lst}
    fpath, gpath = growth_path(force_ticks), growth_path(grid_ticks)
    points = [(axis, x, cfg) for _ in range(repeats) for axis, lst in cfgs.items() for x, cfg in lst]
    for axis, x, cfg in tqdm(points, desc="timing points (mode counts, grid sizes; interleaved passes)", leave=False):
        runs[(axis, x)][0].append(time_steps(cfg, fpath, False))
        runs[(axis, x)][1].append(time_steps(cfg, gpath, True))
    rows = {"modes": [], "grid": []}
    for axis, lst in cfgs.items():
        for x, cfg in lst:
            size = SkinModel(cfg).basis.n_modes if axis == "modes" else x * x
            f, g = runs[(axis, x)]
            rows[axis].append((x, size, _least_disturbed(f), _least_disturbed(g)))
    return rows


def growth_order(x, y) -> float:
    """Exponent ``p`` of a least-squares fit ``y = a + b x^p`` in log space (``a``: the fixed per-call cost).

    Falls back to the plain log-log slope if the fit fails.
    """
    from scipy.optimize import curve_fit

    x = np.asarray(x, float)
    y = np.asarray(y, float)
    slope = float(np.polyfit(np.log(x), np.log(y), 1)[0])

    def model(xx, log_a, log_b, p):
        return np.log(np.exp(log_a) + np.exp(log_b) * xx**p)

    try:
        popt, _ = curve_fit(
            model, x, np.log(y), p0=(np.log(y.min()), np.log(y.max() / x.max() ** max(slope, 0.1)), slope), maxfev=20000
        )
        return float(popt[2])
    except (RuntimeError, ValueError):
        return slope


EXPECTED = {
    ("modes", "force"): (
        "2 (O(M^2): the (M/2)^2 active modes are propagated, with the propagator recomputed, and summed at the tool)"
    ),
    ("modes", "grid"): (
        "1 to 2 (O(M P + M^2 sqrt(P)) for P evaluated cells, the whole sheet with the levers off: the separable sum)"
    ),
    ("grid", "force"): "0 (O(1): the force path never touches the grid)",
    ("grid", "grid"): "1 (O(M G) for G = n^2 cells: every cell is evaluated and assembled with the levers off)",
}


def fits(rows: dict) -> dict:
    """Per (axis, path): (p of ``a + b x^p``, plain log-log slope) over the whole sweep."""
    out = {}
    for axis, lo in (("modes", FIT_MODES_FROM), ("grid", FIT_GRID_FROM)):
        sel = [r for r in rows[axis] if r[0] >= lo]
        x = [r[0] if axis == "modes" else r[1] for r in sel]
        for idx, path in ((2, "force"), (3, "grid")):
            y = [np.median(r[idx]) for r in sel]
            out[(axis, path)] = (growth_order(x, y), float(np.polyfit(np.log(x), np.log(y), 1)[0]))
    return out


def plot(rows: dict, slopes: dict, out_dir: Path) -> list[Path]:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    from skin_sim_node.bags.plots import save_figure

    paths = []
    for axis, xlabel, name in (
        ("modes", "modes per axis M (fixed M x M; (M/2)^2 active odd modes)", "cost_vs_modes.png"),
        ("grid", "grid cells G = n x n over the 120 mm sheet", "cost_vs_grid.png"),
    ):
        fig, ax = plt.subplots(figsize=(6.4, 4.2))
        data = rows[axis]
        x = np.array([r[0] if axis == "modes" else r[1] for r in data], float)
        for idx, label, colour in ((2, "force path (step)", "C0"), (3, "full grid (step + build_grid)", "C1")):
            med = np.array([np.median(r[idx]) for r in data])
            p99 = np.array([np.percentile(r[idx], 99) for r in data])
            p, slope = slopes[(axis, "force" if idx == 2 else "grid")]
            ax.loglog(x, med, "o-", color=colour, label=f"{label}: median; fit a + b x^p: p = {p:.2f}, log-log slope {slope:.2f}")
            ax.loglog(x, p99, ":", color=colour, alpha=0.7, label=f"{label}: p99")
        ax.set_xlabel(xlabel)
        ax.set_ylabel("thread CPU time per 1 kHz tick (us)")
        ax.grid(True, which="both", alpha=0.3)
        ax.legend(fontsize=7)
        title = "Step CPU time against the mode count" if axis == "modes" else "Step CPU time against the grid size"
        paths.append(save_figure(fig, out_dir / name, title + " (LOD levers off, 2-core shared machine)"))
    return paths


def _stats(us: np.ndarray) -> str:
    return f"{np.median(us):9.1f} {np.percentile(us, 99):8.1f}"


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(prog="skin-sim chart performance", description=__doc__.splitlines()[0])
    ap.add_argument(
        "--out",
        type=Path,
        default=DOCS,
        help="output folder (skin-sim chart performance: out/chart/performance; --docs: docs/performance)",
    )
    ap.add_argument("--force-ticks", type=int, default=1500, help="ticks per force-path point (default 1500)")
    ap.add_argument("--grid-ticks", type=int, default=300, help="ticks per full-grid point (default 300)")
    args = ap.parse_args(argv)
    print(
        f"chart performance: this machine's thread CPU time per model step over {len(MODES)} mode counts and {len(GRIDS)} "
        f"grid sizes, 3 interleaved passes -> {args.out} (timings: run it on a quiet machine)",
        flush=True,
    )
    rows = sweep(args.force_ticks, args.grid_ticks)
    slopes = fits(rows)
    print("step CPU time per tick, microseconds (median / p99), LOD levers off, jittered 1 kHz ticks, one run")
    print(f"{'M':>3} {'active':>6} | {'force med':>9} {'p99':>8} | {'grid med':>9} {'p99':>8}")
    for m, k, f, g in rows["modes"]:
        print(f"{m:3d} {k:6d} | {_stats(f)} | {_stats(g)}")
    print(f"{'n':>3} {'cells':>6} | {'force med':>9} {'p99':>8} | {'grid med':>9} {'p99':>8}")
    for n, c, f, g in rows["grid"]:
        print(f"{n:3d} {c:6d} | {_stats(f)} | {_stats(g)}")
    print("fitted order p of t = a + b x^p and plain log-log slope (x = M, or the cells G), against the expected order")
    print("(p is meaningless where the curve is flat: read the slope there):")
    for key, (p, slope) in slopes.items():
        print(f"  time vs {key[0]:>5}, {key[1]:>5} path: p = {p:5.2f}, slope {slope:5.2f}; expected {EXPECTED[key]}")
    for p in plot(rows, slopes, args.out):
        print(f"wrote {p}")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
