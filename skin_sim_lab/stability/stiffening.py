"""Stability with a strain-stiffening tissue: the tangent stiffness at depth against the loop's limits.

The haptic loop sees the local slope of the force, ``K(d) = -dF_z/dz`` (:meth:`SkinModel.tangent`,
the model's hand-over to the force path), not the secant ``F/d``. A stiffening law raises ``K`` with
depth, so a loop stable at the surface can go unstable deep in. This module

- tabulates ``K(d)`` of the model (any ``tissue.form``) and of the large-deformation reference
  (the slope of the axisymmetric neo-Hookean curve, :mod:`skin_sim_lab.validation.hyperelastic`);
- compares it with the naive sampled-loop limit (exact spectral radius,
  :func:`.haptic_loop.linear_k_max`) and the largest wall the device-side passivity controller
  (:mod:`skin_sim_node.device.passivity`, used through the simulated device) holds, at 1 kHz;
- closes the real loop (simulated Touch + :class:`~skin_sim_node.session.HapticSession` with its
  force-rate limiter) pressing and holding at each depth, naive and with the passivity controller,
  and reports the verdict and the largest force rate the session published.
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt
import numpy as np
from tqdm import tqdm

from skin_sim_node.device.stylus import DeviceParams
from skin_sim_node.model import SkinModel, TissueConfig, preset
from skin_sim_node.session import SessionParams

from ..validation.methods import static_dt_s, static_force_n
from ..validation.references import axisym
from . import haptic_loop as hl

RATE_HZ = 1000.0  # the product's haptic rate
DEPTHS_M = tuple(np.round(np.linspace(0.25e-3, 3e-3, 12), 6))
LOOP_DEPTHS_M = (0.5e-3, 1e-3, 2e-3, 3e-3)
TICK_S = 1.0 / RATE_HZ


def tick_force_n(model: SkinModel, depth_m: float, offset_m: float = 0.0, x_m: float = 0.0, y_m: float = 0.0) -> float:
    """Force of one 1 kHz tick at ``depth_m + offset_m`` after the tissue has settled at ``depth_m`` (dampers relaxed:
    one backward-Euler step of :data:`~skin_sim_lab.validation.methods.STATIC_DT_S` in the layered form)."""
    model.reset()
    model.step((x_m, y_m, -depth_m), (0.0, 0.0, 0.0), static_dt_s(model.cfg))
    if offset_m == 0.0:
        return float(model.step((x_m, y_m, -depth_m), (0.0, 0.0, 0.0), TICK_S))
    return float(model.step((x_m, y_m, -depth_m - offset_m), (0.0, 0.0, 0.0), TICK_S))


def model_tangent_n_per_m(model: SkinModel, depth_m: float, x_m: float = 0.0, y_m: float = 0.0) -> tuple[float, float]:
    """Static force at ``depth_m`` and the ``-dF_z/dz`` a 1 kHz tick sees there (``tangent()`` after one tick held at
    the settled depth): in the layered form each layer's slope is ``k_i phi'(eps_i) + b_i / dt`` in series, so the
    loop sees the spring stiffening plus the dampers' backward-Euler stiffness."""
    f = tick_force_n(model, depth_m, 0.0, x_m, y_m)
    t = model.tangent()
    return f, float(-np.asarray(t.stiffness_n_per_m)[2, 2])


LOOP_LABEL = "closed loop at that depth (on the tick tangent): "
STATIC_SLOPE_STEP_M = 1e-6
"""Half-width of the central difference of :func:`model_static_slope_n_per_m`: 1 um, 0.4 % of the shallowest depth
charted, so the curvature of the force adds at most ~1e-5 relative (the force's second derivative is smooth there)."""


def model_static_slope_n_per_m(model: SkinModel, depth_m: float, x_m: float = 0.0, y_m: float = 0.0) -> float:
    """Quasi-static slope ``dF/dd`` of the model's own settled force (a press held still, dampers relaxed:
    :func:`~skin_sim_lab.validation.methods.static_force_n`), by a central difference of
    :data:`STATIC_SLOPE_STEP_M`. It is the springs' stiffening alone, without the dampers' ``b/dt``."""
    h = STATIC_SLOPE_STEP_M
    return (static_force_n(model, x_m, y_m, depth_m + h) - static_force_n(model, x_m, y_m, depth_m - h)) / (2 * h)


def reference_tangent_n_per_m(depths_m) -> np.ndarray:
    """Slope of the converged large-deformation force-depth curve (central differences on its load steps)."""
    r = axisym(progress=False)
    d = np.concatenate([[0.0], r.depths_m])
    f = np.concatenate([[0.0], r.forces_n])
    return np.interp(depths_m, d, np.gradient(f, d))


@dataclass
class LoopPoint:
    """The closed loop at one depth: force, model tangent, naive and passivity verdicts, largest published force rate."""

    depth_m: float
    force_n: float
    tangent_n_per_m: float
    naive_stable: bool
    passivity_stable: bool
    max_force_rate_n_per_s: float  # largest |dF/dt| the session published (naive run)


def loop_point(cfg: TissueConfig, depth_m: float, stabiliser: str, params: SessionParams | None = None):
    """Press and hold at ``depth_m`` with the model in the loop; returns (Verdict, trace)."""
    model = SkinModel(cfg)
    f_static, _ = model_tangent_n_per_m(model, depth_m)
    hand = DeviceParams().hand_stiffness_n_per_m
    path = hl.hold_path(depth_m, hand, max(f_static, 0.05))
    env = hl.TissueEnv(cfg, params)
    tr = hl.run_loop(env, RATE_HZ, path, stabiliser)
    return hl.classify(tr, max(f_static, 0.05)), tr


def table(cfg: TissueConfig | None = None, progress: bool = True) -> tuple[list[dict], list[LoopPoint], dict]:
    """Tangent stiffness per depth (model, reference) and the closed-loop check at :data:`LOOP_DEPTHS_M`."""
    cfg = cfg or preset("default")
    model = SkinModel(cfg)
    k_ref = reference_tangent_n_per_m(np.array(DEPTHS_M))
    rows = []
    for d, kr in zip(DEPTHS_M, k_ref):
        f, k = model_tangent_n_per_m(model, d)
        rows.append(
            {
                "depth_mm": d * 1e3,
                "force_n": f,
                "model_static_slope_n_per_mm": model_static_slope_n_per_m(model, d) * 1e-3,
                "model_tangent_n_per_mm": k * 1e-3,
                "reference_tangent_n_per_mm": kr * 1e-3,
            }
        )
    limits = {
        "naive_exact_n_per_mm": hl.linear_k_max(RATE_HZ) * 1e-3,
        "colgate_device_b_n_per_mm": hl.colgate_k_max(DeviceParams().damping_n_s_per_m, RATE_HZ) * 1e-3,
    }
    pts = []
    for d in tqdm(LOOP_DEPTHS_M, desc="closed loop at depth (naive, passivity)", disable=not progress, leave=False):
        v0, tr = loop_point(cfg, d, "none")
        v1, _ = loop_point(cfg, d, "passivity")
        rate = float(np.max(np.abs(np.diff(tr.force_n))) * RATE_HZ)
        f, k = model_tangent_n_per_m(SkinModel(cfg), d)
        pts.append(LoopPoint(d, f, k, v0.stable, v1.stable, rate))
    return rows, pts, limits


def figures(out: Path, cfg: TissueConfig | None = None) -> list[Path]:
    """Draw ``stiffening.png`` in ``out`` and print its table; the paths.

    Plotted against depth: the model's quasi-static slope (its settled force's ``dF/dd``), the tangent one 1 kHz
    tick sees (that slope with the dampers' ``b/dt`` in series: what the loop's stability depends on), the
    large-deformation reference's slope, the loop limits, and the closed-loop verdicts at :data:`LOOP_DEPTHS_M`.
    """
    cfg = cfg or preset("default")
    rows, pts, limits = table(cfg)
    form = cfg.form
    fig, ax = plt.subplots(figsize=(8, 6.2))
    d = [r["depth_mm"] for r in rows]
    ax.semilogy(
        d,
        [max(r["model_static_slope_n_per_mm"], 1e-6) for r in rows],
        "o-",
        color="#1f77b4",
        label=f"model ({form}), quasi-static slope dF/dd of its settled force",
    )
    ax.semilogy(
        d,
        [max(r["model_tangent_n_per_mm"], 1e-6) for r in rows],
        "^--",
        color="#ff7f0e",
        label="model, tangent one 1 kHz tick sees: that slope plus the rate terms of one tick\n"
        "(the dampers' b/dt in series; the viscoelastic arms' instantaneous stiffness where the tissue has them)",
    )
    ax.semilogy(
        d, [r["reference_tangent_n_per_mm"] for r in rows], "k-", lw=2, alpha=0.6, label="large-deformation reference, slope"
    )
    ax.axhline(limits["naive_exact_n_per_mm"], color="r", ls="--", lw=1, label="naive loop limit, 1 kHz (exact, 1-tick delay)")
    ax.axhline(limits["colgate_device_b_n_per_mm"], color="r", ls=":", lw=1, label="Colgate 2b/T, device damping only")
    for p in pts:
        ok = p.naive_stable and p.passivity_stable
        ax.plot(
            p.depth_m * 1e3, max(p.tangent_n_per_m * 1e-3, 1e-6), "s" if ok else "X", color="g" if ok else "r", ms=11, mfc="none"
        )
    held = [p.naive_stable and p.passivity_stable for p in pts]
    for shown, mark, colour, what in (
        (any(held), "s", "g", "held, naive and with passivity"),
        (not all(held), "X", "r", "unstable, naive or with passivity"),
    ):
        if shown:  # a legend entry only for a mark drawn
            ax.plot([], [], mark, color=colour, ms=9, mfc="none", label=LOOP_LABEL + what)
    ax.set_xlabel("press depth, settled (mm)")
    ax.set_ylabel("stiffness -dF_z/dz (N/mm, log)")
    ax.set_title(
        f"Stiffness against depth, {form} form, flat punch at the origin: the model's quasi-static slope, the tangent a\n"
        "1 kHz tick sees (its rate terms b/dt included), the reference's slope, and the 1 kHz loop limits",
        fontsize=9,
    )
    ax.legend(fontsize=7, loc="upper center", bbox_to_anchor=(0.5, -0.13), ncol=1, frameon=False)
    fig.tight_layout()
    path = out / "stiffening.png"
    fig.savefig(path, dpi=110)
    plt.close(fig)
    print(
        f"loop limits at {RATE_HZ:.0f} Hz: naive exact {limits['naive_exact_n_per_mm']:.3f} N/mm, "
        f"Colgate 2b/T (device b) {limits['colgate_device_b_n_per_mm']:.3f} N/mm"
    )
    print("  depth mm | force N | model quasi-static slope N/mm | model 1 kHz tick tangent N/mm | reference slope N/mm")
    for r in rows:
        print(
            f"  {r['depth_mm']:8.2f} | {r['force_n']:7.4f} | {r['model_static_slope_n_per_mm']:29.4f} "
            f"| {r['model_tangent_n_per_mm']:29.4f} | {r['reference_tangent_n_per_mm']:.4f}"
        )
    print("  closed loop (session with force-rate limiter): depth mm | tick tangent N/mm | naive | passivity | max dF/dt N/s")
    for p in pts:
        print(
            f"  {p.depth_m * 1e3:.2f} | {p.tangent_n_per_m * 1e-3:.4f} | {'stable' if p.naive_stable else 'UNSTABLE'} | "
            f"{'stable' if p.passivity_stable else 'UNSTABLE'} | {p.max_force_rate_n_per_s:.1f}"
        )
    return [path]
