"""``skin-sim chart validation --only reference``: the large-deformation reference, its convergence and its
small-strain check against the linear FEM.

Writes ``docs/validation/large_deformation.{md,csv,png}`` from the cached solves
(``docs/validation/hyper_cache``); ``--fresh`` solves again (about 2 min for all mesh levels on this
machine, most of it level 3).
"""

from __future__ import annotations

import argparse
import csv
from pathlib import Path

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt
import numpy as np

from skin_sim_node.model import TissueConfig, preset

from .references import (
    AXI_LEVELS,
    AXI_REFERENCE_LEVEL,
    THREE_D_LEVEL,
    THREE_D_SCENARIOS,
    axisym,
    converged_fem,
    linear_3d,
    nonlinear_3d,
)
from .scenarios import BY_NAME

OUT = Path(__file__).resolve().parents[2] / "docs" / "validation"
CHECK_DEPTHS_M = (0.1e-3, 0.5e-3, 1e-3, 2e-3, 3e-3)
SMALL_STRAIN_DEPTH_M = 0.1e-3
SMALL_STRAIN_TOL = 0.01  # issue 11: linear and nonlinear agree within 1 % at 0.1 mm


def convergence_rows(cfg: TissueConfig | None = None, fresh: bool = False, progress: bool = True) -> list[dict]:
    """One row per mesh level: forces at the check depths (neo-Hookean and linear) and their ratios."""
    rows, prev = [], None
    for lvl in AXI_LEVELS:
        nh = axisym(cfg, lvl, progress=progress, fresh=fresh)
        lin = axisym(cfg, lvl, law="linear", progress=progress, fresh=fresh)
        s = nh.setup
        row = {"level": lvl, "elements": f"{s.n_tool}, {s.n_out}, {'x'.join(map(str, s.nz))}", "dofs": nh.n_dofs}
        for d in CHECK_DEPTHS_M:
            row[f"F_nh_{d * 1e3:g}mm_n"] = float(nh.force_n(d))
        for d in CHECK_DEPTHS_M:
            row[f"nh_over_linear_{d * 1e3:g}mm"] = float(nh.force_n(d) / lin.force_n(d))
        f3 = row["F_nh_3mm_n"]
        row["change_3mm_pct"] = "" if prev is None else 100 * abs(f3 / prev - 1)
        row["linear_k_n_per_m"] = float(lin.force_n(1e-3) / 1e-3)
        row["edge_slip_3mm_mm"] = float(nh.edge_slip_m[-1] * 1e3)
        row["newton_iterations"] = nh.newton_iterations
        row["solve_s"] = nh.solve_s
        prev = f3
        rows.append(row)
    return rows


def markdown(rows: list[dict], k3d: dict[str, float]) -> str:
    """The reference page: mesh convergence table of the axisymmetric runs and the 3D cross-check."""
    ref = next(r for r in rows if r["level"] == AXI_REFERENCE_LEVEL)
    lines = [
        "# Large-deformation reference (axisymmetric, flat layers, compressible neo-Hookean)",
        "",
        "Written by `skin-sim chart validation --only reference` (`skin_sim_lab/validation/large_deformation.py`).",
        "",
        "## Mesh convergence",
        "",
        "| level | elements (tool, outer, z: epi x dermis x fat) | DOFs | F 0.1 mm (N) | F 1 mm (N) | F 2 mm (N) | F 3 mm (N) "
        "| change at 3 mm | edge slip at 3 mm (mm) | Newton its | solve (s) |",
        "|---|---|---|---|---|---|---|---|---|---|---|",
    ]
    for r in rows:
        ch = "" if r["change_3mm_pct"] == "" else f"{r['change_3mm_pct']:.2f} %"
        lines.append(
            f"| {r['level']} | {r['elements']} | {r['dofs']} | {r['F_nh_0.1mm_n']:.5f} | {r['F_nh_1mm_n']:.4f} "
            f"| {r['F_nh_2mm_n']:.4f} | {r['F_nh_3mm_n']:.4f} | {ch} | {r['edge_slip_3mm_mm']:.3f} | {r['newton_iterations']} "
            f"| {r['solve_s']:.1f} |"
        )
    lines += [
        "",
        f"Reference level: {AXI_REFERENCE_LEVEL}.",
        "",
        "## Nonlinear over linear (same mesh, same moduli)",
        "",
        "| level | " + " | ".join(f"{d * 1e3:g} mm" for d in CHECK_DEPTHS_M) + " |",
        "|---|" + "---|" * len(CHECK_DEPTHS_M),
    ]
    for r in rows:
        ratios = " | ".join(f"{r[f'nh_over_linear_{d * 1e3:g}mm']:.4f}" for d in CHECK_DEPTHS_M)
        lines.append(f"| {r['level']} | {ratios} |")
    ok = abs(ref[f"nh_over_linear_{SMALL_STRAIN_DEPTH_M * 1e3:g}mm"] - 1) <= SMALL_STRAIN_TOL
    lines += [
        "",
        f"Small-strain check at {SMALL_STRAIN_DEPTH_M * 1e3:g} mm (aim within {SMALL_STRAIN_TOL:.0%}): "
        f"{'PASS' if ok else 'FAIL'}.",
        "",
        "## Linear axisymmetric vs the linear 3D FEM (egg-carton interfaces)",
        "",
        f"Axisymmetric linear stiffness, flat layers, level {AXI_REFERENCE_LEVEL}: {ref['linear_k_n_per_m']:.3f} N/m.",
        "",
    ]
    lines += [f"- 3D linear, {k}: {v:.3f} N/m ({100 * (v / ref['linear_k_n_per_m'] - 1):+.2f} %)" for k, v in k3d.items()]
    return "\n".join(lines) + "\n"


def three_d_markdown(cfg: TissueConfig | None = None, fresh: bool = False) -> str:
    """The 3D egg-carton neo-Hookean solves: force at 1, 2, 3 mm, over the linear 3D FEM and the axisymmetric reference."""
    ax = axisym(cfg)
    lines = [
        f"## 3D, egg-carton interfaces (mesh level {THREE_D_LEVEL})",
        "",
        "| scenario | DOFs | F 1 mm (N) | F 2 mm (N) | F 3 mm (N) | nonlinear / linear 3D at 0.3, 1, 2, 3 mm "
        "| 3D / axisymmetric at 1, 2, 3 mm | Newton its | solve (s) |",
        "|---|---|---|---|---|---|---|---|---|",
    ]
    for name in THREE_D_SCENARIOS:
        sc = BY_NAME[name]
        r = nonlinear_3d(sc, cfg, fresh=fresh)
        k = linear_3d(sc, cfg, progress=False).stiffness_n_per_m
        d = np.array([1e-3, 2e-3, 3e-3])
        deepest = float(r.depths_m[-1])
        reached = d <= deepest + 1e-12  # past the deepest converged load step there is no reference (no clamping)
        f = r.force_n(d)
        fcol = [f"{fi:.4f}" if ok else f"- (stopped at {deepest * 1e3:.2f} mm)" for fi, ok in zip(f, reached)]
        ratio_lin = "; ".join(f"{r.force_n(x) / (k * x):.4f}" if x <= deepest + 1e-12 else "-" for x in (r.depths_m[0], *d))
        ratio_ax = "; ".join(f"{a / b:.3f}" if ok else "-" for a, b, ok in zip(f, ax.force_n(d), reached))
        lines.append(
            f"| {name} | {r.n_dofs} | {' | '.join(fcol)} | {ratio_lin} | {ratio_ax} | {r.newton_iterations} | {r.solve_s:.0f} |"
        )
    return "\n".join(lines) + "\n"


def chart(out: Path, cfg: TissueConfig | None, k3d: dict[str, float]) -> None:
    """Draw ``large_deformation.png`` in ``out``: neo-Hookean against linear force-depth, and the surface profile."""
    nh = axisym(cfg)
    lin = axisym(cfg, law="linear")
    fig, (a0, a1) = plt.subplots(1, 2, figsize=(12, 4.5))
    d = np.linspace(0, nh.depths_m[-1], 300)
    a0.plot(d * 1e3, nh.force_n(d), "k", lw=2, label="neo-Hookean, axisymmetric (reference)")
    a0.plot(d * 1e3, lin.force_n(d), "k--", lw=1, label="linear, axisymmetric (same mesh)")
    for k, v in k3d.items():
        a0.plot(d * 1e3, v * d, lw=0.8, label=f"linear 3D FEM, {k}")
    a0.set_xlabel("punch depth (mm)")
    a0.set_ylabel("force (N)")
    a0.legend(fontsize=7)
    a0.set_title(f"flat punch r0 = {nh.setup.tool_radius_m * 1e3:g} mm on the default layers", fontsize=9)
    r = np.linspace(0, 15e-3, 300)
    for i, pd in enumerate(nh.profile_depths_m):
        a1.plot(r * 1e3, nh.field_down_at(pd, r) / pd, color=f"C{i}", label=f"neo-Hookean, {pd * 1e3:g} mm")
    a1.plot(r * 1e3, lin.field_down_at(1e-3, r) / 1e-3, "k--", lw=1, label="linear (any depth)")
    a1.set_xlabel("current radius (mm)")
    a1.set_ylabel("surface displacement / depth")
    a1.legend(fontsize=7)
    fig.tight_layout()
    fig.savefig(out / "large_deformation.png", dpi=120)
    plt.close(fig)


def run(out: Path = OUT, fresh: bool = False, cfg: TissueConfig | None = None) -> list[dict]:
    """Solve (or load) every level, write the table, CSV and chart, print the table."""
    src = "fresh solves, ~2 min" if fresh else "docs/validation/hyper_cache, or solved once if missing; --fresh to solve again"
    print(f"large-deformation reference: {len(AXI_LEVELS)} mesh levels x (neo-Hookean, linear) ({src})", flush=True)
    rows = convergence_rows(cfg, fresh)
    with open(out / "large_deformation.csv", "w", newline="") as fh:
        w = csv.DictWriter(fh, fieldnames=list(rows[0]))
        w.writeheader()
        w.writerows(rows)
    k3d = {}
    if cfg is None or cfg == preset("default"):  # the cached 3D solves are of the default preset
        k3d = {n: converged_fem(BY_NAME[n], progress=False).stiffness_n_per_m for n in ("peak-3layer", "valley-3layer")}
    text = markdown(rows, k3d) + "\n" + three_d_markdown(cfg, fresh)
    (out / "large_deformation.md").write_text(text)
    chart(out, cfg, k3d)
    print(text)
    return rows


def main(argv=None) -> int:
    """``skin-sim chart validation --only reference``: solve (or read) the references, write their page, CSV and chart."""
    ap = argparse.ArgumentParser(prog="skin-sim chart validation --only reference", description=__doc__.split("\n")[0])
    ap.add_argument("--out", default=str(OUT))
    ap.add_argument("--fresh", action="store_true", help="solve again instead of reading the cache (~2 min)")
    a = ap.parse_args(argv)
    run(Path(a.out), a.fresh)
    return 0
