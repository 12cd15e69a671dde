"""The needle at an angle and on the way out (issue 31): puncture force, tip travel and the force's angle to the axis
for 21 G at 90, 60, 45, 30 and 15 degrees to the skin; the tent's energy around closed loops; the axial force over the
first 1 mm of a withdrawal and the energy of an insert-withdraw cycle; the tip travel at puncture for 18-27 G against
the band of an in-vivo skin stiffness.

``skin-sim needle-angle`` (deterministic, the model alone at 1 um steps, and the loops through the tool and the
session); exits 1 when a check fails.

The law (docs/needle.md, "Oblique insertion"): before the skin gives, the tented skin answers the tip with its normal
reaction ``N`` (+z, from the tip's normal depth) and the presliding friction of the tip on it, ``f_t = -k_t (p - a)``
along the surface capped at ``mu N`` (the anchor ``a`` dragged beyond); the skin ruptures when ``N`` reaches
``F_p = lambda Gamma d``. Table 1 is a **regression check of the code against its own law** (the normal reaction at
the peak is ``F_p`` at every angle, the tangential force at most ``mu N``, the force's angle to the axis
``90 - theta - atan(f_t / N)``): it confirms the implementation, not the physics. Table 2 is the physics' own check:
the tent is passive, so no closed loop of the tip returns energy to the hand.
"""

from __future__ import annotations

import argparse
import math

import numpy as np

from skin_sim_node.model.config import preset
from skin_sim_node.model.needle import NeedleModel, NeedleParams

ANGLES_DEG = (90.0, 60.0, 45.0, 30.0, 15.0)
LOOP_ANGLES_DEG = (70.0, 45.0, 30.0)
LOOP_SIZE_M = (1.0e-3, 1.15e-3)
"""The closed loops' rectangle in x-z (sideways, down; m): the review's, from a tip pressed 0.3 mm normal into the
skin along its axis (nothing ruptures)."""
LOOP_START_DEPTH_M = 0.3e-3
LOOP_TOLERANCE_J = 1e-9
"""Net energy a loop may return to the hand (J): rounding (a loop of the trapezoid rule on a potential closes to
~1e-12 J; the session books each tick's force over the next 1 um move, an explicit rule whose error is of the order
``k dx^2`` per tick, ~1e-10 J over a loop)."""
STEP_M = 1e-6
"""Axial step of the scans (m)."""
FLYNN_STIFFNESS_N_PER_MM = (0.44, 1.45)
"""In-vivo skin, right anterior forearm: "the ratio of the maximum probe reaction force to maximum probe displacement
ranged from 0.44 N/mm to 1.45 N/mm" (Flynn, Taberner & Nielsen 2011, Med Eng Phys 33(5):610-619, abstract; a 3D probe
of its own size, not a needle: a band for the tent's secant stiffness, not a calibration)."""


def _axis(deg: float) -> np.ndarray:
    th = math.radians(deg)
    return np.array([math.cos(th), 0.0, -math.sin(th)])


def puncture(cfg, deg: float, gauge: int = 21) -> dict:
    """Insert along the axis at ``deg`` to the surface until the skin (dermis) ruptures: the peak before it."""
    u = _axis(deg)
    m = NeedleModel(cfg, NeedleParams.gauge(gauge))
    best = None
    s = -0.2e-3
    while s < 30e-3:
        p = s * u
        t = m.step(p, u)
        if m.ruptured >= 2:
            break
        if best is None or t.axial_n > best[0].axial_n:
            best = (t, p, t.tangential_n >= (1.0 - 1e-9) * m.params.tip_friction * t.normal_n > 0.0)
        s += STEP_M
    assert best is not None
    t, p, skating = best
    f = t.force_n
    angle = math.degrees(math.acos(min(1.0, -float(f @ u) / float(np.linalg.norm(f)))))
    th = math.radians(deg)
    pr = m.params
    c = t.tangential_n / t.normal_n if t.normal_n > 0.0 else 0.0
    fp = pr.puncture_force_n(1)
    return {
        "deg": deg,
        "axial_n": t.axial_n,
        "dimple_n": t.dimple_n,
        "magnitude_n": float(np.linalg.norm(f)),
        "normal_n": t.normal_n,
        "tangential_n": t.tangential_n,
        "travel_m": t.insertion_m,
        "vertical_m": -float(p[2]),
        "sideways_m": float(math.hypot(p[0], p[1])),
        "angle_deg": angle,
        "skate": skating,
        "predicted_normal_n": fp,
        "predicted_axial_n": t.normal_n * (math.sin(th) + c * math.cos(th)),
        "predicted_angle_deg": 90.0 - deg - math.degrees(math.atan(c)) if deg < 90.0 else 0.0,
        "friction_within_cap": t.tangential_n <= (1.0 + 1e-9) * pr.tip_friction * t.normal_n,
        "fp_n": fp,
    }


def withdrawal(cfg, gauge: int = 21, depth_m: float = 4.5e-3) -> dict:
    """Vertical, through every layer to ``depth_m`` (5 mm/s at 1 kHz is 5 um a tick; here 1 um steps), then out: the
    axial force over the first 1 mm back, the distance and energy of the outward push, and the cycle's energy (the
    tissue's work on the needle, trapezoid rule)."""
    m = NeedleModel(cfg, NeedleParams.gauge(gauge))
    n_in = int(round((depth_m + 0.2e-3) / STEP_M))
    zs_in = np.linspace(0.2e-3, -depth_m, n_in + 1)
    zs_out = np.linspace(-depth_m, 0.3e-3, int(round((depth_m + 0.3e-3) / STEP_M)) + 1)[1:]
    work, f_prev, z_prev = 0.0, 0.0, zs_in[0]
    back, returned, push_end = [], 0.0, 0.0
    for i, z in enumerate(np.concatenate([zs_in, zs_out])):
        t = m.step((0.0, 0.0, float(z)), (0.0, 0.0, -1.0))
        d_ins = z_prev - z  # insertion step
        work -= 0.5 * (f_prev + t.axial_n) * d_ins
        if i >= len(zs_in):
            dist = float(z) + depth_m
            seg = 0.5 * (f_prev + t.axial_n) * -d_ins
            if seg > 0.0:
                returned += seg
            if t.axial_n > 0.0:
                push_end = dist
            if dist <= 1.0e-3 + 1e-12 and (not back or dist > 0.0):
                back.append((dist, t.axial_n, t.cutting_n, t.friction_n))
        f_prev, z_prev = t.axial_n, z
    return {"back": back, "returned_j": returned, "push_m": push_end, "cycle_j": work, "params": m.params}


def _loop_tips(deg: float, reverse: bool, step_m: float = STEP_M):
    """The way in along the axis to the loop's start, and one loop (rectangle in x-z, :data:`LOOP_SIZE_M`) from it."""
    u = _axis(deg)
    s0 = LOOP_START_DEPTH_M / math.sin(math.radians(deg))
    way_in = [s * u for s in np.arange(-0.2e-3, s0 + 0.5 * step_m, step_m)]
    a = way_in[-1]
    dx, dz = LOOP_SIZE_M
    b, c, d = a + (dx, 0.0, 0.0), a + (dx, 0.0, -dz), a + (0.0, 0.0, -dz)
    corners = [a, d, c, b, a] if reverse else [a, b, c, d, a]
    loop = []
    for p, q in zip(corners[:-1], corners[1:]):
        n = int(round(float(np.linalg.norm(q - p)) / step_m))
        loop += [p + (q - p) * (i / n) for i in range(1, n + 1)]
    return u, way_in, loop


def loop_energy(cfg, deg: float, reverse: bool, via: str = "model", cycles: int = 3, gauge: int = 21) -> list[float]:
    """Net energy (J) each closed loop returns to the hand (the tissue's work on the needle; > 0: the hand gains), the
    needle at ``deg`` to the skin, through the model (trapezoid rule), the tool (:func:`~skin_sim_node.tools.make_tool`,
    trapezoid) or the session (:class:`~skin_sim_node.session.haptic.HapticSession` at 1 kHz, each published force
    held over the next move, as a device renders it)."""
    from msgs_schema.parameters import SessionParams
    from skin_sim_node.device.trajectories import needle_orientation
    from skin_sim_node.session.haptic import HapticSession
    from skin_sim_node.tools import make_tool
    from skin_sim_node.tools.base import ToolPose

    u, way_in, loop = _loop_tips(deg, reverse)
    ax = tuple(float(c) for c in u)
    tcfg = cfg.replace(**{"tool.shape": "needle", "needle.outer_diameter_m": NeedleParams.gauge(gauge).outer_diameter_m})
    if via == "model":
        m = NeedleModel(cfg, NeedleParams.gauge(gauge))

        def force(p):
            return m.step(p, u).force_n

        def ruptured():
            return m.ruptured
    elif via == "tool":
        tool = make_tool(tcfg)

        def force(p):
            pose = ToolPose(tuple(float(c) for c in p), (0.0, 0.0, 0.0), ax, 1e-3, False)
            return np.asarray(tool.step(pose).force_n, dtype=float)

        def ruptured():
            return tool.needle.ruptured  # type: ignore[attr-defined]
    else:
        session = HapticSession(make_tool(tcfg), SessionParams())
        quat = needle_orientation(math.radians(deg))
        clock = [0]

        def force(p):
            clock[0] += 1_000_000
            session.on_pose(clock[0], "tissue", tuple(float(c) for c in p), quat=quat)
            return np.asarray(session.tick(clock[0], 1_000_000).force_n, dtype=float)

        def ruptured():
            return session.tool.needle.ruptured  # type: ignore[attr-defined]

    for p in way_in:
        f_prev = force(p)
    p_prev = way_in[-1]
    works = []
    for _ in range(cycles):
        work = 0.0
        for p in loop:
            f = force(p)
            dp = p - p_prev
            work += float((f_prev if via == "session" else 0.5 * (f_prev + f)) @ dp)
            f_prev, p_prev = f, p
        works.append(work)
    if ruptured():
        raise RuntimeError(f"the loop at {deg} deg ruptured a layer: not a tent's loop")
    return works


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(prog="skin-sim needle-angle", description=__doc__.splitlines()[0])
    ap.parse_args(argv)
    cfg = preset("default")
    fails = []
    pr = NeedleParams.gauge(21)
    print(
        f"1. 21 G puncture against the angle (mu {pr.tip_friction}, kappa {pr.tent_shear_ratio:.3f};"
        f" F_p {pr.puncture_force_n(1):.3f} N on the normal reaction N). REGRESSION CHECK of the code against its own law,"
        " not a validation:"
    )
    print(
        "   angle  axial (N) [tent's: law]  |F| (N)  N (N) [F_p]  f_t (N)  f_t/N  travel axis (mm)  vertical (mm)  sideways (mm)"
        "  force to axis (deg) [law]  skate"
    )
    for deg in ANGLES_DEG:
        r = puncture(cfg, deg)
        sk = "yes" if r["skate"] else "no"
        print(
            f"   {deg:5.0f}  {r['axial_n']:9.3f} [{r['dimple_n']:5.3f}: {r['predicted_axial_n']:5.3f}]  {r['magnitude_n']:7.3f}"
            f"  {r['normal_n']:5.3f} [{r['predicted_normal_n']:5.3f}]  {r['tangential_n']:7.3f}"
            f"  {r['tangential_n'] / r['normal_n']:5.3f}  {r['travel_m'] * 1e3:16.2f}  {r['vertical_m'] * 1e3:13.2f}"
            f"  {r['sideways_m'] * 1e3:13.2f}  {r['angle_deg']:18.1f} [{r['predicted_angle_deg']:4.1f}]  {sk:>5}"
        )
        if abs(r["dimple_n"] / r["predicted_axial_n"] - 1.0) > 1e-9 or abs(r["normal_n"] / r["predicted_normal_n"] - 1.0) > 2e-3:
            fails.append(f"{deg:.0f} deg: force off the law")
        if abs(r["angle_deg"] - r["predicted_angle_deg"]) > 0.1 or not r["friction_within_cap"]:
            fails.append(f"{deg:.0f} deg: angle off the law or friction above mu N")

    print(
        f"\n2. the tent is passive: net energy a closed {LOOP_SIZE_M[0] * 1e3:g} x {LOOP_SIZE_M[1] * 1e3:g} mm loop in x-z"
        f" returns to the hand (uJ per cycle, 3 cycles; > {LOOP_TOLERANCE_J * 1e6:g} uJ fails), 21 G from"
        f" {LOOP_START_DEPTH_M * 1e3:g} mm normal depth, nothing ruptured"
    )
    print("   angle  direction    model (uJ)             tool, make_tool (uJ)   session, 1 kHz (uJ)")
    for deg in LOOP_ANGLES_DEG:
        for reverse in (False, True):
            row = []
            for via in ("model", "tool", "session"):
                works = loop_energy(cfg, deg, reverse, via)
                row.append(works)
                if max(works) > LOOP_TOLERANCE_J:
                    fails.append(f"loop {deg:.0f} deg {'ccw' if reverse else 'cw'} via {via}: returns {max(works) * 1e6:.3g} uJ")
            cells = "  ".join(" ".join(f"{w * 1e6:6.1f}" for w in works) for works in row)
            print(f"   {deg:5.0f}  {'down-first' if reverse else 'side-first':>10}  {cells}")

    w = withdrawal(cfg)
    p = w["params"]
    print(
        f"\n3. 21 G withdrawal from 4.5 mm (vertical, every layer cut): cutting fade in fat x_c {p.cut_fade_m(2) * 1e3:.3f} mm,"
        f" Dahl x_0 {p.dahl_length_m * 1e3:.2f} mm"
    )
    print("   back (mm)  axial (N, > 0 pushes out)  cutting (N)  shaft friction (N)")
    for d, f, c, fr in w["back"]:
        if d == w["back"][0][0] or any(
            abs(d - x) < 0.5e-6 for x in (0.02e-3, 0.05e-3, 0.1e-3, 0.15e-3, 0.2e-3, 0.3e-3, 0.4e-3, 0.6e-3, 0.8e-3, 1.0e-3)
        ):
            print(f"   {d * 1e3:9.2f}  {f:25.4f}  {c:11.4f}  {fr:18.4f}")
    print(
        f"   the tissue pushes the needle out for the first {w['push_m'] * 1e3:.3f} mm, returning {w['returned_j'] * 1e6:.1f} uJ;"
        f" resists from there. Energy per insert-withdraw cycle (tissue on needle): {w['cycle_j'] * 1e6:.1f} uJ"
    )
    if not w["push_m"] < 0.2e-3:
        fails.append("withdrawal: the outward push lasts 0.2 mm or more")
    if not w["cycle_j"] < 0.0:
        fails.append("withdrawal: the cycle returns energy")

    lo, hi = FLYNN_STIFFNESS_N_PER_MM
    print(f"\n4. tip travel at the skin's puncture, vertical, against F_p / k for in-vivo skin k = {lo}-{hi} N/mm (Flynn 2011)")
    print("   Flynn's probe is wider than a needle's tent, and a contact's stiffness grows with its radius: the needle's")
    print("   secant may lie below the band (travel past its long end) but not above it. Checked: travel >= F_p / k_max.")
    print("   gauge  F_p (N)  travel (mm)  band (mm)   secant F_p / travel (N/mm)")
    for g in (18, 21, 25, 27):
        r = puncture(cfg, 90.0, g)
        band = (r["fp_n"] / hi, r["fp_n"] / lo)
        travel_mm = r["travel_m"] * 1e3
        where = "in the band" if band[0] <= travel_mm <= band[1] else ("past its long end" if travel_mm > band[1] else "SHORT")
        print(
            f"   {g:5d}  {r['fp_n']:7.3f}  {travel_mm:11.2f}  {band[0]:.2f}-{band[1]:.2f}"
            f"   {r['fp_n'] / travel_mm:.2f}  ({where})"
        )
        if travel_mm < band[0]:  # stiffer than in-vivo skin under a wider probe: not a tent of this tissue
            fails.append(f"{g} G: tip travel {travel_mm:.2f} mm below F_p / k_max = {band[0]:.2f} mm")
    for f in fails:
        print(f"FAIL {f}")
    print(f"needle_angle FAIL: {len(fails)} checks failed" if fails else "needle_angle PASS")
    return 1 if fails else 0


if __name__ == "__main__":
    raise SystemExit(main())
