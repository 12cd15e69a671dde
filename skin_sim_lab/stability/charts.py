"""``skin-sim chart stability``: regenerate ``docs/stability/`` and print the figures' key numbers.

- ``numerics_maps.png``: per method, over grid spacing and ``dt``: where energy grows, where the
  error at 40 ms passes 1 %, with the explicit limits ``2 / omega_max`` and ``c dt / dx = 1 / sqrt(2)``;
- ``cfl_boundary.png``: the measured explicit limits (bisection) against theory, per grid;
- ``haptic_map.png``: the wall sweep over stiffness and loop rate, naive and with the device-side
  passivity controller, against Colgate & Brown's ``K < 2 b / T`` and the exact sampled-loop limit;
- ``transparency.png``: the stiffness the user feels against the rendered wall's.
"""

from __future__ import annotations

import argparse
import math
from pathlib import Path

import matplotlib
import matplotlib.ticker

matplotlib.use("Agg")
import matplotlib.pyplot as plt
import numpy as np
from tqdm import tqdm

from skin_sim_node.device.stylus import DeviceParams

from . import haptic_loop as hl
from . import numerics as nm
from . import stiffening

DOCS = Path(__file__).resolve().parents[2] / "docs" / "stability"
CHART_RATES_HZ = (100.0, 250.0, 500.0, 1000.0, 2000.0, 4000.0)
CHART_STIFFNESSES = tuple(float(k) for k in np.geomspace(100.0, 5000.0, 10))
TRANSPARENCY_K = tuple(float(k) for k in np.geomspace(200.0, 5000.0, 6))
ERROR_LIMIT = 0.01


def numerics_figures(out: Path) -> list[Path]:
    mem = nm.dermis_membrane()
    c = mem.wave_speed_m_s
    pts = nm.sweep()
    fig, axes = plt.subplots(1, len(nm.METHODS), figsize=(17, 3.8), sharey=True)
    dxs = np.array(sorted({p.dx_m for p in pts}))
    fine = np.geomspace(dxs.min() * 0.8, dxs.max() * 1.2, 50)
    for ax, method in zip(axes, nm.METHODS):
        sel = [p for p in pts if p.method == method]
        for cond, style, label in (
            (lambda p: p.grows, dict(marker="x", color="#c0392b"), "energy grows"),
            (lambda p: not p.grows and p.error > ERROR_LIMIT, dict(marker="o", color="#e67e22", mfc="none"), "time error > 1 %"),
            (lambda p: not p.grows and p.error <= ERROR_LIMIT, dict(marker="o", color="#27ae60"), "time error <= 1 %"),
        ):
            q = [p for p in sel if cond(p)]
            if q:
                ax.plot([p.dx_m * 1e3 for p in q], [p.dt_s * 1e3 for p in q], ls="none", ms=5, label=label, **style)
        ax.plot(fine * 1e3, fine / (math.sqrt(2) * c) * 1e3, "k--", lw=1, label="c dt/dx = 1/sqrt(2)")
        if method in ("leapfrog", "mass-spring"):
            lim = [nm.dt_limit_s(method, mem, n) for n in nm.GRIDS]
            ax.plot([mem.size_x_m / (n + 1) * 1e3 for n in nm.GRIDS], np.array(lim) * 1e3, "b-", lw=1, label="2 / omega_max")
        ax.set_xscale("log")
        ax.set_yscale("log")
        ax.set_xlabel("grid spacing dx (mm)")
        ax.set_title(method, fontsize=9)
    axes[0].set_ylabel("time step dt (ms)")
    handles = {}
    for ax in axes:  # one legend with every mark any panel uses (each panel holds only some)
        for h, lab in zip(*ax.get_legend_handles_labels()):
            handles.setdefault(lab, h)
    fig.legend(handles.values(), handles.keys(), fontsize=7, loc="lower center", ncol=len(handles), frameon=False)
    fig.suptitle(
        f"dermis membrane, c = {c:.1f} m/s, 60 mm patch, released from a 1 mm tool indentation; error at "
        f"{nm.T_END_S * 1e3:.0f} ms against the exact-in-time solution of the same grid",
        fontsize=9,
    )
    fig.tight_layout(rect=(0, 0.07, 1, 1))
    p1 = out / "numerics_maps.png"
    fig.savefig(p1, dpi=110)
    plt.close(fig)

    rows = []
    fig, ax = plt.subplots(figsize=(6, 3.8))
    for method, mk in (("leapfrog", "o"), ("mass-spring", "s")):
        grids = tqdm(nm.GRIDS, desc=f"{method} dt limit (bisection)", leave=False)
        meas = [nm.measured_dt_limit_s(method, mem, n) for n in grids]
        dx = np.array([mem.size_x_m / (n + 1) for n in nm.GRIDS])
        th = np.array([nm.dt_limit_s(method, mem, n) for n in nm.GRIDS])
        ax.plot(dx * 1e3, c * np.array(meas) / dx, mk, mfc="none", label=f"{method}: measured")
        rows += [(method, n, d, m, t) for n, d, m, t in zip(nm.GRIDS, dx, meas, th)]
    ax.plot(dx * 1e3, c * th / dx, "b-", lw=1, label="theory 2 / omega_max (both)")
    ax.axhline(1 / math.sqrt(2), color="k", ls="--", lw=1, label="CFL 1/sqrt(2)")
    ax.set_xscale("log")
    ax.set_xlabel("grid spacing dx (mm)")
    ax.set_ylabel("largest stable c dt / dx")
    ax.legend(fontsize=7)
    ax.set_title("measured explicit stability limit vs theory", fontsize=9)
    fig.tight_layout()
    p2 = out / "cfl_boundary.png"
    fig.savefig(p2, dpi=110)
    plt.close(fig)
    print(
        "spatial error of the 5-point grid (exact in time) against the continuum modes at "
        f"{nm.T_END_S * 1e3:.0f} ms, max over the patch / initial peak:"
    )
    for n in nm.GRIDS:
        print(f"  n={n:2d} dx={mem.size_x_m / (n + 1) * 1e3:5.2f} mm: {nm.spatial_error(mem, n) * 100:.1f} %")
    print("measured explicit limits (energy growth > 100x within 2000 steps, bisection to 0.1 %):")
    for method, n, d, m, t in rows:
        print(
            f"  {method:<11} n={n:2d} dx={d * 1e3:5.2f} mm: dt {m * 1e6:8.2f} us vs 2/omega_max {t * 1e6:8.2f} us "
            f"(ratio {m / t:.4f}), c dt/dx = {c * m / d:.4f} (1/sqrt(2) = {1 / math.sqrt(2):.4f})"
        )
    return [p1, p2]


def haptic_figures(out: Path) -> list[Path]:
    res = hl.sweep(CHART_STIFFNESSES, CHART_RATES_HZ)
    p = DeviceParams()
    b_dev, b_all = p.damping_n_s_per_m, p.damping_n_s_per_m + p.hand_damping_n_s_per_m
    rates = np.geomspace(80, 5000, 60)
    fig, axes = plt.subplots(1, 2, figsize=(12, 4.8), sharey=True)
    for ax, stab in zip(axes, ("none", "passivity")):
        for r in CHART_RATES_HZ:
            for k in CHART_STIFFNESSES:
                v = res[(stab, r, k)]
                ax.plot(r, k * 1e-3, "o" if v.stable else "x", color="#27ae60" if v.stable else "#c0392b", ms=6)
        ax.plot([], [], "o", color="#27ae60", ms=6, label="swept point: stable (force settles)")
        ax.plot([], [], "x", color="#c0392b", ms=6, label="swept point: unstable (force does not settle)")
        ax.plot(
            rates,
            [hl.colgate_k_max(b_dev, r) * 1e-3 for r in rates],
            "k--",
            lw=1,
            label=f"Colgate 2b/T, b = device {b_dev:.2f} N s/m",
        )
        ax.plot(
            rates,
            [hl.colgate_k_max(b_all, r) * 1e-3 for r in rates],
            "k:",
            lw=1,
            label=f"2b/T, b = device + hand {b_all:.2f} N s/m",
        )
        ax.plot(rates, [hl.linear_k_max(r) * 1e-3 for r in rates], "b-", lw=1, label="exact sampled loop, 1-tick delay")
        ax.set_xscale("log")
        ax.set_yscale("log")
        ax.set_ylim(0.08, 6)
        ax.set_xlabel("loop rate (Hz)")
        ax.set_title(
            f"{'naive coupling' if stab == 'none' else 'device-side passivity controller'}: dot stable, x unstable", fontsize=9
        )
    axes[0].set_ylabel("rendered wall stiffness K (N/mm)")
    handles, labels = axes[0].get_legend_handles_labels()  # below the panels: inside, it hid swept points
    fig.legend(handles, labels, fontsize=7, loc="lower center", ncol=3, frameon=False)
    fig.tight_layout(rect=(0, 0.1, 1, 1))
    p1 = out / "haptic_map.png"
    fig.savefig(p1, dpi=110)
    plt.close(fig)
    print("haptic wall sweep (hold 0.5 N, 1-tick delay + ZOH): largest swept K below which all points are stable, N/mm")
    for r in CHART_RATES_HZ:
        print(
            f"  {r:6.0f} Hz: naive {hl.boundary(res, 'none', r, CHART_STIFFNESSES) * 1e-3:.3f}, passivity "
            f"{hl.boundary(res, 'passivity', r, CHART_STIFFNESSES) * 1e-3:.3f}; Colgate 2b/T b=0.05: "
            f"{hl.colgate_k_max(b_dev, r) * 1e-3:.3f}, b=3.05: {hl.colgate_k_max(b_all, r) * 1e-3:.3f}; exact linear "
            f"{hl.linear_k_max(r) * 1e-3:.3f}"
        )
    for r in (1000.0, 250.0):
        lo = hl.largest_stable(r, "none", 100.0, 20000.0)
        print(f"  naive boundary by bisection at {r:.0f} Hz: {lo * 1e-3:.3f} N/mm (exact linear {hl.linear_k_max(r) * 1e-3:.3f})")
        hi_k = max_stable_stabilised(res, r)
        print(f"  largest stiffness the stabilised loop renders stably at {r:.0f} Hz: {hi_k * 1e-3:.2f} N/mm")

    fig, (ax, bx) = plt.subplots(1, 2, figsize=(11, 3.8))
    for r, col in ((1000.0, "#2c3e50"), (250.0, "#8e44ad")):
        for stab, mk in (("none", "x"), ("passivity", "o")):
            ks, kr, br = [], [], []
            for k in TRANSPARENCY_K:
                if not hl.wall_point(k, r, stab).stable:
                    continue
                kf, bf = hl.rendered_stiffness(k, r, stab)
                ks.append(k)
                kr.append(kf)
                br.append(bf)
                print(
                    f"  transparency {r:.0f} Hz {stab}: K {k * 1e-3:.3f} N/mm -> felt {kf * 1e-3:.3f} N/mm, "
                    f"damping {bf:.2f} N*s/m"
                )
            ks = np.array(ks)
            ax.plot(ks * 1e-3, np.array(kr) / ks, mk + "-", color=col, mfc="none", label=f"{r:.0f} Hz, {stab}")
            bx.plot(ks * 1e-3, br, mk + "-", color=col, mfc="none", label=f"{r:.0f} Hz, {stab}")
    for a_ in (ax, bx):
        a_.set_xscale("log")
        a_.xaxis.set_minor_formatter(matplotlib.ticker.NullFormatter())
        ticks = [0.2, 0.5, 1.0, 2.0, 5.0]  # the swept range, 0.2-5 N/mm: a log axis alone labels only 10^0
        a_.set_xticks(ticks, [f"{t:g}" for t in ticks])
        a_.set_xlabel("rendered wall stiffness K (N/mm)")
        a_.legend(fontsize=7)
    ax.axhline(1.0, color="k", ls="--", lw=0.8)
    ax.set_ylabel("felt / rendered stiffness")
    ax.set_title("stiffness felt at the stylus (5 Hz, 0.2 mm hand wobble; stable points only)", fontsize=9)
    bx.axhline(0.0, color="k", ls="--", lw=0.8)
    bx.set_ylabel("damping felt (N*s/m)")
    bx.set_title("damping felt: the delayed wall's own (negative) and the controller's", fontsize=9)
    fig.text(0.5, 0.01, "x inside o: naive and passivity controller give the same figure at that K", ha="center", fontsize=7)
    fig.tight_layout(rect=(0, 0.04, 1, 1))
    p2 = out / "transparency.png"
    fig.savefig(p2, dpi=110)
    plt.close(fig)
    return [p1, p2]


def max_stable_stabilised(res, rate_hz: float, k_max: float = 200e3) -> float:
    """Largest wall stiffness the passivity-stabilised loop holds stably.

    From the sweep: bisect between the last all-stable swept ``K`` and the next (unstable) one; if the
    whole sweep is stable, scan upwards by 2x first.
    """
    lo = hl.boundary(res, "passivity", rate_hz, CHART_STIFFNESSES)
    higher = [k for k in CHART_STIFFNESSES if k > lo]
    if higher:
        return hl.largest_stable(rate_hz, "passivity", lo, higher[0], iters=5)
    k = lo
    while k < k_max and hl.wall_point(2 * k, rate_hz, "passivity").stable:
        k *= 2
    return k if k >= k_max else hl.largest_stable(rate_hz, "passivity", k, 2 * k, iters=5)


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(prog="skin-sim chart stability", description=__doc__.splitlines()[0])
    ap.add_argument(
        "--out",
        type=Path,
        default=DOCS,
        help="output folder (skin-sim chart stability: out/chart/stability; --docs: docs/stability)",
    )
    ap.add_argument("--only", choices=("numerics", "haptic", "stiffening"), help="regenerate one group")
    args = ap.parse_args(argv)
    what = {
        "numerics": "explicit-solver maps (~35 s)",
        "haptic": "haptic-loop sweeps (~45 s)",
        "stiffening": "tangent stiffness vs depth and loop limits (~30 s)",
    }
    todo = [k for k in what if args.only in (None, k)]
    print("chart stability: " + "; ".join(what[k] for k in todo) + f" (durations measured on 2 cores) -> {args.out}", flush=True)
    args.out.mkdir(parents=True, exist_ok=True)
    paths = []
    if args.only in (None, "numerics"):
        paths += numerics_figures(args.out)
    if args.only in (None, "haptic"):
        paths += haptic_figures(args.out)
    if args.only in (None, "stiffening"):
        paths += stiffening.figures(args.out)
    for p in paths:
        print(f"wrote {p}")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
