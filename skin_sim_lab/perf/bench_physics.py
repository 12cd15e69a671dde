"""``skin-sim bench-model --physics``: the issue-11 physics figures of both tissue forms, printed.

The checks themselves are pure model code (:mod:`skin_sim_lab.oracles.physics`, asserted by
``tests/test_layered.py``); this module only runs them on the ``default`` and ``paper`` presets and prints.
"""

from __future__ import annotations

from skin_sim_node.model import preset

from ..oracles.physics import (
    BAND_DEPTHS_M,
    FEM_NONLINEAR_RATIO,
    IN_VIVO_BAND_N_PER_MM,
    band_n,
    drag_ratio,
    eq9_error,
    fit_stiffening,
    linear_series_force,
    monotone_scan,
    quasi_static_force,
    wall_curve,
)


def main(points: int = 40) -> int:
    """Print every physics figure of issue 11 for the ``default`` (layered) and ``paper`` presets."""
    from tqdm import tqdm

    print("skin-sim physics checks (issue 11): default preset = layered form; paper preset = the paper's form", flush=True)
    cfg = preset("default")
    paper = preset("paper")
    lo, hi = IN_VIVO_BAND_N_PER_MM
    print(
        f"in-vivo band: secant F(d)/d in [{lo}, {hi}] N/mm (Mayrovitz 2024; Flynn, Taberner, Nielsen 2011); flat punch "
        f"r = {cfg.tool_radius_m * 1e3:.1f} mm, 1 mm/s press, 2 s hold"
    )
    wl = cfg.interfaces[-1].wavelength_x_m
    for d in BAND_DEPTHS_M:
        f0 = quasi_static_force(cfg, d)
        fv = quasi_static_force(cfg, d, wl / 2, 0.0)
        b_lo, b_hi = band_n(d)
        ok = b_lo <= min(f0, fv) and max(f0, fv) <= b_hi
        print(
            f"  {d * 1e3:.0f} mm: origin (peak) {f0:.3f} N, valley {fv:.3f} N; band [{b_lo:.3f}, {b_hi:.3f}] N: "
            f"{'inside' if ok else 'OUTSIDE'}",
            flush=True,
        )
    with tqdm(total=points, desc="monotone scan", leave=False) as bar:
        worst, where = monotone_scan(cfg, points, progress=bar.update)
    print(
        f"monotone: slow press (0.5 mm/s, 1 kHz) to 5 mm at {points} sheet points: worst drop {worst * 100:.4f} % of the "
        f"running maximum (at x = {where[0] * 1e3:.1f} mm, y = {where[1] * 1e3:.1f} mm)",
        flush=True,
    )
    for y in (0.0, wl / 4):
        r, fmin, fmax = drag_ratio(cfg, y_m=y)
        print(
            f"drag: 10 mm at 1 mm depth, 10 mm/s, y = {y * 1e3:.2f} mm: max/min {r:.4f} ({fmin:.4f} .. {fmax:.4f} N)", flush=True
        )
    print(f"wall (quasi-static force below the stack, bottom at {cfg.total_thickness_m * 1e3:.3f} mm):")
    prev = None
    for d, f in wall_curve(cfg):
        slope = "" if prev is None else f", slope {(f - prev[1]) / (d - prev[0]) / 1e3:.2f} N/mm"
        print(f"  {d * 1e3:6.3f} mm: {f:9.3f} N{slope}", flush=True)
        prev = (d, f)
    print(
        "stiffening vs the layered neo-Hookean / linear force ratios of the reference (default moduli; "
        + ", ".join(f"{r}" for r in FEM_NONLINEAR_RATIO.values())
        + " at 1, 2, 3 mm):"
    )
    for d, r in FEM_NONLINEAR_RATIO.items():
        print(f"  {d * 1e3:.0f} mm: model {quasi_static_force(cfg, d) / linear_series_force(cfg, d):.3f}, FEM {r}", flush=True)
    n_fit, rms = fit_stiffening(cfg)
    print(f"  best common exponent n = {n_fit:.2f} (rms log error {rms:.3f}); default n = {cfg.layers[0].stiffening}", flush=True)
    print(f"paper form: eq 9 max error over the patch {eq9_error(paper):.2e} of the 6.11 um amplitude", flush=True)
    return 0
