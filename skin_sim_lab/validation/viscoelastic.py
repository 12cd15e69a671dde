"""``skin-sim visco``: the layered form's viscoelasticity in time, against the in-vivo data it was chosen for.

Each layer carries quasi-linear viscoelasticity (Fung) with a two-term Prony series,
``G(t) = 1 + g1 exp(-t/tau1) + g2 exp(-t/tau2)`` relative to its equilibrium law
(:func:`skin_sim_node.model.layered_law.prony_prepare`). This module drives the model offline through the
protocols the data come from and prints, for the configured tissue (default preset unless ``--params-file``):

- relaxation under a held indentation (2 mm, pressed at 10 mm/s, held 1 s): the force relaxed and its half time;
- creep under a held force (the force of the press's end held 1 s by a force-controlled tool);
- the rate effect: the peak force of a 2 mm press at 1-200 mm/s over the static force;
- recovery after release (after the 1 s hold): the time to 50 % and 90 % of the surface's return, and the two time
  constants of a two-exponential fit to it (with the part that returns within the first tick);
- passivity: the work of closed press-release cycles from rest back to rest (>= 0).

The data and their provenance: ``docs/data/viscoelastic/`` (sources.md, data.yaml). The verdict checks what the
data fix: two time scales in recovery (the fitted fast one 3-30 ms, the slow one 0.1-1 s; PMID 23604906: about
10 ms and 0.1-1 s), the peak at the fastest press 2-2.75 x the static force (Spartacus et al. 2021), a relaxed
fraction over the 1 s hold between 0.28 and 0.72 (the excised-skin G_inf range of Wang et al. 2015, wider than any
in-vivo bound found), and non-negative cycle work. It exits 1 on a failure.
"""

from __future__ import annotations

import argparse
import sys
from dataclasses import dataclass

import numpy as np

from skin_sim_lab.oracles.physics import press
from skin_sim_lab.validation.methods import static_force_n
from skin_sim_node.model import SkinModel, TissueConfig
from skin_sim_node.model.config import load_tissue_config, preset

DEPTH_M = 2e-3
"""Indentation depth of every protocol (m): mid-range of the validated 0.5-3 mm."""
DT_S = 1e-3
"""Tick (s): the haptic rate."""
HOLD_S = 1.0
"""Hold of the relaxation and creep protocols (s): the issue's 1 s hold."""
PRESS_SPEED_M_S = 0.01
"""Press speed before the hold (m/s): 10 mm/s, a moderate hand speed."""
RATE_SPEEDS_M_S = (1e-3, 1e-2, 1e-1, 2e-1)
"""Press speeds of the rate effect (m/s)."""
RATE_BAND = (2.0, 2.75)
"""Peak over quasi-static force at high rate, in vivo (Spartacus et al. 2021, PLOS ONE 16:e0261008)."""
RELAXED_BAND = (0.28, 0.72)
"""Fraction relaxed over the hold: 1 - G_inf of the excised-skin QLV fits (0.28-0.47: 0.53-0.72 relaxed at steady
state, Wang et al. 2015) as the upper end; 0.28 as the lower: the smallest G_inf-derived fraction reported."""


@dataclass(frozen=True)
class Figures:
    """What :func:`measure` prints (SI units)."""

    static_force_n: float
    relax_peak_n: float
    relax_end_n: float
    relaxed_fraction: float
    relax_half_time_s: float
    creep_start_m: float
    creep_end_m: float
    peak_over_static: tuple[float, ...]
    recover_50_s: float
    recover_90_s: float
    recover_tau_fast_s: float
    recover_tau_slow_s: float
    recover_instant: float
    cycle_work_j: float


def _press(m: SkinModel, speed: float, depth: float = DEPTH_M) -> list[float]:
    """The forces of :func:`~skin_sim_lab.oracles.physics.press` at the centre, tick by tick (N)."""
    forces: list[float] = []
    press(m, 0.0, 0.0, depth, speed, DT_S, on_tick=forces.append)
    return forces


def static_force(cfg: TissueConfig, depth: float = DEPTH_M) -> float:
    """Equilibrium force (N): :func:`~skin_sim_lab.validation.methods.static_force_n` at the centre."""
    return static_force_n(SkinModel(cfg), 0.0, 0.0, depth)


def relaxation_and_recovery(cfg: TissueConfig) -> tuple[float, float, float, float, float, float, np.ndarray]:
    """Press, hold, release: peak (N), end-of-hold force (N), relaxation half time (s), 50 % / 90 % recovery (s),
    the surface depth at the end of the hold (m), and the surface after release over 3 s (per tick, m)."""
    m = SkinModel(cfg)
    peak = _press(m, PRESS_SPEED_M_S)[-1]
    hold = np.array([m.step((0.0, 0.0, -DEPTH_M), (0.0, 0.0, 0.0), DT_S) for _ in range(int(HOLD_S / DT_S))])
    half = float(np.argmax(hold <= hold[-1] + 0.5 * (peak - hold[-1])) + 1) * DT_S
    s0 = m.surface_displacement_at(0.0, 0.0)
    surf = []
    for _ in range(int(3.0 / DT_S)):
        m.step((0.0, 0.0, 5e-3), (0.0, 0.0, 0.0), DT_S)
        surf.append(m.surface_displacement_at(0.0, 0.0))
    s = np.array(surf)

    def t_frac(frac: float) -> float:
        hit = np.flatnonzero(s <= s0 * (1.0 - frac))
        return float(hit[0] + 1) * DT_S if hit.size else float("inf")

    return peak, float(hold[-1]), half, t_frac(0.5), t_frac(0.9), s0, s


def recovery_time_constants(surface_m: np.ndarray, s0_m: float) -> tuple[float, float, float]:
    """Fit ``u(t) / u0 = A exp(-t / tau_f) + B exp(-t / tau_s)`` to the recovering surface (ticks of :data:`DT_S`
    after release); returns ``(tau_f, tau_s, 1 - A - B)``: the two time constants (s) and the part that returned at
    once (within the first tick, at the Kelvin-Voigt rate)."""
    from scipy.optimize import curve_fit

    t = np.arange(1, surface_m.size + 1) * DT_S
    y = surface_m / s0_m

    def model(t, a, tf, b, ts):
        return a * np.exp(-t / tf) + b * np.exp(-t / ts)

    (a, tf, b, ts), _ = curve_fit(model, t, y, p0=(0.3, 0.01, 0.5, 0.3), bounds=([0, 1e-4, 0, 1e-3], [1, 1, 1, 100]))
    if tf > ts:
        a, tf, b, ts = b, ts, a, tf
    return float(tf), float(ts), float(1.0 - a - b)


def creep(cfg: TissueConfig) -> tuple[float, float]:
    """Depth (m) at the start and end of a 1 s hold at the force the press ended with (a force-controlled tool:
    each tick's depth found by bisection on a copy of the state)."""
    m = SkinModel(cfg)
    target = _press(m, PRESS_SPEED_M_S)[-1]
    depth = start = DEPTH_M
    for _ in range(int(HOLD_S / DT_S)):
        state = m.state()
        lo, hi = depth, depth + 1e-3
        for _ in range(40):
            mid = 0.5 * (lo + hi)
            m.set_state(state)
            if m.step((0.0, 0.0, -mid), (0.0, 0.0, 0.0), DT_S) < target:
                lo = mid
            else:
                hi = mid
        m.set_state(state)
        depth = 0.5 * (lo + hi)
        m.step((0.0, 0.0, -depth), (0.0, 0.0, 0.0), DT_S)
    return start, depth


def cycle_work(cfg: TissueConfig, cycles: int = 3, speed: float = 0.05) -> float:
    """Work (J) the tool does over press-release cycles from rest to 2 mm and back to the surface, where the force
    is zero: what is left stored in the tissue is >= 0, so the work is >= 0 for a passive model."""
    m = SkinModel(cfg)
    work, d_prev = 0.0, 0.0
    n = round(DEPTH_M / (speed * DT_S))
    path = [DEPTH_M * (i + 1) / n for i in range(n)] + [DEPTH_M * (n - 1 - i) / n for i in range(n)]
    for _ in range(cycles):
        for d in path:
            f = m.step((0.0, 0.0, -d), (0.0, 0.0, 0.0), DT_S)
            work += f * (d - d_prev)
            d_prev = d
    return work


def measure(cfg: TissueConfig) -> Figures:
    """Every figure of this module for ``cfg``."""
    f_static = static_force(cfg)
    peak, end, half, r50, r90, s0, surf = relaxation_and_recovery(cfg)
    tf, ts, inst = recovery_time_constants(surf, s0)
    c0, c1 = creep(cfg)
    ratios = tuple(max(_press(SkinModel(cfg), v)) / f_static for v in RATE_SPEEDS_M_S)
    return Figures(f_static, peak, end, 1.0 - end / peak, half, c0, c1, ratios, r50, r90, tf, ts, inst, cycle_work(cfg))


def verdict(fig: Figures) -> list[tuple[str, bool]]:
    """Each check of the module docstring: (what, passed)."""
    fast = fig.peak_over_static[-1]
    return [
        (
            f"recovery: a fast time constant of 3-30 ms ({fig.recover_tau_fast_s * 1e3:.1f} ms)",
            0.003 <= fig.recover_tau_fast_s <= 0.03,
        ),
        (
            f"recovery: a slow time constant of 0.1-1 s ({fig.recover_tau_slow_s:.2f} s)",
            0.1 <= fig.recover_tau_slow_s <= 1.0,
        ),
        (
            f"rate: peak at {RATE_SPEEDS_M_S[-1] * 1e3:.0f} mm/s is {RATE_BAND[0]}-{RATE_BAND[1]} x static ({fast:.2f})",
            RATE_BAND[0] <= fast <= RATE_BAND[1],
        ),
        (
            f"relaxed over the {HOLD_S:.0f} s hold in {RELAXED_BAND} ({fig.relaxed_fraction:.2f})",
            RELAXED_BAND[0] <= fig.relaxed_fraction <= RELAXED_BAND[1],
        ),
        (
            f"creep under the held force (+{(fig.creep_end_m - fig.creep_start_m) * 1e6:.0f} um)",
            fig.creep_end_m > fig.creep_start_m,
        ),
        (f"closed cycles dissipate ({fig.cycle_work_j * 1e6:.1f} uJ >= 0)", fig.cycle_work_j >= 0.0),
    ]


def main(argv: list[str] | None = None) -> int:
    """Print the figures and the verdict; exit 1 on a failed check."""
    ap = argparse.ArgumentParser(prog="skin-sim visco", description=__doc__.split("\n\n")[0])
    ap.add_argument("--params-file", help="a ros__parameters YAML (default: the default preset)")
    args = ap.parse_args(argv)
    cfg = load_tissue_config(args.params_file) if args.params_file else preset("default")
    ve = cfg.viscoelastic
    print(
        f"visco: G(t) = 1 + {ve.g1:g} exp(-t/{ve.tau1_s * 1e3:g} ms) + {ve.g2:g} exp(-t/{ve.tau2_s:g} s); "
        f"{DEPTH_M * 1e3:g} mm, flat punch at the centre (~3 s)",
        flush=True,
    )
    fig = measure(cfg)
    print(f"static force at {DEPTH_M * 1e3:g} mm: {fig.static_force_n:.4f} N")
    print(
        f"relaxation: peak {fig.relax_peak_n:.4f} N after a {PRESS_SPEED_M_S * 1e3:g} mm/s press, {fig.relax_end_n:.4f} N "
        f"after {HOLD_S:g} s: {fig.relaxed_fraction * 100:.1f} % relaxed, half of it in {fig.relax_half_time_s * 1e3:.0f} ms"
    )
    print(f"creep: depth {fig.creep_start_m * 1e3:.4f} -> {fig.creep_end_m * 1e3:.4f} mm over {HOLD_S:g} s at the held force")
    print(
        "rate: peak / static at " + ", ".join(f"{v * 1e3:g} mm/s {r:.2f}" for v, r in zip(RATE_SPEEDS_M_S, fig.peak_over_static))
    )
    print(
        f"recovery after the hold: 50 % in {fig.recover_50_s * 1e3:.0f} ms, 90 % in {fig.recover_90_s * 1e3:.0f} ms; "
        f"fit: {fig.recover_instant * 100:.0f} % at once, then tau {fig.recover_tau_fast_s * 1e3:.1f} ms and "
        f"{fig.recover_tau_slow_s:.2f} s"
    )
    print(f"closed press-release cycles: work {fig.cycle_work_j * 1e6:.2f} uJ")
    checks = verdict(fig)
    failed = [what for what, ok in checks if not ok]
    for what, ok in checks:
        print(f"  {'ok  ' if ok else 'FAIL'} {what}")
    print(f"visco {'FAIL' if failed else 'PASS'}: " + ("; ".join(failed) if failed else f"{len(checks)} checks"))
    return 1 if failed else 0


if __name__ == "__main__":
    sys.exit(main())
