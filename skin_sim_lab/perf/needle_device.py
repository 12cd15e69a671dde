"""``skin-sim needle-device``: the needle at the device, offline and deterministic (issue 22, "At the device").

No DDS and no scheduler, as :func:`skin_sim_lab.perf.force_path.device_drag`:

- the *device* ticks at 1 kHz along a straight vertical insertion at the centre of the default tissue: from
  :data:`START_M` above the surface down to :data:`DEPTH_M` (past the last rupture: every layer is punctured) at
  :data:`SPEED_M_S`, then straight back out to the start at the same speed;
- the *server*, a :class:`skin_sim_node.model.needle.NeedleModel` stepped at the server rate (250 Hz by default) at
  the newest device pose, answers with its force and :meth:`NeedleModel.law` packed as a
  :class:`msgs_schema.contact_model.LocalModel` (:func:`needle_model`), which reaches the bridge one server period
  later (the server computes during its tick and publishes at the next);
- the *bridge* renders every device tick with the bridge's renderer (:class:`skin_sim_node.device.render.ContactRenderer`
  with the Touch caps, the passivity controller and the chatter guard: :func:`force_path.bridge_renderer_kw`) and,
  on the same models, with the hold-last baseline (``f0`` held between server updates);
- the *truth* is a second :class:`NeedleModel` stepped at every device pose (1 ms).

Printed per gauge (21 G and 18 G): for each rupture of the truth (the tick at which its count of ruptured layers
grows), the tick at which the rendered axial force drops by at least half the truth's drop, for the renderer and for
hold-last from the same run (aim: the renderer within 1 device tick); the render error ``|F - F_true|`` (whole
vector) p50 / p99 as % of the peak ``|F_true|``; the passivity observer's energy over the insertion cycle; the
commands ``|F_cmd| > 1.2 |F_true| + 0.05 N`` (aim: none). Then what a device clamp does to the 18 G peak, with and
without ``--force-scale``. Exits 1 when an aim fails.

Energy sign: the observer (:class:`skin_sim_node.device.passivity.PassivityController`) books the energy the rendered
environment *absorbed*, ``-sum F_applied . dx`` (>= 0 passive); the issue's aim "<= 0 per insertion cycle" is the
energy the environment *generated*, its negative, and is printed as such.
"""

from __future__ import annotations

import argparse
import math

import numpy as np

from msgs_schema.contact_model import DEFAULT_TTL_S, DEFAULT_VALIDITY_RADIUS_M, LocalModel
from msgs_schema.tissue import LAYER_NAMES
from skin_sim_node.device.mapping import TOUCH_PEAK_FORCE_N
from skin_sim_node.device.render import ContactRenderer, HoldLastRenderer

from .force_path import DEVICE_HZ, bridge_renderer_kw

GAUGES = (21, 18)
SERVER_HZ = 250.0
"""The server rate of the issue's aim (the slowest rate at which a 1 kHz device still gets a model every 4 ticks)."""
SPEED_M_S = 10e-3
"""Insertion and retraction speed (m/s): the faster end of the issue's 1-10 mm/s."""
START_M = 0.5e-3
"""Tip height above the rest surface at the start and end of the cycle (m): the cycle starts and ends out of contact."""
DEPTH_M = 6.0e-3
"""Deepest tip position below the rest surface (m): past the last rupture of the default tissue (5.23 mm at 21 G and
18 G, ``tests/test_needle.py``), so every layer is punctured, as in ``tests/test_needle.py``'s straight insertions."""
AXIS = (0.0, 0.0, -1.0)
"""Vertical insertion (tip direction)."""
SAW_MAX_FORCE_N = 2.0
"""sawSensablePhantom's default ``servo_cf`` clamp (``m_max_force``, N; docs/devices.md, "With a real Touch")."""
DROP_SHARE = 0.5
"""A rendered drop is a one-tick fall of the axial force of at least this share of the truth's drop at the rupture."""
DROP_WINDOW_TICKS = (10, 40)
"""Device ticks before and after the truth's rupture in which the rendered drop is looked for."""
OVER_RATIO, OVER_N = 1.2, 0.05
"""A command is above the truth when ``|F_cmd| > OVER_RATIO |F_true| + OVER_N`` (the issue's aim)."""


def tip_path(n_hold: int = 20) -> tuple[np.ndarray, np.ndarray]:
    """Tip positions (n, 3) and velocities (n, 3) at 1 kHz: in from :data:`START_M` to ``-DEPTH_M``, out again, then
    ``n_hold`` ticks at rest above the surface."""
    step = SPEED_M_S / DEVICE_HZ
    n_in = int(round((START_M + DEPTH_M) / step))
    z_in = START_M - step * np.arange(n_in + 1)
    z_out = z_in[::-1][1:]
    z = np.concatenate([z_in, z_out, np.full(n_hold, START_M)])
    vz = np.concatenate([np.full(n_in + 1, -SPEED_M_S), np.full(n_in, SPEED_M_S), np.zeros(n_hold)])
    x = np.zeros((z.size, 3))
    v = np.zeros((z.size, 3))
    x[:, 2], v[:, 2] = z, vz
    return x, v


def needle_model(seq: int, stamp_ns: int, x, v, tick, law) -> LocalModel:
    """The server's answer to the tip at ``x`` as the node would publish it: ``f0`` the tick's force, the needle law
    (None out of the tissue: a zero model), ``K`` the law's axial linearisation ``-g u u^T`` (the lateral bed's
    stiffness is not in ``step``/``law``'s answer: zero here, and zero on a straight track), no ``D``."""
    K = np.zeros((3, 3))
    if law is not None:
        u = np.asarray(law.axis, dtype=float)
        K = -law.axial_gradient_n_per_m * np.outer(u, u)
    return LocalModel(
        seq,
        stamp_ns,
        "tissue",
        np.asarray(x, dtype=float),
        np.asarray(v, dtype=float),
        np.asarray(tick.force_n, dtype=float),
        K,
        np.zeros((3, 3)),
        np.array([0.0, 0.0, 1.0]),
        DEFAULT_VALIDITY_RADIUS_M,
        DEFAULT_TTL_S,
        needle=law,
    )


def insertion(
    gauge: int,
    server_hz: float = SERVER_HZ,
    latency_ticks: int | None = None,
    max_force_n: float = TOUCH_PEAK_FORCE_N,
    force_scale: float = 1.0,
    renderer_kw: dict | None = None,
) -> dict:
    """One insertion cycle of a ``gauge`` needle through the default tissue, offline (module docstring).

    ``latency_ticks``: device ticks from a server tick to its model reaching the bridge (default one server period).
    ``max_force_n`` is the device's clamp (device N) and ``force_scale`` the bridge's device N per tissue N: the
    renderer works in tissue units, clamped at ``max_force_n / force_scale``, as ``skin-sim bridge`` builds it.
    Returns the forces (tissue N, per device tick) and the figures.
    """
    from skin_sim_node.device.stylus import DeviceParams
    from skin_sim_node.model.config import preset
    from skin_sim_node.model.needle import NeedleModel, NeedleParams

    cfg = preset("default")
    params = NeedleParams.gauge(gauge)
    truth, srv = NeedleModel(cfg, params), NeedleModel(cfg, params)
    kw = {**bridge_renderer_kw(DeviceParams.mass_kg), **(renderer_kw or {})}
    kw["max_force_n"] = max_force_n / force_scale if force_scale > 0 else math.inf
    render, hold = ContactRenderer(**kw), HoldLastRenderer(kw["max_force_n"])
    x, v = tip_path()
    n = x.shape[0]
    every = max(int(round(DEVICE_HZ / server_hz)), 1)
    lat = every if latency_ticks is None else int(latency_ticks)
    ms = 1_000_000
    t0_ns = 1_700_000_000 * 1_000_000_000
    f_true, f_ren, f_hold = np.zeros((n, 3)), np.zeros((n, 3)), np.zeros((n, 3))
    ruptured = np.zeros(n, dtype=int)
    latches: list[tuple[int, float]] = []  # (tick, rupture's axial position u . x) of each latch of the renderer
    pending: list[tuple[int, LocalModel]] = []
    seq = 0
    for k in range(n):
        stamp = t0_ns + k * ms
        t = truth.step(x[k], AXIS)
        f_true[k], ruptured[k] = t.force_n, t.ruptured
        if k % every == 0:
            ts = srv.step(x[k], AXIS)
            seq += 1
            pending.append((k + lat, needle_model(seq, stamp, x[k], v[k], ts, srv.law(ts, x[k]))))
        now = stamp * 1e-9
        while pending and pending[0][0] <= k:
            m = pending.pop(0)[1]
            render.set_model(m, now)
            hold.set_model(m, now)
        nr = render.needle
        was = nr is not None and nr.latched
        f_ren[k] = render.render(now, x[k], v[k])
        nr2 = render.needle
        if nr2 is not None and nr2.latched and not (was and nr2 is nr):
            latches.append((k, float(nr2.u @ render.model.x0_m) + nr2.law.rupture_distance_m))  # type: ignore[union-attr]
        f_hold[k] = hold.render(now, x[k], v[k])
    u = np.asarray(AXIS)
    axial = {"true": -f_true @ u, "render": -f_ren @ u, "hold": -f_hold @ u}
    peak = float(np.linalg.norm(f_true, axis=1).max())
    out: dict = {"gauge": gauge, "peak_n": peak, "f_true": f_true, "f_render": f_ren, "f_hold": f_hold, "axial": axial}
    events = []
    for k in (int(i) + 1 for i in np.flatnonzero(np.diff(ruptured) > 0)):
        drop = float(axial["true"][k - 1] - axial["true"][k])
        ev = {"tick": k, "layers": tuple(range(int(ruptured[k - 1]), int(ruptured[k]))), "drop_n": drop}
        for key in ("render", "hold"):
            ev[key] = drop_tick(axial[key], int(k), drop)
        # the renderer's latch of this rupture: the first whose rupture point lies on the truth's step over it
        lo, hi = sorted((float(u @ x[k - 1]), float(u @ x[k])))
        ev["latch"] = next((j for j, a in latches if lo - 1e-7 <= a <= hi + 1e-7), None)
        events.append(ev)
    out["events"] = events
    for key, f in (("render", f_ren), ("hold", f_hold)):
        err = np.linalg.norm(f - f_true, axis=1)
        for q in (50, 99):
            out[f"{key}_p{q}_pct"] = 100.0 * float(np.percentile(err, q)) / peak
        over = np.linalg.norm(f, axis=1) > OVER_RATIO * np.linalg.norm(f_true, axis=1) + OVER_N
        out[f"{key}_over_in"] = int(np.sum(over & (v[:, 2] < 0)))
        out[f"{key}_over_out"] = int(np.sum(over & (v[:, 2] >= 0)))
        out[f"{key}_over"] = int(np.sum(over))
    assert render.passivity is not None  # bridge_renderer_kw: the controller is on
    out["absorbed_j"] = render.passivity.energy_j
    out["dissipated_j"] = render.passivity.dissipated_j
    out["controller_ticks"] = render.passivity.active_ticks
    out["clamped_ticks"] = render.counts_clamped
    out["rendered_peak_n"] = float(np.linalg.norm(f_ren, axis=1).max())
    return out


def drop_tick(axial: np.ndarray, k_true: int, drop_n: float) -> int | None:
    """The first tick near ``k_true`` (:data:`DROP_WINDOW_TICKS`) at which ``axial`` falls by at least
    :data:`DROP_SHARE` of ``drop_n`` from the tick before; None if it never does."""
    lo = max(k_true - DROP_WINDOW_TICKS[0], 1)
    hi = min(k_true + DROP_WINDOW_TICKS[1], axial.size)
    for j in range(lo, hi):
        if axial[j - 1] - axial[j] >= DROP_SHARE * drop_n:
            return j
    return None


def _late(ev: dict, key: str) -> str:
    j = ev[key]
    return "none seen" if j is None else f"{j - ev['tick']:+d} ticks"


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(
        prog="skin-sim needle-device",
        description="Offline: a needle insertion rendered at the device (1 kHz) from a 250 Hz server's needle law, "
        "against the truth stepped every 1 ms and against hold-last (issue 22). Deterministic; exit 1 when an aim fails.",
    )
    ap.add_argument("--gauges", type=int, nargs="+", default=list(GAUGES), help="needle gauges (default 21 18)")
    ap.add_argument("--server-hz", type=float, default=SERVER_HZ, help="server rate (Hz), default 250")
    ap.add_argument("--max-force-n", type=float, default=TOUCH_PEAK_FORCE_N, help="device clamp (N), default 3.3 (Touch)")
    ap.add_argument("--force-scale", type=float, default=1.0, help="device N per tissue N (the bridge's), default 1")
    a = ap.parse_args(argv)
    if not (a.server_hz > 0 and a.max_force_n > 0 and a.force_scale > 0):
        ap.error("--server-hz, --max-force-n and --force-scale must be > 0")
    every = max(int(round(DEVICE_HZ / a.server_hz)), 1)
    print(
        f"needle at the device: vertical insertion at {SPEED_M_S * 1e3:g} mm/s from {START_M * 1e3:g} mm above to "
        f"{DEPTH_M * 1e3:g} mm below the surface and back; server {a.server_hz:g} Hz (a model every {every} device "
        f"ticks, one server period late), device 1 kHz, bridge renderer (Touch caps, passivity controller), clamp "
        f"{a.max_force_n:g} N at force scale {a.force_scale:g}; truth stepped every 1 ms"
    )
    ok = True
    for g in a.gauges:
        r = insertion(g, a.server_hz, max_force_n=a.max_force_n, force_scale=a.force_scale)
        print(f"{g} G: peak |F_true| {r['peak_n']:.3f} N, rendered peak {r['rendered_peak_n']:.3f} N (tissue units)")
        for ev in r["events"]:
            names = "+".join(LAYER_NAMES[j] for j in ev["layers"])
            is_drop = ev["drop_n"] >= 0.1 * r["peak_n"]  # a rupture whose force falls by less is a kink, not a drop
            print(
                f"  rupture {names:<11} truth tick {ev['tick']}, drop {ev['drop_n']:.3f} N"
                + f": renderer latched {_late(ev, 'latch')}"
                + (
                    f", its force drop {_late(ev, 'render')}; hold-last's force drop {_late(ev, 'hold')}"
                    if is_drop
                    else " (a kink, < 10 % of peak: no force drop to time)"
                )
            )
            late = ev["latch"] is None or abs(ev["latch"] - ev["tick"]) > 1
            if late or (is_drop and (ev["render"] is None or abs(ev["render"] - ev["tick"]) > 1)):
                ok = False
        generated = -r["absorbed_j"]
        print(
            f"  |F - F_true| p50 / p99 % of peak: rendered {r['render_p50_pct']:.2f} / {r['render_p99_pct']:.2f}, "
            f"hold-last {r['hold_p50_pct']:.2f} / {r['hold_p99_pct']:.2f}"
        )
        print(
            f"  passivity observer over the cycle: absorbed {r['absorbed_j'] * 1e6:.1f} uJ, so generated "
            f"{generated * 1e6:.1f} uJ (aim <= 0); controller active {r['controller_ticks']} ticks"
        )
        print(
            f"  commands above {OVER_RATIO:g} |F_true| + {OVER_N:g} N (inserting + retracting): rendered "
            f"{r['render_over_in']} + {r['render_over_out']} (aim 0), hold-last {r['hold_over_in']} + {r['hold_over_out']}; "
            f"ticks clamped {r['clamped_ticks']}"
        )
        ok = ok and generated <= 0.0 and r["render_over"] == 0
    # what a device clamp below the peak loses, and what --force-scale keeps (18 G: the largest peak)
    g = max(a.gauges, key=lambda q: -q)  # the thickest needle given (smallest gauge number)
    print(
        f"device clamp {SAW_MAX_FORCE_N:g} N (sawSensablePhantom's default), {g} G, in device N (axial K cap off, so the "
        "peak the clamp meets is the law's):"
    )
    peak_true = None
    for scale in (1.0, SAW_MAX_FORCE_N / TOUCH_PEAK_FORCE_N):
        r = insertion(
            g, a.server_hz, max_force_n=SAW_MAX_FORCE_N, force_scale=scale, renderer_kw={"max_stiffness_n_per_m": math.inf}
        )
        peak_true = r["peak_n"]
        big = max(r["events"], key=lambda e: e["drop_n"])
        k = big["tick"]
        before, after = (scale * float(np.linalg.norm(r["f_render"][j])) for j in (k - 1, k))
        print(
            f"  --force-scale {scale:.3f}: peak {scale * r['rendered_peak_n']:.3f} N (true x scale "
            f"{scale * peak_true:.3f}), drop {before:.3f} -> {after:.3f} N, {r['clamped_ticks']} ticks clamped"
        )
    print("without the K cap on the axial slopes (max_stiffness_n_per_m inf; not a device setting: a comparison):")
    for g in a.gauges:
        r = insertion(g, a.server_hz, max_force_n=a.max_force_n, force_scale=a.force_scale,
                      renderer_kw={"max_stiffness_n_per_m": math.inf})  # fmt: skip
        print(
            f"  {g} G: rendered peak {r['rendered_peak_n']:.3f} of {r['peak_n']:.3f} N, p50 / p99 "
            f"{r['render_p50_pct']:.2f} / {r['render_p99_pct']:.2f} %, generated {-r['absorbed_j'] * 1e6:.1f} uJ, "
            f"above {r['render_over_in']} + {r['render_over_out']}"
        )
    print(f"aims {'met' if ok else 'FAILED'}")
    return 0 if ok else 1


if __name__ == "__main__":
    raise SystemExit(main())
