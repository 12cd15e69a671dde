"""``skin-sim friction``: the presliding friction's figures (issue 30), offline and deterministic (no timing).

- **tremor**: a vertical press to 1.5 mm (0.5 s, held 1 s), then a lateral tremor ``x = A sin(2 pi f t)`` for 2 s
  (2 Hz 0.1 mm and 8 Hz 0.05 mm): the sideways force of the presliding law against today's (issue 19) velocity law
  in the same run (``-mu F_n v_t / sqrt(|v_t|^2 + v_s^2)`` at the tremor's exact velocity and the run's ``F_n``);
- **drag** at 1, 10 and 30 mm/s: the steady sliding force over ``mu F_n`` and the presliding distance (the tool's
  travel to the first slip) against the contact-mechanics band ``[1, 1.5] mu F_n / k_t``
  (``msgs_schema.tissue.TANGENTIAL_STIFFNESS_N_PER_M``);
- **reversal** at 10 mm/s (+-5 mm, two cycles) at 1 kHz and 250 Hz: the hysteresis loop's area ``-oint F_x dx``
  (the friction's dissipation, > 0) against the rigid-plastic loop ``4 mu F_n (L - delta)``.

Each scene is a :class:`SkinModel` of the default preset stepped at fixed ``dt`` on a scripted path. Prints one
block per figure; about 20 s on 2 cores (numba warm-up included).
"""

from __future__ import annotations

import argparse
import math

import numpy as np

from skin_sim_node.model import SkinModel
from skin_sim_node.model.friction import regularised_coulomb
from skin_sim_node.scenes import DEFAULT_PARAMS

PRESS_M = 1.5e-3
PRESS_S = 0.5
HOLD_S = 1.0
TREMORS = ((2.0, 0.1e-3), (8.0, 0.05e-3))
"""(frequency Hz, amplitude m) of the two tremor figures."""
TREMOR_S = 2.0
LEGACY_SLIP_SPEED_M_S = 1e-3
"""``v_s`` of today's (issue 19) velocity law, the baseline (its default ``contact.slip_speed_m_s``)."""
DRAG_SPEEDS_M_S = (1e-3, 10e-3, 30e-3)
DRAG_DISTANCE_M = 8e-3
REVERSAL_SPEED_M_S = 10e-3
REVERSAL_HALF_M = 5e-3
REVERSAL_RATES_HZ = (1000.0, 250.0)


def _cfg(params=DEFAULT_PARAMS):
    from skin_sim_node.bags.offline import load_params

    return load_params(params)[1]


def _press(model: SkinModel, dt: float) -> int:
    """Press to :data:`PRESS_M` over :data:`PRESS_S` and hold :data:`HOLD_S` at x = y = 0; returns the ticks run."""
    n = int(round((PRESS_S + HOLD_S) / dt))
    for k in range(n):
        t = (k + 1) * dt
        model.step((0.0, 0.0, -PRESS_M * min(t / PRESS_S, 1.0)), (0.0, 0.0, 0.0), dt)
    return n


def tremor(freq_hz: float, amp_m: float, dt: float = 1e-3, cfg=None) -> dict:
    """The tremor figure: sideways force of both laws over :data:`TREMOR_S` of tremor after the press.

    Returns
    -------
    dict
        ``x``, ``v`` (m, m/s), ``fx`` (presliding), ``fx_legacy`` (today's law, same run), ``fn`` (N) and the
        figures: amplitudes, ``k_t A``, ``mu F_n``, sign agreement with ``-x``, sign flips near velocity zero
        crossings (within an eighth of a period) for each law.
    """
    cfg = cfg or _cfg()
    m = SkinModel(cfg)
    _press(m, dt)
    n = int(round(TREMOR_S / dt))
    w = 2.0 * math.pi * freq_hz
    x, v, fx, fxl, fn = (np.zeros(n) for _ in range(5))
    for k in range(n):
        t = (k + 1) * dt
        x[k], v[k] = amp_m * math.sin(w * t), amp_m * w * math.cos(w * t)
        m.step((x[k], 0.0, -PRESS_M), (v[k], 0.0, 0.0), dt)
        f = m.force_vector_n
        normal = m.contact_normal
        fn[k] = float(normal @ f)
        fx[k] = f[0] - fn[k] * normal[0]
        fxl[k] = regularised_coulomb(normal, fn[k], cfg.friction_coefficient, LEGACY_SLIP_SPEED_M_S, (v[k], 0.0, 0.0))[0]
    k_t, mu = cfg.tangential_stiffness_n_per_m, cfg.friction_coefficient
    period = 1.0 / freq_hz
    vzero = np.flatnonzero(np.sign(v[1:]) * np.sign(v[:-1]) < 0)  # velocity zero crossings (tremor peaks)
    near = int(round(period / 8 / dt))

    def flips_at_v0(f):
        s = np.sign(f)
        flips = np.flatnonzero(s[1:] * s[:-1] < 0)
        return int(sum(np.any(np.abs(flips - i) <= near) for i in vzero))

    big = np.abs(x) > 0.2 * amp_m
    return {
        "x": x,
        "v": v,
        "fx": fx,
        "fx_legacy": fxl,
        "fn": fn,
        "amplitude_n": float(np.abs(fx).max()),
        "legacy_amplitude_n": float(np.abs(fxl).max()),
        "expected_n": k_t * amp_m,
        "slip_level_n": float(mu * fn.min()),
        "sign_follows_displacement": float(np.mean(np.sign(fx[big]) == -np.sign(x[big]))),
        "legacy_sign_follows_displacement": float(np.mean(np.sign(fxl[big]) == -np.sign(x[big]))),
        "flips_at_velocity_zero": flips_at_v0(fx),
        "legacy_flips_at_velocity_zero": flips_at_v0(fxl),
        "velocity_zero_crossings": int(vzero.size),
        "elastic_error_n": float(np.abs(fx + k_t * x).max()),
    }


def drag(speed_m_s: float, dt: float = 1e-3, cfg=None) -> dict:
    """The drag figure: after the press, drag :data:`DRAG_DISTANCE_M` along x at ``speed_m_s``.

    Returns
    -------
    dict
        ``ratio``: mean ``|F_t| / (mu F_n)`` over the last half of the drag; ``presliding_m``: the tool's travel to the
        first slip; ``expected_m``: ``mu F_n / k_t`` at that tick; ``band_m``: ``(1, 1.5) x expected``.
    """
    cfg = cfg or _cfg()
    m = SkinModel(cfg)
    _press(m, dt)
    n = int(round(DRAG_DISTANCE_M / speed_m_s / dt))
    ratio = np.zeros(n)
    first_slip = None
    expected = math.nan
    mu, k_t = cfg.friction_coefficient, cfg.tangential_stiffness_n_per_m
    for k in range(n):
        x = min((k + 1) * dt * speed_m_s, DRAG_DISTANCE_M)
        m.step((x, 0.0, -PRESS_M), (speed_m_s, 0.0, 0.0), dt)
        f = m.force_vector_n
        normal = m.contact_normal
        fn = float(normal @ f)
        ratio[k] = float(np.linalg.norm(f - fn * normal)) / (mu * fn)
        if first_slip is None and m.state()["_out"][21] > 0.0:  # OUT_SLIP_M: the anchor moved
            first_slip = x
            expected = mu * fn / k_t
    tail = ratio[n // 2 :]
    return {
        "ratio": float(tail.mean()),
        "ratio_min": float(tail.min()),
        "ratio_max": float(tail.max()),
        "presliding_m": math.nan if first_slip is None else first_slip,
        "expected_m": expected,
        "band_m": (expected, 1.5 * expected),
    }


def reversal(rate_hz: float, cfg=None, cycles: int = 2) -> dict:
    """The reversal figure: ``x`` 0 -> +L -> -L -> 0 at :data:`REVERSAL_SPEED_M_S`, ``cycles`` times, stepped at
    ``rate_hz``; the loop area ``-sum F_x dx`` (J) of the last cycle (trapezoidal), and the rigid-plastic estimate."""
    cfg = cfg or _cfg()
    dt = 1.0 / rate_hz
    m = SkinModel(cfg)
    _press(m, dt)
    L = REVERSAL_HALF_M
    leg = [(0.0, L), (L, -L), (-L, 0.0)]
    xs = [0.0]
    for _ in range(cycles):
        for a, b in leg:
            steps = int(round(abs(b - a) / REVERSAL_SPEED_M_S / dt))
            xs += list(a + (b - a) * np.arange(1, steps + 1) / steps)
    xs = np.array(xs)
    fx = np.zeros(xs.size)
    fn = np.zeros(xs.size)
    for k, x in enumerate(xs):
        m.step((x, 0.0, -PRESS_M), (0.0, 0.0, 0.0), dt)
        f = m.force_vector_n
        normal = m.contact_normal
        fn[k] = float(normal @ f)
        fx[k] = f[0]
    per = (xs.size - 1) // cycles
    a = xs.size - 1 - per
    work = -float(np.sum(0.5 * (fx[a + 1 :] + fx[a:-1]) * np.diff(xs[a:])))
    mu, k_t = cfg.friction_coefficient, cfg.tangential_stiffness_n_per_m
    fbar = float(fn[a:].mean())
    return {
        "area_j": work,
        "expected_j": 4.0 * mu * fbar * (L - mu * fbar / k_t),
        "x": xs,
        "fx": fx,
    }


def print_figures() -> dict:
    """Print every figure (tremor, drag, reversal); returns them."""
    cfg = _cfg()
    mu, k_t = cfg.friction_coefficient, cfg.tangential_stiffness_n_per_m
    print(f"presliding friction (Hayward-Armstrong adhesion point): mu {mu:g}, k_t {k_t:g} N/m; default preset, offline")
    out: dict = {"tremor": {}, "drag": {}, "reversal": {}}
    print("tremor: press 1.5 mm, then x = A sin(2 pi f t) for 2 s at 1 kHz; sideways force F_x, presliding vs today's law")
    for f, a in TREMORS:
        r = tremor(f, a, cfg=cfg)
        out["tremor"][f] = r
        print(
            f"  {f:g} Hz {a * 1e3:.2f} mm: presliding |F_x| max {r['amplitude_n'] * 1e3:.2f} mN (k_t A "
            f"{r['expected_n'] * 1e3:.2f} mN, |F_x + k_t x| max {r['elastic_error_n']:.1e} N; mu F_n "
            f"{r['slip_level_n'] * 1e3:.0f} mN), sign of -x {100 * r['sign_follows_displacement']:.0f} %, "
            f"flips at velocity zeros {r['flips_at_velocity_zero']} of {r['velocity_zero_crossings']} | today's law: "
            f"|F_x| max {r['legacy_amplitude_n'] * 1e3:.0f} mN, sign of -x "
            f"{100 * r['legacy_sign_follows_displacement']:.0f} %, flips at velocity zeros "
            f"{r['legacy_flips_at_velocity_zero']} of {r['velocity_zero_crossings']}",
            flush=True,
        )
    print(f"drag: press 1.5 mm, then {DRAG_DISTANCE_M * 1e3:g} mm along x at 1 kHz; |F_t| / mu F_n over its last half")
    for v in DRAG_SPEEDS_M_S:
        r = drag(v, cfg=cfg)
        out["drag"][v] = r
        lo, hi = r["band_m"]
        print(
            f"  {v * 1e3:4.0f} mm/s: sliding |F_t| / mu F_n {r['ratio']:.4f} (min {r['ratio_min']:.4f}, max "
            f"{r['ratio_max']:.4f}); presliding distance {r['presliding_m'] * 1e3:.3f} mm (band {lo * 1e3:.3f}-"
            f"{hi * 1e3:.3f} mm)",
            flush=True,
        )
    print(
        f"reversal: +-{REVERSAL_HALF_M * 1e3:g} mm at {REVERSAL_SPEED_M_S * 1e3:g} mm/s, 2 cycles; loop area "
        "-oint F_x dx of the last"
    )
    for hz in REVERSAL_RATES_HZ:
        r = reversal(hz, cfg=cfg)
        out["reversal"][hz] = r
        print(
            f"  {hz:5.0f} Hz: loop area {r['area_j'] * 1e3:.3f} mJ (rigid-plastic 4 mu F_n (L - delta) "
            f"{r['expected_j'] * 1e3:.3f} mJ)",
            flush=True,
        )
    return out


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(prog="skin-sim friction", description=__doc__.split("\n\n")[0])
    ap.parse_args(argv)
    print_figures()
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
