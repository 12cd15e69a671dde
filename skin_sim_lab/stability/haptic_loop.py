"""Haptic-loop stability: the simulated Touch against a rendered stiffness, swept in-process.

The loop is the product's: the pure :class:`skin_sim_node.device.stylus.SimulatedDevice` (45 g stylus,
hand spring and damper) reports its pose, the environment answers a force, and the device applies
it one tick late with a zero-order hold (``delay_ticks`` in total, >= 1). The stylus and hand are
integrated in 50 us substeps, so they behave as continuous physics and only the loop is sampled.

Environments: :class:`Wall` (a unilateral linear spring of stiffness ``K``: the classic virtual wall)
and :class:`TissueEnv` (the skin model behind :class:`skin_sim_node.session.HapticSession`).

The hand presses the stylus onto the environment and holds (:func:`hold_path`). A run is
**unstable** when the force does not settle (it limit-cycles, or the stylus bounces off) or the
oscillation grows; see :func:`classify`. Theory: Colgate & Brown (1994) passivity of a sampled
wall, ``b > K T / 2``, and the exact spectral radius of the sampled linear loop
(:func:`linear_loop_radius`).

``skin-sim stability-loop`` prints the sweep (``main``).
"""

from __future__ import annotations

import argparse
import math
from collections import deque
from dataclasses import dataclass, replace

import numpy as np
from tqdm import tqdm

from skin_sim_node.device.stylus import DeviceParams, SimulatedDevice
from skin_sim_node.device.trajectories import LIFT_Z_M, Trajectory

SUBSTEP_S = 50e-6
"""Stylus integration substep: omega * h = 0.017 at 5 N/mm (omega = sqrt(5300 / 0.045) = 343 rad/s)."""
HOLD_FORCE_N = 0.5
"""Force the hand aims to hold: well inside the Touch's 3.3 N so saturation does not hide growth."""
RAMP_S, HOLD_S = 0.3, 1.2
EARLY = (0.3, 0.6)  # windows into the hold (s after the ramp): decay is judged between them
LATE = (0.9, 1.2)
SETTLED_FRACTION = 0.02
"""A run has settled when the force's std over the late window is below 2 % of the hold force (10 mN),
well under the ~7 % just-noticeable difference of force (Jones 1989, Exp Brain Res 77:211)."""
DECAY_RATIO = 0.7
"""Not settled but decaying: late std below 0.7 x early std (a decay time under 1.7 s between the windows)."""
STIFFNESSES_N_PER_M = tuple(float(k) for k in np.geomspace(100.0, 5000.0, 12))  # 0.1 .. 5 N/mm
RATES_HZ = (100.0, 150.0, 250.0, 400.0, 600.0, 1000.0, 1600.0, 2500.0, 4000.0)


# --- environments ---------------------------------------------------------------------------
class Wall:
    """A unilateral linear spring at z = 0: ``F = K max(0, -z)`` along +z (no rendered damping)."""

    def __init__(self, stiffness_n_per_m: float):
        self.k = float(stiffness_n_per_m)

    def force(self, t_s: float, pos, vel, dt: float) -> float:
        """Normal force of the linear wall at ``pos`` (N): ``k`` times the depth below z = 0."""
        return self.k * max(0.0, -pos[2])


class TissueEnv:
    """The skin model through the haptic session (input checks, velocity, force limits), as the node runs it."""

    def __init__(self, cfg, session_params=None):
        from skin_sim_node.session import HapticSession, SessionParams
        from skin_sim_node.tools import make_tool

        self.session = HapticSession(make_tool(cfg), session_params or SessionParams(max_stamp_age_s=0.0))

    def force(self, t_s: float, pos, vel, dt: float) -> float:
        """Normal force of the haptic session at ``pos``, ``vel`` for a tick of ``dt`` (N): pose and twist in, one tick."""
        stamp = int(round(t_s * 1e9)) + 1
        self.session.on_twist(stamp, "tissue", vel)
        self.session.on_pose(stamp, "tissue", pos)
        return self.session.tick(stamp, int(round(dt * 1e9))).force_z_n


# --- the loop -------------------------------------------------------------------------------
def hold_path(depth_m: float, hand_stiffness_n_per_m: float, force_n: float = HOLD_FORCE_N) -> Trajectory:
    """Hand ramps from lifted to where a stylus at ``depth_m`` carries ``force_n`` on the hand spring, then holds."""
    z_h = -depth_m - force_n / hand_stiffness_n_per_m
    return Trajectory("hold", (0.0, 0.0, LIFT_Z_M), ((RAMP_S, (0.0, 0.0, z_h)), (HOLD_S, (0.0, 0.0, z_h))))


@dataclass
class Trace:
    """One closed-loop run, per tick: time, stylus height, environment force, applied force; and its rate."""

    t_s: np.ndarray
    z_m: np.ndarray  # stylus tip height (tissue frame) at each tick
    force_n: np.ndarray  # environment force computed at each tick
    applied_n: np.ndarray  # z force the device applied over the tick (incl. the stabiliser)
    rate_hz: float


def run_loop(env, rate_hz: float, path: Trajectory, stabiliser: str = "none", delay_ticks: int = 1, device=None) -> Trace:
    """Close the loop for ``path.duration_s``: sample, answer, apply ``delay_ticks`` late with a ZOH."""
    params = replace(device or DeviceParams(), substep_s=SUBSTEP_S, stabiliser=stabiliser, delay_ticks=1)
    dev = SimulatedDevice(path, params)
    T = 1.0 / rate_hz
    n = int(round(path.duration_s / T))
    fifo = deque([0.0] * (delay_ticks - 1))  # extra ticks of delay beyond the device's one
    t, z, f, fa = np.empty(n), np.empty(n), np.empty(n), np.empty(n)
    for k in range(n):
        p, v = dev.pos_tissue, dev.vel_tissue
        fz = env.force(k * T, p, v, T)
        fifo.append(fz)
        dev.step(dev.mapping.force_to_device((0.0, 0.0, fifo.popleft())), T)
        t[k], z[k], f[k], fa[k] = k * T, p[2], fz, dev.mapping.velocity_to_tissue(dev.applied_force_n)[2]
    return Trace(t, z, f, fa, rate_hz)


@dataclass(frozen=True)
class Verdict:
    """Stability verdict of one run: stable or not, the kind, the force std early and late, the late mean and energy."""

    stable: bool
    kind: str  # settled | decaying | limit cycle | growing
    std_early_n: float
    std_late_n: float
    mean_late_n: float
    energy_late_j: float  # net work of the applied force on the stylus over the late window (> 0: energy put in)


def verdict_kind(std_early_n: float, std_late_n: float, scale_n: float) -> str:
    """Classify a force trace from its std early and late in the hold, against a force scale (N)."""
    if std_late_n <= SETTLED_FRACTION * scale_n:
        return "settled"
    if std_late_n < DECAY_RATIO * std_early_n:
        return "decaying"
    if std_late_n > 1.5 * std_early_n:
        return "growing"
    return "limit cycle"


def classify(tr: Trace, force_n: float = HOLD_FORCE_N) -> Verdict:
    """Unstable when the force neither settles nor decays, or grows (see the module docstring)."""

    def win(w):
        return (tr.t_s >= RAMP_S + w[0]) & (tr.t_s < RAMP_S + w[1])

    e, la = win(EARLY), win(LATE)
    s_e, s_l = float(tr.force_n[e].std()), float(tr.force_n[la].std())
    idx = np.flatnonzero(la)
    dz = np.diff(tr.z_m[idx[0] : idx[-1] + 2])
    energy = float(np.sum(tr.applied_n[idx[0] : idx[0] + dz.size] * dz))
    kind = "growing" if not np.all(np.isfinite(tr.force_n)) else verdict_kind(s_e, s_l, force_n)
    return Verdict(kind in ("settled", "decaying"), kind, s_e, s_l, float(tr.force_n[la].mean()), energy)


def wall_point(k_n_per_m: float, rate_hz: float, stabiliser: str = "none", delay_ticks: int = 1) -> Verdict:
    """One sweep point: the default hand holds the stylus on a wall of stiffness ``k`` at ``rate_hz``."""
    dev = DeviceParams()
    path = hold_path(HOLD_FORCE_N / k_n_per_m, dev.hand_stiffness_n_per_m)
    return classify(run_loop(Wall(k_n_per_m), rate_hz, path, stabiliser, delay_ticks))


def sweep(
    stiffnesses=STIFFNESSES_N_PER_M,
    rates=RATES_HZ,
    stabilisers=("none", "passivity"),
    delay_ticks: int = 1,
    progress: bool = True,
):
    """All wall points: ``{(stabiliser, rate_hz, k): Verdict}`` (a tqdm bar over the points)."""
    keys = [(s, r, k) for s in stabilisers for r in rates for k in stiffnesses]
    return {
        key: wall_point(key[2], key[1], key[0], delay_ticks)
        for key in tqdm(keys, desc="wall sweep (stabiliser x rate x K)", disable=not progress, leave=False)
    }


def boundary(results, stabiliser: str, rate_hz: float, stiffnesses=STIFFNESSES_N_PER_M) -> float:
    """Largest swept stiffness below which every point is stable (nan if the smallest is unstable)."""
    best = math.nan
    for k in sorted(stiffnesses):
        if not results[(stabiliser, rate_hz, k)].stable:
            break
        best = k
    return best


def largest_stable(rate_hz: float, stabiliser: str, lo: float, hi: float, iters: int = 8, delay_ticks: int = 1) -> float:
    """Bisect (geometrically) for the stability boundary in stiffness, given ``lo`` stable and ``hi`` unstable."""
    for _ in range(iters):
        mid = math.sqrt(lo * hi)
        if wall_point(mid, rate_hz, stabiliser, delay_ticks).stable:
            lo = mid
        else:
            hi = mid
    return lo


# --- transparency -----------------------------------------------------------------------------
def rendered_stiffness(k_n_per_m: float, rate_hz: float, stabiliser: str, amp_m: float = 0.2e-3, freq_hz: float = 5.0):
    """Stiffness and damping the user feels: the hand wobbles the held stylus at ``freq_hz``; fit ``F = K z + B v + c``.

    Returns ``(K_rendered, B_rendered)`` in N/m and N*s/m over the last 0.6 s of 1.2 s of wobble.
    """
    dev = DeviceParams()
    d = HOLD_FORCE_N / k_n_per_m
    z_h = -d - HOLD_FORCE_N / dev.hand_stiffness_n_per_m
    half = 0.5 / freq_hz
    segs = [(RAMP_S, (0.0, 0.0, z_h)), (0.3, (0.0, 0.0, z_h))]
    segs += [(half, (0.0, 0.0, z_h + (amp_m if i % 2 else -amp_m))) for i in range(int(1.2 / half))]
    tr = run_loop(Wall(k_n_per_m), rate_hz, Trajectory("wobble", (0.0, 0.0, LIFT_Z_M), tuple(segs)), stabiliser)
    sel = tr.t_s > tr.t_s[-1] - 0.6
    z, f = tr.z_m[sel], tr.applied_n[sel]
    v = np.gradient(z, tr.t_s[sel])
    A = np.column_stack([-z, -v, np.ones_like(z)])
    (kr, br, _), *_ = np.linalg.lstsq(A, f, rcond=None)
    return float(kr), float(br)


# --- theory -----------------------------------------------------------------------------------
def colgate_k_max(b_n_s_per_m: float, rate_hz: float) -> float:
    """Colgate & Brown (1994): a sampled virtual wall is passive iff ``b > K T / 2``, i.e. ``K < 2 b / T``."""
    return 2.0 * b_n_s_per_m * rate_hz


def linear_loop_radius(k_n_per_m: float, rate_hz: float, delay_ticks: int = 1, device: DeviceParams | None = None) -> float:
    """Spectral radius of the sampled loop, linearised in contact: < 1 is asymptotically stable.

    Continuous stylus on the hand (``m x'' = -K_h x - (B_h + b) x' + u``), exactly discretised with a
    zero-order hold over ``T``; ``u_k = -K x_{k - delay_ticks}``.
    """
    from scipy.linalg import expm

    p = device or DeviceParams()
    m, T = p.mass_kg, 1.0 / rate_hz
    a = np.array([[0.0, 1.0], [-p.hand_stiffness_n_per_m / m, -(p.hand_damping_n_s_per_m + p.damping_n_s_per_m) / m]])
    aug = np.zeros((3, 3))
    aug[:2, :2], aug[1, 2] = a, 1.0 / m
    e = expm(aug * T)
    phi, gam = e[:2, :2], e[:2, 2]
    n = 2 + delay_ticks  # state: x_k, v_k, x_{k-1}, ..., x_{k-d}
    M = np.zeros((n, n))
    M[:2, :2] = phi
    M[:2, 1 + delay_ticks] += -k_n_per_m * gam
    if delay_ticks >= 1:
        M[2, 0] = 1.0
        for i in range(3, n):
            M[i, i - 1] = 1.0
    return float(np.max(np.abs(np.linalg.eigvals(M))))


def linear_k_max(rate_hz: float, delay_ticks: int = 1, device: DeviceParams | None = None) -> float:
    """Largest ``K`` with :func:`linear_loop_radius` < 1 (bisection in log K from 1 N/m to 1e6 N/m)."""
    lo, hi = 1.0, 1e6
    if linear_loop_radius(hi, rate_hz, delay_ticks, device) < 1.0:
        return hi
    for _ in range(60):
        mid = math.sqrt(lo * hi)
        if linear_loop_radius(mid, rate_hz, delay_ticks, device) < 1.0:
            lo = mid
        else:
            hi = mid
    return lo


def main(argv=None) -> int:
    """Print the naive and stabilised wall sweep and the theory lines."""
    ap = argparse.ArgumentParser(prog="skin-sim stability-loop", description=__doc__.splitlines()[0])
    ap.add_argument("--rates", type=float, nargs="*", default=list(RATES_HZ))
    ap.add_argument("--delay-ticks", type=int, default=1)
    args = ap.parse_args(argv)
    n_pts = 2 * len(args.rates) * len(STIFFNESSES_N_PER_M)
    print(
        f"stability-loop: {n_pts} closed-loop runs (naive and passivity, {len(args.rates)} rates x "
        f"{len(STIFFNESSES_N_PER_M)} stiffnesses), about {0.2 * n_pts:.0f}-{0.35 * n_pts:.0f} s on 2 cores "
        "(0.2-0.35 s a run: 216 runs took 74 s beside other work, 2026-12-02)",
        flush=True,
    )
    p = DeviceParams()
    b_dev, b_all = p.damping_n_s_per_m, p.damping_n_s_per_m + p.hand_damping_n_s_per_m
    res = sweep(rates=args.rates, delay_ticks=args.delay_ticks)
    print(f"wall sweep, hold {HOLD_FORCE_N} N, delay {args.delay_ticks} tick(s) + ZOH; K in N/mm")
    print("  rate Hz | naive K_max | passivity K_max | Colgate 2b/T b=dev | b=dev+hand | exact linear")
    for r in args.rates:
        print(
            f"  {r:7.0f} | {boundary(res, 'none', r) * 1e-3:11.3f} | {boundary(res, 'passivity', r) * 1e-3:15.3f} | "
            f"{colgate_k_max(b_dev, r) * 1e-3:18.3f} | {colgate_k_max(b_all, r) * 1e-3:10.3f} | "
            f"{linear_k_max(r, args.delay_ticks) * 1e-3:12.3f}"
        )
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
