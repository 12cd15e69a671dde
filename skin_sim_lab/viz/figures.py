"""``skin-sim chart model``: regenerate the model figures in ``docs/figures/``.

Fig 4 analogue: cross-sections of the default tissue pressed to two depths, one reaching
epidermis + dermis, one reaching all three layers; plus the force-depth curve of the
Reuss composite and the release-and-return trace of the surface under the tool.
"""

from __future__ import annotations

import argparse
from pathlib import Path

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt
import numpy as np

from skin_sim_node.bags.plots import draw_cross_section
from skin_sim_node.model import SkinModel, preset

DOCS = Path(__file__).resolve().parents[2] / "docs" / "figures"


def press(model: SkinModel, x: float, y: float, depth: float, dt: float = 1e-3, ticks: int = 200) -> None:
    model.reset()
    for i in range(ticks):
        d = depth * (i + 1) / ticks
        model.step((x, y, -d), (0.0, 0.0, -depth / (ticks * dt)), dt)
    for _ in range(20):
        model.step((x, y, -depth), (0.0, 0.0, 0.0), dt)


def fig4_cross_sections(out: Path) -> Path:
    cfg = preset("default")
    model = SkinModel(cfg)
    i_ed, i_df = cfg.interfaces
    cases = [
        (0.5 * (i_ed.mean_depth_m + i_df.mean_depth_m - i_df.amplitude_m), "tool depth within the dermis's rest depths"),
        (i_df.mean_depth_m + 0.6 * cfg.layers[2].thickness_m, "tool depth within the fat's rest depths"),
    ]
    fig, axes = plt.subplots(1, 2, figsize=(11, 4.0), sharey=True)
    for ax, (depth, label) in zip(axes, cases):
        press(model, 0.0, 0.0, depth)
        draw_cross_section(
            ax,
            model,
            0.0,
            0.0,
            -depth,
            f"{label}: {depth * 1e3:.2f} mm, F = {model.force_n:.3f} N\n"
            f"(layered form: all {model.n_affected} layers act in series from first contact)",
            half_m=12e-3,
        )
    axes[0].legend(loc="lower left", fontsize=7)
    fig.suptitle(
        "default tissue pressed at the origin by the flat punch, held 20 ms (interfaces at rest: "
        f"{i_ed.mean_depth_m * 1e3:.3f} mm and {i_df.mean_depth_m * 1e3:.3f} mm mean depth)",
        fontsize=9,
    )
    fig.tight_layout(rect=(0, 0, 1, 0.95))
    path = out / "fig4_cross_sections.png"
    fig.savefig(path, dpi=120)
    plt.close(fig)
    return path


def force_depth_and_release(out: Path) -> Path:
    """Force-depth of both forms at the origin and the release of the default (layered) form from 3 mm.

    Layered: a slow press (0.5 mm/s, 1 kHz; the dampers carry almost nothing). Paper form (the ``paper``
    preset's springs on the default tissue, Fig 3 engagement): static, one tick from rest per depth.
    """
    cfg = preset("default")
    paper_k = {f"layers.{la.name}.stiffness_n_per_m": la.stiffness_n_per_m for la in preset("paper").layers}
    paper = SkinModel(cfg.replace(form="paper", **paper_k))
    depths = np.linspace(0, cfg.total_thickness_m * 1.05, 600)
    forces, layers = [], []
    for d in depths:
        paper.reset()
        forces.append(paper.step((0.0, 0.0, -d), (0, 0, 0), 1e-3))
        layers.append(paper.n_affected)
    model = SkinModel(cfg)
    speed, dt = 0.5e-3, 1e-3
    slow_d = np.arange(1, int(depths[-1] / (speed * dt)) + 1) * speed * dt
    slow_f = [model.step((0.0, 0.0, -d), (0.0, 0.0, -speed), dt) for d in slow_d]
    press(model, 0.0, 0.0, 3e-3)
    s0 = model.surface_displacement_at(0.0, 0.0)
    dt = 1e-3
    t = np.arange(0, 3.0, dt)  # the slow viscoelastic arm (tau2 = 0.28 s) needs seconds
    surf = []
    for _ in t:
        model.step((0.0, 0.0, 0.02), (0, 0, 0), dt)
        surf.append(model.surface_displacement_at(0.0, 0.0))
    t, surf = np.concatenate(([0.0], t + dt)), np.array([s0, *surf])
    back = np.abs(surf) <= 0.05 * abs(s0)  # within 5 % of rest
    t5 = float(t[np.argmax(back)]) if back.any() else float(t[-1])
    fig, (a0, a1) = plt.subplots(1, 2, figsize=(11, 3.6))
    a0.plot(slow_d * 1e3, slow_f, "k", label="layered (default), 0.5 mm/s press")
    a0.plot(depths * 1e3, forces, color="grey", lw=0.8, label="paper form, static")
    a0.set_yscale("log")
    for n, c in zip((1, 2, 3), ("#f2c9a5", "#d9777a", "#f5e08e")):
        sel = np.array(layers) == n
        if sel.any():
            a0.axvspan(depths[sel][0] * 1e3, depths[sel][-1] * 1e3, color=c, alpha=0.6, label=f"paper: {n} layer(s)")
    a0.set_xlabel("tool depth at x = y = 0 (mm)")
    a0.set_ylabel("reaction force (N)")
    a0.set_title("force-depth at the origin: layered vs paper form", fontsize=9)
    a0.legend(fontsize=7)
    a1.plot(t * 1e3, surf * 1e3, "k.-", ms=3, lw=0.8)
    a1.axhline(0, color="grey", lw=0.5)
    a1.axvline(t5 * 1e3, color="r", lw=0.8, ls="--", label=f"within 5 % of rest after {t5 * 1e3:.0f} ms")
    a1.set_xlim(0, min(max(4 * t5, 0.02), t[-1]) * 1e3)
    a1.set_xlabel("time after release (ms; 1 ms ticks)")
    a1.set_ylabel("surface displacement under the tool (mm)")
    a1.set_title(
        f"release after a press to 3 mm (the surface under the punch then at {s0 * 1e3:.2f} mm):\n"
        "viscoelastic recovery of the layers, then the damped modal return (eq 2)",
        fontsize=9,
    )
    a1.legend(fontsize=7)
    fig.tight_layout()
    path = out / "force_depth_release.png"
    fig.savefig(path, dpi=120)
    plt.close(fig)
    return path


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(prog="skin-sim chart model", description=__doc__.splitlines()[0])
    ap.add_argument(
        "--out", type=Path, default=DOCS, help="output folder (skin-sim chart model: out/chart/model; --docs: docs/figures)"
    )
    args = ap.parse_args(argv)
    args.out.mkdir(parents=True, exist_ok=True)
    for p in (fig4_cross_sections(args.out), force_depth_and_release(args.out)):
        print(f"wrote {p}")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
