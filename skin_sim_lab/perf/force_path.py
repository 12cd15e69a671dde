"""``skin-sim force-path``: the server rate as a level-of-detail lever (issue 12), offline (no DDS).

For each scene (press, drag, release) and server rate (1000, 500, 250, 100 Hz by default):

- the *device* ticks at 1 kHz along the scene's path (prescribed motion, exact velocity);
- the *server* (a :class:`SkinModel` stepped at the server rate) answers the newest device pose with
  its force and local tangent (:meth:`SkinModel.tangent`), packed as a
  :class:`msgs_schema.contact_model.LocalModel`, which reaches the bridge ``--latency-ms`` later;
- the *bridge* renders every device tick, with :class:`skin_sim_node.device.render.ContactRenderer`
  and, on the same models, with the hold-last-force baseline (:class:`HoldLastRenderer`);
- the *reference* is the full model stepped at 1 kHz at the device pose.

It prints, per scene and rate, the p99 and maximum of ``|F_rendered - F_reference|`` as a percentage
of the scene's peak reference force, for both bridges from the same run, and draws
``out/force_path/force_path_rate.png`` (``--docs``: ``docs/figures/force_path_rate.png``). Takes about 10 s
(measured on 2 cores, numba warm-up included).
"""

from __future__ import annotations

import argparse
import math
import os
import time
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from msgs_schema.contact_model import DEFAULT_TTL_S, DEFAULT_VALIDITY_RADIUS_M, LocalModel
from skin_sim_node.device.render import ContactRenderer, HoldLastRenderer
from skin_sim_node.device.trajectories import TRAJECTORIES
from skin_sim_node.model import SkinModel, load_tissue_config
from skin_sim_node.scenes import DEFAULT_PARAMS, REPO
from skin_sim_node.tools import make_tool, warm_up

DEVICE_HZ = 1000.0
RATES_HZ = (1000.0, 500.0, 250.0, 100.0)
DOCS_CHART = REPO / "docs" / "figures" / "force_path_rate.png"
OUT_CHART = Path("out/force_path/force_path_rate.png")
"""Where ``skin-sim force-path`` draws its chart unless told ``--docs`` or ``--chart``: the tracked docs stay as committed."""


@dataclass(frozen=True)
class ForceScene:
    """A hand path and the window (s) in which the error is counted (the path runs from 0 for the state)."""

    name: str
    path: str
    window_s: tuple[float, float]
    description: str


SCENES = (
    ForceScene("press", "press_all_layers", (0.0, 1.8), "press to 4 mm in 0.8 s and hold 1 s (all three layers)"),
    ForceScene("drag", "drag", (0.0, 3.5), "press to 1.5 mm, drag 40 mm in 2 s across the egg-carton interface, lift"),
    ForceScene("release", "press_all_layers", (1.7, 2.8), "from the 4 mm hold, release over 0.5 s, then lifted"),
)


def tangent_model(model: SkinModel, seq: int, stamp_ns: int, x, v) -> LocalModel:
    """The server's answer to a pose, as the node publishes it (the layered form's presliding friction included)."""
    t = model.tangent()
    law = t.tangential_stiffness_n_per_m > 0.0 and t.friction_anchor_m is not None
    return LocalModel(
        seq,
        stamp_ns,
        "tissue",
        x,
        v,
        t.force_n,
        t.stiffness_n_per_m,
        t.damping_n_s_per_m,
        t.normal,
        DEFAULT_VALIDITY_RADIUS_M,
        DEFAULT_TTL_S,
        normal_force_n=t.normal_force_n,
        normal_force_gradient_n_per_m=t.normal_force_gradient_n_per_m,
        friction_coefficient=t.friction_coefficient if law else 0.0,
        tangential_stiffness_n_per_m=t.tangential_stiffness_n_per_m if law else 0.0,
        friction_anchor_m=t.friction_anchor_m if law else np.zeros(3),
        slip_force_n=t.friction_coefficient * t.normal_force_n if law else 0.0,
    )


# --- the device benchmark's drag, offline (issue 19): the bridge's render error without a scheduler ------------
DRAG_RATES_HZ = (1000.0, 250.0)
DRAG_PERIODS = 2
"""Back-and-forth periods of the bench-device drag counted (4 s: four friction reversals)."""


def _plain_contact_model_msg():
    """A ``ContactModel``-shaped object (attribute access, arrays) for :func:`fill_contact_model_from_tick` without ROS."""
    from types import SimpleNamespace

    from msgs_schema.contact_model import NeedleLaw

    return SimpleNamespace(
        needle_axis=np.zeros(3),
        **dict.fromkeys(NeedleLaw.FIELDS, 0.0),
        header=SimpleNamespace(stamp=SimpleNamespace(sec=0, nanosec=0), frame_id=""),
        sequence=0,
        x0_m=np.zeros(3),
        v0_m_s=np.zeros(3),
        f0_n=np.zeros(3),
        stiffness_n_per_m=np.zeros(9),
        damping_n_s_per_m=np.zeros(9),
        normal=np.zeros(3),
        validity_radius_m=0.0,
        time_to_live_s=0.0,
        normal_force_n=0.0,
        normal_force_gradient_n_per_m=np.zeros(3),
        coupling_rate_n_per_s=np.zeros(3),
        friction_coefficient=0.0,
        slip_speed_m_s=0.0,
        tangential_stiffness_n_per_m=0.0,
        friction_anchor_m=np.zeros(3),
        slip_force_n=0.0,
    )


LEGACY_SLIP_SPEED_M_S = 1e-3
"""``v_s`` of issue 19's velocity law (its default ``contact.slip_speed_m_s``): the baseline of issue 30's figures."""


def legacy_model(m: LocalModel) -> LocalModel:
    """``m`` with issue 19's velocity law in place of the presliding friction: ``f0 = F_n0 n - mu F_n0 v_t / r`` at the
    model's ``v0`` (the law's own answer at ``x0``, ``v0``), its ``K``, ``D`` and ``v_s``, no anchor. The baseline
    ("today's law in the same run") of ``skin-sim friction`` and the closed-loop drag; ``m`` without friction is
    returned as is."""
    from dataclasses import replace

    from skin_sim_node.model.friction import regularised_coulomb

    mu = m.friction_coefficient
    if mu <= 0.0 or m.tangential_stiffness_n_per_m <= 0.0:
        return m
    n, fn, g, vs = m.normal, m.normal_force_n, m.normal_force_gradient_n_per_m, LEGACY_SLIP_SPEED_M_S
    vt = m.v0_m_s - float(n @ m.v0_m_s) * n
    r = math.sqrt(float(vt @ vt) + vs * vs)
    proj = np.eye(3) - np.outer(n, n)
    return replace(
        m,
        f0_n=fn * n + regularised_coulomb(n, fn, mu, vs, m.v0_m_s),
        stiffness_n_per_m=np.outer(n - mu * vt / r, g),
        damping_n_s_per_m=-mu * fn * (np.eye(3) / r - np.outer(vt, vt) / r**3) @ proj,
        slip_speed_m_s=vs,
        tangential_stiffness_n_per_m=0.0,
        friction_anchor_m=np.zeros(3),
        slip_force_n=0.0,
    )


def bridge_renderer_kw(mass_kg: float) -> dict:
    """The renderer as ``skin-sim bridge`` builds it by default for a stylus of ``mass_kg`` (unit scales): the Touch
    caps, the passivity controller and the chatter guard."""
    from skin_sim_node.device.render import SERVO_PERIOD_S, stable_damping_n_s_per_m

    return {"passivity_mass_kg": mass_kg, "stick_slope_n_s_per_m": stable_damping_n_s_per_m(mass_kg, SERVO_PERIOD_S)}


def device_drag(
    rate_hz: float,
    latency_ticks: int = 1,
    renderer_kw: dict | None = None,
    device_velocity: bool = True,
    periods: int = DRAG_PERIODS,
    jitter_ticks: int = 0,
    drop: float = 0.0,
    seed: int = 0,
) -> dict:
    """Render error of the bench-device drag, offline and deterministic (no DDS, no scheduler).

    The device ticks at 1 kHz along :func:`skin_sim_lab.perf.device_bench.hand` (press at 1.5 mm, 10 mm back and
    forth every 2 s) and reports its exact velocity, as the emulator's ``measured_cv`` (``device_velocity`` False:
    none, the renderer estimates it). The *server*, a :class:`HapticSession` as the node's, answers every
    ``1000 / rate_hz``-th pose; its :class:`TickResult` goes through :func:`fill_contact_model_from_tick` and
    :func:`read_contact_model` (the node's and the bridge's code, no CDR) and reaches the bridge ``latency_ticks``
    later. The bridge renders every device tick with the bridge's renderer (Touch caps, passivity controller), and
    the hold-last baseline holds the newest ``f0`` (the published wrench). The *truth* is a second session stepped
    on every pose (bench-device's ground truth). Errors: ``|F - F_true|``, whole vector, % of the peak ``|F_true|``
    over the drag. ``jitter_ticks`` adds a uniform 0..jitter extra delay per model and ``drop`` loses that share of
    the models (seeded ``seed``: DDS's irregular delivery, deterministic), for both bridges alike.
    """
    from msgs_schema.contact_model import fill_contact_model_from_tick, read_contact_model
    from skin_sim_node.bags.offline import load_params
    from skin_sim_node.device.stylus import DeviceParams
    from skin_sim_node.session import HapticSession

    from .device_bench import DRAG_PERIOD_S, WARM_S, hand

    sp, cfg = load_params()
    truth_s, srv = HapticSession(make_tool(cfg), sp), HapticSession(make_tool(cfg), sp)
    kw = {**bridge_renderer_kw(DeviceParams.mass_kg), **(renderer_kw or {})}
    render, hold = ContactRenderer(**kw), HoldLastRenderer()
    msg = _plain_contact_model_msg()
    phase_s = DRAG_PERIOD_S * periods
    n = int(round((WARM_S + phase_s) * DEVICE_HZ))
    every = max(int(round(DEVICE_HZ / rate_hz)), 1)
    ms = 1_000_000
    t0_ns = 1_700_000_000 * 1_000_000_000
    f_true, f_ren, f_hold = np.zeros((n, 3)), np.zeros((n, 3)), np.zeros((n, 3))
    pending: list[tuple[int, LocalModel]] = []
    rng = np.random.default_rng(seed)
    prev_srv = None
    for k in range(n):
        t = k / DEVICE_HZ
        stamp = t0_ns + k * ms
        x, v = hand(t, phase_s)
        truth_s.on_twist(stamp, sp.tissue_frame, v)
        truth_s.on_pose(stamp, sp.tissue_frame, x)
        r = truth_s.tick(stamp, ms)
        f_true[k] = r.force_n
        if k % every == 0:
            srv.on_twist(stamp, sp.tissue_frame, v)
            srv.on_pose(stamp, sp.tissue_frame, x)
            rs = srv.tick(stamp, 0 if prev_srv is None else stamp - prev_srv)
            prev_srv = stamp
            m_new = read_contact_model(fill_contact_model_from_tick(msg, rs, stamp, sp.tissue_frame))
            if rng.random() >= drop:
                extra = int(rng.integers(0, jitter_ticks + 1)) if jitter_ticks > 0 else 0
                pending.append((k + latency_ticks + extra, m_new))
                pending.sort(key=lambda e: e[0])
        ts = stamp * 1e-9
        while pending and pending[0][0] <= k:
            m = pending.pop(0)[1]
            render.set_model(m, ts)
            hold.set_model(m, ts)
        f_ren[k] = render.render(ts, x, v if device_velocity else None)
        f_hold[k] = hold.render(ts, x, v)
    sl = slice(int(round(WARM_S * DEVICE_HZ)), n)
    peak = float(np.linalg.norm(f_true[sl], axis=1).max())
    out = {"peak_n": peak, "f_true": f_true[sl], "f_render": f_ren[sl], "f_hold": f_hold[sl]}
    for key, f in (("render", f_ren), ("hold", f_hold)):
        err = np.linalg.norm(f[sl] - f_true[sl], axis=1)
        for q in (50, 99):
            out[f"{key}_p{q}_pct"] = 100.0 * float(np.percentile(err, q)) / peak
        out[f"{key}_max_pct"] = 100.0 * float(err.max()) / peak
    return out


def closed_loop_drag(
    renderer_kw: dict | None = None, every: int = 4, legacy: bool = False, path: str = "drag", kick_m_s: float = 0.0
) -> tuple[np.ndarray, ContactRenderer]:
    """The force path with a stylus in the loop, offline: :class:`SimulatedDevice` on the ``drag`` path (a 45 g stylus
    on a 300 N/m hand), a :class:`HapticSession` answering every ``every``-th tick through the contact model message,
    the bridge's renderer (Touch caps, passivity controller), the command applied the tick after. ``legacy``: each
    model carries issue 19's velocity law instead (:func:`legacy_model`); ``path``: another hand path (the demo's
    ``press_hold_release``); ``kick_m_s``: a sideways velocity (device x) given to the stylus at 1.0 s, the lateral
    disturbance of a live run (a hand is never exactly still). Returns the commanded forces (n, 3) and the renderer
    (its passivity observer's energy, its chatter guard's count)."""
    from msgs_schema.contact_model import fill_contact_model_from_tick, read_contact_model
    from skin_sim_node.bags.offline import load_params
    from skin_sim_node.device.stylus import SimulatedDevice
    from skin_sim_node.session import HapticSession

    sp, cfg = load_params()
    dev = SimulatedDevice(path)
    s = HapticSession(make_tool(cfg), sp)
    r = ContactRenderer(**{**bridge_renderer_kw(dev.params.mass_kg), **(renderer_kw or {})})
    msg = _plain_contact_model_msg()
    n = int(round(dev.hand_path.duration_s * DEVICE_HZ))
    f = np.zeros((n, 3))
    prev = None
    t0_ns = 1_700_000_000 * 1_000_000_000
    for k in range(n):
        p, v = dev.pos_tissue, dev.vel_tissue
        stamp = t0_ns + k * 1_000_000
        if k % every == 0:
            s.on_twist(stamp, sp.tissue_frame, tuple(v))
            s.on_pose(stamp, sp.tissue_frame, tuple(p))
            res = s.tick(stamp, 0 if prev is None else stamp - prev)
            prev = stamp
            m = read_contact_model(fill_contact_model_from_tick(msg, res, stamp, sp.tissue_frame))
            r.set_model(legacy_model(m) if legacy else m, stamp * 1e-9)
        f[k] = r.render(stamp * 1e-9, p, v)
        if kick_m_s and k == int(DEVICE_HZ):
            dev.vel = (dev.vel[0] + kick_m_s, dev.vel[1], dev.vel[2])
        dev.step(dev.mapping.force_to_device(tuple(f[k])), 1.0 / DEVICE_HZ)
    return f, r


CLOSED_LOOP_DRAG_S = (0.7, 2.9)
"""The drag of the ``drag`` path (s): pressed, sliding, before the lift."""


def stick_flips(fx: np.ndarray) -> int:
    """Sign changes of the tangential force ``fx`` over :data:`CLOSED_LOOP_DRAG_S` (a chatter counts each flip)."""
    a, b = (int(round(t * DEVICE_HZ)) for t in CLOSED_LOOP_DRAG_S)
    seg = fx[a:b]
    return int(np.sum(np.sign(seg[1:]) * np.sign(seg[:-1]) < 0))


def print_closed_loop() -> None:
    """Print the closed-loop drag's friction flips (per second of the slide), mean friction, energy and chatter guard
    engagements: the presliding law against issue 19's velocity law in the same run (linear form, law with and
    without the chatter guard, with slope caps)."""
    from skin_sim_node.device.render import SERVO_PERIOD_S, stable_damping_n_s_per_m
    from skin_sim_node.device.stylus import DeviceParams

    cap = stable_damping_n_s_per_m(DeviceParams.mass_kg, SERVO_PERIOD_S)
    print(
        "  closed loop (SimulatedDevice drag: 45 g stylus on a 300 N/m hand; server 250 Hz; passivity controller): "
        "sign flips of F_x per second of the slide, mean |F_x|, the passivity observer's energy, chatter guard"
    )
    a, b = (int(round(t * DEVICE_HZ)) for t in CLOSED_LOOP_DRAG_S)
    slide_s = CLOSED_LOOP_DRAG_S[1] - CLOSED_LOOP_DRAG_S[0]
    for label, kw, legacy in (
        ("presliding law (bridge, chatter guard on)", {}, False),
        ("presliding law, linear form", {"friction_law": False}, False),
        ("velocity law, linear form", {"friction_law": False}, True),
        ("velocity law, no chatter guard", {"stick_slope_n_s_per_m": math.inf}, True),
        ("velocity law + chatter guard (bridge)", {}, True),
        (
            f"velocity law, slope cap {cap:.1f} N s/m",
            {"max_friction_slope_n_s_per_m": cap, "stick_slope_n_s_per_m": math.inf},
            True,
        ),
    ):
        f, r = closed_loop_drag(kw, legacy=legacy)
        assert r.passivity is not None
        print(
            f"  {label:42s} flips {stick_flips(f[:, 0]) / slide_s:6.1f} /s  mean |F_x| {np.abs(f[a:b, 0]).mean():.4f} N  "
            f"energy {r.passivity.energy_j * 1e3:.2f} mJ, controller active {r.passivity.active_ticks} ticks, "
            f"guard engaged {r.counts_chatter} times",
            flush=True,
        )


PRESS_KICK_M_S = 5e-3
"""The sideways kick of :func:`print_closed_loop_press` (m/s, device x, at 1.0 s of the demo's press)."""


def print_closed_loop_press() -> dict:
    """The demo's press (``press_hold_release``: 2.5 mm, held 0.5-1.5 s) closed loop, the stylus kicked sideways at
    :data:`PRESS_KICK_M_S` at 1.0 s: the force over the hold 1.0-1.45 s with the presliding law against issue 19's
    velocity law in the same run. Returns ``{law: (|F| min, |F| max, |F_x| max, |F_x| max after 0.2 s, flips,
    guard engagements)}``."""
    print(
        f"  closed loop, the demo's press (2.5 mm, held; 45 g stylus on a 300 N/m hand; server 250 Hz), kicked "
        f"sideways at {PRESS_KICK_M_S * 1e3:g} mm/s at 1.0 s: the hold 1.0-1.45 s"
    )
    out = {}
    for label, legacy in (("presliding law", False), ("velocity law", True)):
        f, r = closed_loop_drag(legacy=legacy, path="press_hold_release", kick_m_s=PRESS_KICK_M_S)
        hold, late = f[1000:1450], f[1200:1450, 0]
        mag = np.linalg.norm(hold, axis=1)
        flips = int(np.sum(np.sign(hold[1:, 0]) * np.sign(hold[:-1, 0]) < 0))
        out[label] = (mag.min(), mag.max(), np.abs(hold[:, 0]).max(), np.abs(late).max(), flips, r.counts_chatter)
        print(
            f"  {label:15s} |F| {mag.min():.3f}-{mag.max():.3f} N, |F_x| max {np.abs(hold[:, 0]).max() * 1e3:6.1f} mN, "
            f"after 0.2 s {np.abs(late).max() * 1e3:5.2f} mN, F_x sign flips {flips:3d}, chatter guard engaged "
            f"{r.counts_chatter} times",
            flush=True,
        )
    return out


def print_device_drag(rates=DRAG_RATES_HZ, latency_ticks: int = 1) -> dict:
    """Print the offline bench-device drag's render error, law and linear renderers and hold-last, per server rate."""
    print(
        "  bench-device drag offline (press 1.5 mm, 10 mm back and forth, 2 periods; device 1 kHz, model delivered "
        f"{latency_ticks} tick(s) after its pose; Touch caps, passivity controller, chatter guard): |F - F_true|, % of peak"
    )
    print(
        "  velocity: the device's (CRTK measured_cv) or none; the presliding law renders from positions alone, so both "
        "rows are the same forces"
    )
    head = f"{'law p50 / p99':>14s} | {'linear p50 / p99':>16s} | {'hold-last p50 / p99':>19s}"
    print(f"  {'server Hz':>9s} | {'velocity':13s} | {head}")
    res = {}
    cases = [("device", True, {}), ("none", False, {})]  # the presliding law reads no velocity: the same forces
    for r in rates:
        for name, dv, kw in cases:
            law = device_drag(r, latency_ticks, kw, device_velocity=dv)
            lin = device_drag(r, latency_ticks, {**kw, "friction_law": False}, device_velocity=dv)
            res[(r, name)] = (law, lin)
            print(
                f"  {r:9.0f} | {name:13s} | {law['render_p50_pct']:5.2f} / {law['render_p99_pct']:5.2f}"
                f"  | {lin['render_p50_pct']:6.2f} / {lin['render_p99_pct']:6.2f}   | {law['hold_p50_pct']:7.2f} / "
                f"{law['hold_p99_pct']:6.2f}",
                flush=True,
            )
    for r in rates:
        law = device_drag(r, latency_ticks, jitter_ticks=8, drop=0.1)
        lin = device_drag(r, latency_ticks, {"friction_law": False}, jitter_ticks=8, drop=0.1)
        res[(r, "jitter")] = (law, lin)
        print(
            f"  {r:9.0f} | {'dev, DDS-like':13s} | {law['render_p50_pct']:5.2f} / {law['render_p99_pct']:5.2f}"
            f"  | {lin['render_p50_pct']:6.2f} / {lin['render_p99_pct']:6.2f}   | {law['hold_p50_pct']:7.2f} / "
            f"{law['hold_p99_pct']:6.2f}",
            flush=True,
        )
    print("  (dev, DDS-like: the device's velocity; each model 0-8 ticks later still, 10 % of them lost, seeded)")
    return res


def run_scene(cfg, scene: ForceScene, rate_hz: float, latency_ticks: int, renderer_kw: dict) -> dict:
    """Error series of both bridges against the 1 kHz reference for one scene and server rate."""
    traj = TRAJECTORIES[scene.path]
    dt = 1.0 / DEVICE_HZ
    n = int(round(min(scene.window_s[1], traj.duration_s) / dt)) + 1
    ref, srv = SkinModel(cfg), SkinModel(cfg)
    render, hold = ContactRenderer(**renderer_kw), HoldLastRenderer()
    every = DEVICE_HZ / rate_hz
    pending: list[tuple[int, LocalModel]] = []
    next_srv, last_srv_t, seq = 0.0, None, 0
    f_ref = np.zeros((n, 3))
    f_ren = np.zeros((n, 3))
    f_hold = np.zeros((n, 3))
    for k in range(n):
        t = k * dt
        x, v = traj.sample(t)
        ref.step(x, v, dt if k else 0.0)
        f_ref[k] = ref.tangent().force_n
        if k >= next_srv - 1e-9:  # the server's tick: answers the newest device pose
            srv.step(x, v, t - last_srv_t if last_srv_t is not None else 0.0)
            last_srv_t = t
            seq += 1
            pending.append((k + latency_ticks, tangent_model(srv, seq, int(t * 1e9), x, v)))
            next_srv += every
        while pending and pending[0][0] <= k:
            _, m = pending.pop(0)
            render.set_model(m, t)
            hold.set_model(m, t)
        f_ren[k] = render.render(t, x, v)
        f_hold[k] = hold.render(t, x, v)
    lo = int(round(scene.window_s[0] / dt))
    sl = slice(lo, n)
    peak = float(np.linalg.norm(f_ref[sl], axis=1).max())
    out = {"peak_n": peak, "t_s": np.arange(n)[sl] * dt, "f_ref": f_ref[sl], "f_render": f_ren[sl], "f_hold": f_hold[sl]}
    for key, f in (("render", f_ren), ("hold", f_hold)):
        err = np.linalg.norm(f[sl] - f_ref[sl], axis=1)
        out[f"{key}_p99_pct"] = 100.0 * float(np.percentile(err, 99)) / peak if peak > 0 else float("nan")
        out[f"{key}_max_pct"] = 100.0 * float(err.max()) / peak if peak > 0 else float("nan")
    return out


def chart(results: dict, rates, path: Path, latency_ticks: int = 1) -> Path:
    """Draw the force error against server rate, local model against hold-last, to ``path``; returns ``path``.

    Top row: one panel per scene, the p99 error of both bridges against the server rate (shared log axis).
    Bottom row: the drag scene at 250 Hz over time, its normal force and each bridge's error against the
    1 kHz reference (the forces themselves agree to a line's width, so the error is drawn apart).
    """
    import matplotlib
    import matplotlib.ticker

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig = plt.figure(figsize=(12, 7.6))
    grid = fig.add_gridspec(2, len(results), height_ratios=(1.0, 0.9))
    floor = 0.01  # % of peak: an exact render would vanish from a log axis
    top = [fig.add_subplot(grid[0, 0])]
    top += [fig.add_subplot(grid[0, i], sharey=top[0]) for i in range(1, len(results))]
    for ax, (name, by_rate) in zip(top, results.items()):
        ax.plot(
            rates, [max(by_rate[r]["render_p99_pct"], floor) for r in rates], "o-", color="tab:blue", label="local model rendered"
        )
        ax.plot(rates, [max(by_rate[r]["hold_p99_pct"], floor) for r in rates], "s--", color="tab:red", label="hold last force")
        ax.axhline(5.0, color="grey", lw=0.8, ls=":", label="5 % of the scene's peak")
        ax.set_xscale("log")
        ax.set_yscale("log")
        ax.set_xticks(rates, [f"{r:.0f}" for r in rates])
        ax.xaxis.set_minor_locator(matplotlib.ticker.NullLocator())
        ax.set_xlabel("server (model) rate (Hz)")
        sc = next((s for s in SCENES if s.name == name), None)
        ax.set_title(f"{name}: {sc.description}" if sc else name, fontsize=8, wrap=True)
        ax.grid(True, which="both", alpha=0.3)
    top[0].set_ylabel("p99 |F_device - F_full model|\n(% of the scene's peak force)")
    handles, labels = top[0].get_legend_handles_labels()
    fig.legend(handles, labels, fontsize=8, loc="upper center", bbox_to_anchor=(0.5, 0.955), ncol=3, frameon=False)
    for ax in top[1:]:
        ax.tick_params(labelleft=False)
    key = 250.0 if 250.0 in results.get("drag", {}) else next(iter(results["drag"]))
    r = results["drag"][key]
    half = max(1, len(results) // 2)
    ax = fig.add_subplot(grid[1, :half])
    ax.plot(r["t_s"], r["f_ref"][:, 2], "k-", lw=1.2, label="full model at 1 kHz (reference)")
    ax.set_xlabel("time (s)")
    ax.set_ylabel("normal force F_z (N)")
    ax.set_title(f"drag scene, reference force (both bridges at {key:.0f} Hz lie on it: see right)", fontsize=8)
    ax.legend(fontsize=7, loc="lower center")
    ax.grid(True, alpha=0.3)
    ax = fig.add_subplot(grid[1, half:])
    ax.plot(r["t_s"], 1e3 * (r["f_hold"][:, 2] - r["f_ref"][:, 2]), "-", color="tab:red", lw=0.8, label="hold last force")
    ax.plot(r["t_s"], 1e3 * (r["f_render"][:, 2] - r["f_ref"][:, 2]), "-", color="tab:blue", lw=0.9, label="local model rendered")
    ax.axhline(0.0, color="k", lw=0.6)
    ax.set_xlabel("time (s)")
    ax.set_ylabel("F_z device - F_z reference (mN)")
    ax.set_title(f"drag scene, server at {key:.0f} Hz: normal-force error of each bridge", fontsize=8)
    ax.legend(fontsize=7, loc="upper left")
    ax.grid(True, alpha=0.3)
    fig.suptitle(
        "Force at the device (1 kHz) against the full model at 1 kHz, per server rate; model delivered "
        f"{latency_ticks} tick(s) after the pose it answers; "
        f"errors under {floor} % drawn at {floor} %",
        fontsize=9,
    )
    fig.tight_layout(rect=(0, 0, 1, 0.93))
    path.parent.mkdir(parents=True, exist_ok=True)
    fig.savefig(path, dpi=110)
    plt.close(fig)
    return path


def main(argv=None) -> int:
    """``skin-sim force-path``: device force error against server rate, offline; prints the table and draws the chart."""
    ap = argparse.ArgumentParser(prog="skin-sim force-path", description=__doc__.splitlines()[0])
    ap.add_argument("--rates", type=float, nargs="+", default=list(RATES_HZ), help="server rates (Hz)")
    ap.add_argument("--latency-ms", type=float, default=1.0, help="pose-to-model delivery delay, whole device ticks (default 1)")
    ap.add_argument("--device-limits", action="store_true", help="apply the Touch's force and stiffness caps (default: off)")
    ap.add_argument("--chart", type=Path, default=None, help=f"chart path (default {OUT_CHART})")
    ap.add_argument("--docs", action="store_true", help=f"write the tracked chart {DOCS_CHART.relative_to(REPO)}")
    ap.add_argument("--no-chart", action="store_true")
    ap.add_argument("--msg-cost", action="store_true", help="measure the contact model message types instead (about 10 s)")
    ap.add_argument(
        "--device-drag",
        action="store_true",
        help="the bench-device drag offline instead: render error of the bridge (friction law, linear) and hold-last at "
        "1 kHz and 250 Hz server rates (deterministic, about 30 s)",
    )
    args = ap.parse_args(argv)
    if args.device_drag:
        print("skin-sim force-path --device-drag: the bridge's render error on the bench-device drag, offline ...", flush=True)
        print_device_drag(latency_ticks=max(int(round(args.latency_ms)), 0))
        print_closed_loop()
        print_closed_loop_press()
        return 0
    if args.docs and args.chart is not None:
        ap.error("--docs writes the tracked chart; give --docs or --chart, not both")
    chart_path = DOCS_CHART if args.docs else (args.chart or OUT_CHART)
    if args.msg_cost:
        print("skin-sim force-path --msg-cost: contact model message candidates ...", flush=True)
        print_msg_cost(5.0)
        return 0
    print("skin-sim force-path: offline server-rate lever (press, drag, release; device at 1 kHz) ...", flush=True)
    cfg = load_tissue_config(DEFAULT_PARAMS)
    t0 = time.perf_counter()
    warm_up(cfg)
    print(f"  numba warm-up {time.perf_counter() - t0:.1f} s", flush=True)
    kw = {} if args.device_limits else {"max_force_n": math.inf, "max_stiffness_n_per_m": math.inf}
    rates = sorted(args.rates, reverse=True)
    latency = max(int(round(args.latency_ms)), 0)
    limits = "on (Touch: 3.3 N, 1.02 N/mm)" if args.device_limits else "off"
    print(
        f"  device limits {limits}; model delivered {latency} tick(s) after the pose it answers; "
        "error = |F_device - F_full model at 1 kHz|, % of the scene's peak reference force"
    )
    print(f"  {'scene':8s} {'rate Hz':>7s} | {'peak N':>6s} | rendered p99 / max % | hold-last p99 / max % | ratio p99")
    results: dict[str, dict[float, dict]] = {}
    for sc in SCENES:
        for r in rates:
            res = run_scene(cfg, sc, r, latency, kw)
            results.setdefault(sc.name, {})[r] = res
            ratio = res["hold_p99_pct"] / max(res["render_p99_pct"], 0.01)  # floor: 0.01 % of peak
            bound = ">" if res["render_p99_pct"] < 0.01 else ""
            ren = f"{res['render_p99_pct']:8.2f} / {res['render_max_pct']:6.2f}"
            hold = f"{res['hold_p99_pct']:9.2f} / {res['hold_max_pct']:6.2f}"
            print(
                f"  {sc.name:8s} {r:7.0f} | {res['peak_n']:6.3f} | {ren}   | {hold}     | hold/rendered {bound}{ratio:.1f}x",
                flush=True,
            )
    if not args.no_chart:
        where = "the tracked docs (--docs)" if args.docs else "not the tracked docs (--docs writes those)"
        print(f"  chart: {chart(results, rates, chart_path, latency)}, {where}")
    return 0


# --- message type cost (issue 12: custom interface package vs a documented layout in standard messages) -------
def _layout_values(m: LocalModel) -> list[float]:
    """The 31 numbers of a contact model in the standard-message layout that was measured against the package."""
    return [
        float(m.sequence),
        *m.x0_m,
        *m.v0_m_s,
        *m.f0_n,
        *m.stiffness_n_per_m.ravel(),
        *m.damping_n_s_per_m.ravel(),
        *m.normal,
        m.validity_radius_m,
        m.time_to_live_s,
    ]


def msg_cost(duration_s: float = 3.0, rate_hz: float = 1000.0) -> dict:
    """Fill + serialize, and fill + publish to a matched reader, per message, for each candidate type at ``rate_hz``.

    Candidates: ``skin_sim_msgs/ContactModel`` (the package), ``sensor_msgs/JointState`` with the 31 numbers in
    ``position`` (stamp and frame in the header; names empty, or 31 labels), ``std_msgs/Float64MultiArray`` (no
    header) and, as the same-run baseline, ``geometry_msgs/WrenchStamped`` (the force alone, ``tool/wrench``).
    Returns {name: (fill+serialize us p50, p99, fill+publish us p50, p99, bytes)}.
    """
    import threading

    import rclpy
    from geometry_msgs.msg import WrenchStamped
    from rclpy.serialization import serialize_message
    from sensor_msgs.msg import JointState
    from skin_sim_msgs.msg import ContactModel
    from std_msgs.msg import Float64MultiArray, MultiArrayDimension

    from msgs_schema.contact_model import fill_contact_model
    from msgs_schema.convert import fill_wrench, set_stamp
    from msgs_schema.qos import PROFILES
    from skin_sim_node.ros_util import sleep_until_ns

    rng = np.random.default_rng(0)
    lm = LocalModel(
        1,
        0,
        "tissue",
        rng.normal(size=3),
        rng.normal(size=3),
        rng.normal(size=3),
        rng.normal(size=(3, 3)),
        rng.normal(size=(3, 3)),
        (0, 0, 1),
        DEFAULT_VALIDITY_RADIUS_M,
        DEFAULT_TTL_S,
    )
    labels = [f"v{i}" for i in range(31)]

    def fill_js(msg, t_ns, names):
        set_stamp(msg.header, t_ns)
        msg.header.frame_id = "tissue"
        if names and len(msg.name) != 31:
            msg.name = labels
        msg.position = _layout_values(lm)
        return msg

    def fill_fa(msg, t_ns):
        if not msg.layout.dim:
            msg.layout.dim = [MultiArrayDimension(label="skin_sim_contact_model_v1", size=31, stride=31)]
        msg.data = _layout_values(lm)
        return msg

    kinds = {
        "WrenchStamped (force only, baseline)": (WrenchStamped, lambda m, t: fill_wrench(m, t, "tissue", lm.f0_n)),
        "skin_sim_msgs/ContactModel": (ContactModel, lambda m, t: fill_contact_model(m, lm)),
        "JointState layout, no names": (JointState, lambda m, t: fill_js(m, t, False)),
        "JointState layout, 31 names": (JointState, lambda m, t: fill_js(m, t, True)),
        "Float64MultiArray layout (no header)": (Float64MultiArray, fill_fa),
    }
    ctx = rclpy.Context()
    rclpy.init(context=ctx)
    pub_node = rclpy.create_node(f"msg_cost_pub_{os.getpid()}", context=ctx)
    sub_node = rclpy.create_node(f"msg_cost_sub_{os.getpid()}", context=ctx)
    received = dict.fromkeys(kinds, 0)
    pubs = {}
    for i, (name, (cls, _)) in enumerate(kinds.items()):
        topic = f"msg_cost/t{i}"
        pubs[name] = pub_node.create_publisher(cls, topic, PROFILES["haptic"])
        sub_node.create_subscription(cls, topic, lambda _m, n=name: received.__setitem__(n, received[n] + 1), PROFILES["haptic"])
    ex = rclpy.executors.SingleThreadedExecutor(context=ctx)
    ex.add_node(sub_node)
    stop = threading.Event()
    th = threading.Thread(target=lambda: [ex.spin_once(timeout_sec=0.05) for _ in iter(stop.is_set, True)], daemon=True)
    th.start()
    time.sleep(1.0)  # discovery
    msgs = {name: cls() for name, (cls, _) in kinds.items()}
    ser = {name: [] for name in kinds}
    pub = {name: [] for name in kinds}
    size = {}
    n = int(duration_s * rate_hz)
    period = int(1e9 / rate_hz)
    nxt = time.perf_counter_ns()
    order = list(kinds.items())
    for k in range(n):
        nxt += period
        sleep_until_ns(nxt)
        j = k % len(order)
        for name, (_, fill) in order[j:] + order[:j]:  # interleaved, first place rotating: the same machine state for all
            t0 = time.perf_counter_ns()
            b = serialize_message(fill(msgs[name], t0))
            t1 = time.perf_counter_ns()
            pubs[name].publish(fill(msgs[name], t1))
            t2 = time.perf_counter_ns()
            ser[name].append(t1 - t0)
            pub[name].append(t2 - t1)
            size[name] = len(b)
    time.sleep(0.3)
    stop.set()
    th.join(timeout=2)
    out = {}
    for name in kinds:
        s, p = np.array(ser[name]) * 1e-3, np.array(pub[name]) * 1e-3
        out[name] = (
            np.percentile(s, 50),
            np.percentile(s, 99),
            np.percentile(p, 50),
            np.percentile(p, 99),
            size[name],
            received[name] / n,
        )
    pub_node.destroy_node()
    sub_node.destroy_node()
    rclpy.try_shutdown(context=ctx)
    return out


def print_msg_cost(duration_s: float) -> None:
    """Print the per-message fill, serialize and publish cost of the candidate message types at 1 kHz."""
    print(
        f"  message cost at 1 kHz for {duration_s:.0f} s, one matched reader in this process, types interleaved "
        "(shared machine: read the ratios to the WrenchStamped baseline of the same run)"
    )
    res = msg_cost(duration_s)
    base = res["WrenchStamped (force only, baseline)"]
    print(f"  {'type':40s} | fill+serialize us p50 / p99 | fill+publish us p50 / p99 (x baseline p50) | bytes | received")
    for name, (s50, s99, p50, p99, nbytes, rx) in res.items():
        print(
            f"  {name:40s} | {s50:7.1f} / {s99:7.1f}            | {p50:7.1f} / {p99:7.1f} ({p50 / base[2]:.2f}x)"
            f"                | {nbytes:5d} | {100 * rx:.1f} %"
        )


if __name__ == "__main__":
    raise SystemExit(main())
