"""Presliding friction (issue 30): the law's kernels, its place in the layered kernel and the session, its passivity,
live equals offline whatever the twists, the anchor through a stall, the device's renderer and the figures' numbers.

Deterministic: no ROS graph, no wall clock.
"""

from __future__ import annotations

import math

import numpy as np
import pytest
from conftest import kernel

from msgs_schema.contact_model import fill_contact_model_from_tick, read_contact_model
from msgs_schema.tissue import TANGENTIAL_STIFFNESS_N_PER_M
from skin_sim_lab.perf import friction_path as fp
from skin_sim_lab.perf.force_path import _plain_contact_model_msg, closed_loop_drag, device_drag, stick_flips
from skin_sim_node.device.render import ContactRenderer, presliding_update
from skin_sim_node.model import SkinModel
from skin_sim_node.model import friction as fr
from skin_sim_node.model.layout import OUT_ANCHORED, OUT_ZX, OUT_ZZ
from skin_sim_node.session import HapticSession, SessionParams
from skin_sim_node.tools import make_tool

MS = 1_000_000
T0 = 1_700_000_000 * 1_000_000_000


def _unit(rng):
    n = rng.normal(size=3)
    return n / np.linalg.norm(n)


# --- the kernels against the reference -----------------------------------------------------------------------------
def test_presliding_step_matches_the_reference(compiled, rng):
    step = kernel(fr.presliding_step, compiled)
    for _ in range(300):
        n = _unit(rng)
        p, z = rng.normal(scale=2e-3, size=3), rng.normal(scale=2e-3, size=3)
        k_t = float(rng.choice([0.0, rng.uniform(10, 2000)]))
        limit = float(rng.choice([0.0, rng.uniform(0.0, 2.0)]))
        zx, zy, zz, fx, fy, fz, slip = step(*p, *n, *z, k_t, limit)
        z_ref, f_ref, slip_ref = fr.presliding_reference(p, n, z, k_t, limit)
        np.testing.assert_allclose((zx, zy, zz), z_ref, rtol=0, atol=1e-15)
        np.testing.assert_allclose((fx, fy, fz), f_ref, rtol=1e-12, atol=1e-15)
        assert slip == pytest.approx(slip_ref, rel=1e-9, abs=1e-15)
        f = np.array((fx, fy, fz))
        assert abs(f @ n) <= 1e-12 * (1 + np.linalg.norm(f))  # tangential
        assert np.linalg.norm(f) <= max(limit, 0.0) * (1 + 1e-12) + 1e-15  # inside the slip level


def test_device_update_is_the_kernel_bit_for_bit(compiled, rng):
    step = kernel(fr.presliding_step, compiled)
    for _ in range(200):
        n, p, z = _unit(rng), rng.normal(scale=2e-3, size=3), rng.normal(scale=2e-3, size=3)
        k_t, limit = float(rng.uniform(10, 2000)), float(rng.uniform(0, 1))
        assert presliding_update(p, n, z, k_t, limit) == step(*p, *n, *z, k_t, limit)


def _law_force(p, n, z, k_t, mu, fn0, grad, x0):
    fn = fn0 + grad @ (p - x0)
    _, f_ref, _ = fr.presliding_reference(p, n, z, k_t, mu * max(fn, 0.0))
    return fn * n + f_ref


def test_presliding_tangent_matches_differences_of_the_law(compiled, rng):
    tangent = kernel(fr.presliding_tangent, compiled)
    for sticking in (True, False):
        for _ in range(30):
            n = _unit(rng)
            grad = rng.normal(scale=500.0, size=3)
            k_t, mu, fn0 = float(rng.uniform(50, 1000)), float(rng.uniform(0.1, 1.0)), float(rng.uniform(0.2, 2.0))
            x0 = np.zeros(3)
            r = mu * fn0 / k_t
            u = rng.normal(size=3)
            u -= (u @ n) * n
            u /= np.linalg.norm(u)
            z0 = x0 - (0.5 if sticking else 1.0) * r * u  # stretch s = x0 - z0 (tangential)
            s = x0 - z0
            k = np.empty((3, 3))
            tangent(n, s, k_t, mu, fn0, grad, k)
            # central differences in stick; in a slip, one-sided ones along directions d that keep it slipping (the
            # trial stretch grows faster than the slip distance: u . d > mu grad . d / k_t)
            h = 1e-9 * r

            def law(x, n=n, z0=z0, k_t=k_t, mu=mu, fn0=fn0, grad=grad, x0=x0):
                return _law_force(x, n, z0, k_t, mu, fn0, grad, x0)

            if sticking:
                fd = np.column_stack([(law(x0 + h * e) - law(x0 - h * e)) / (2 * h) for e in np.eye(3)])
                np.testing.assert_allclose(k, fd, rtol=1e-5, atol=1e-4 * (k_t + np.abs(grad).max()))
            else:
                for _ in range(5):
                    d = rng.normal(size=3)
                    if u @ d <= mu * (grad @ d) / k_t + 0.1:
                        d = -d
                    if u @ d <= mu * (grad @ d) / k_t + 0.1:
                        continue
                    fd = (law(x0 + h * d) - law(x0)) / h
                    np.testing.assert_allclose(k @ d, fd, rtol=1e-4, atol=1e-4 * (k_t + np.abs(grad).max()))
            np.testing.assert_allclose(k.T @ n, grad, rtol=1e-12, atol=1e-9)  # K^T n = grad F_n, exactly


# --- passivity: the slip update dissipates ----------------------------------------------------------------------------
@pytest.mark.parametrize("seed", range(6))
def test_closed_paths_dissipate(seed):
    """Random closed tangential paths from rest (anchor at the tool), any step size: the work the tool does against
    the friction, sum of -F(x_k) . dx_k (the force of the step's end, as a sampled device applies it), is at least
    the stored energy left, k_t |s|^2 / 2 >= 0, and exceeds it by the sum of the slip updates' dissipation."""
    rng = np.random.default_rng(seed)
    n = _unit(rng)
    k_t, limit = float(rng.uniform(100, 1000)), float(rng.uniform(0.1, 1.0))
    pts = rng.normal(scale=3 * limit / k_t, size=(int(rng.integers(5, 60)), 3))
    path = np.vstack([np.zeros(3), pts, np.zeros(3)])  # closed
    z = np.zeros(3)
    work = dissipated = 0.0
    for a, b in zip(path[:-1], path[1:]):
        zx, zy, zz, fx, fy, fz, slip = fr.presliding_step(*b, *n, *z, k_t, limit)
        f = np.array((fx, fy, fz))
        work += -f @ (b - a)
        s = -f / k_t
        dissipated += k_t * s @ (np.array((zx, zy, zz)) - z)  # k_t s . dz = k_t r (|s_trial| - r) >= 0
        z = np.array((zx, zy, zz))
    stored = 0.5 * k_t * (s @ s)
    assert dissipated >= 0.0
    assert work >= stored + dissipated - 1e-12 * (1 + abs(work))
    assert work >= -1e-15


def test_reversal_loop_area_is_positive_at_1khz_and_250hz(default_cfg):
    for hz in fp.REVERSAL_RATES_HZ:
        r = fp.reversal(hz, cfg=default_cfg)  # the second cycle: the steady loop
        assert r["area_j"] > 0.0
        assert r["area_j"] == pytest.approx(r["expected_j"], rel=0.05)


# --- the figures' numbers -------------------------------------------------------------------------------------------
@pytest.mark.parametrize(("freq", "amp"), fp.TREMORS)
def test_tremor_is_elastic_with_the_sign_of_the_displacement(default_cfg, freq, amp):
    r = fp.tremor(freq, amp, cfg=default_cfg)
    k_t = default_cfg.tangential_stiffness_n_per_m
    assert r["amplitude_n"] == pytest.approx(k_t * amp, rel=0.01)
    assert r["amplitude_n"] < r["slip_level_n"]
    assert r["elastic_error_n"] <= 1e-12  # F_x = -k_t x exactly: the skin sticks
    assert r["sign_follows_displacement"] == 1.0
    assert r["flips_at_velocity_zero"] == 0
    # today's law in the same run flips at every velocity zero, its sign the velocity's, not the displacement's
    assert r["legacy_flips_at_velocity_zero"] == r["velocity_zero_crossings"] > 0
    assert r["legacy_sign_follows_displacement"] < 0.6
    assert r["legacy_amplitude_n"] > 10 * r["amplitude_n"]


@pytest.mark.parametrize("speed", fp.DRAG_SPEEDS_M_S)
def test_drag_slides_at_mu_fn_after_the_presliding_distance(default_cfg, speed):
    r = fp.drag(speed, cfg=default_cfg)
    assert abs(r["ratio"] - 1.0) <= 0.05 and abs(r["ratio_min"] - 1.0) <= 0.05
    lo, hi = r["band_m"]
    assert lo <= r["presliding_m"] * (1 + 1e-9) and r["presliding_m"] <= hi
    assert r["presliding_m"] <= lo + speed * 1e-3 * 1.001  # within one tick's travel of mu F_n / k_t


def test_default_tangential_stiffness_is_the_mindlin_ratio_of_the_punch():
    nu = 0.48
    assert TANGENTIAL_STIFFNESS_N_PER_M == pytest.approx(2 * (1 - nu) / (2 - nu) * 326.3, abs=0.05)


# --- the session: live equals offline, the anchor's life ---------------------------------------------------------------
def _press_path(k):
    t = k * 1e-3
    x = 1e-3 * math.sin(2 * math.pi * 1.5 * max(t - 0.4, 0.0)) if t > 0.4 else 0.0
    return (x, 0.3 * x, -1.5e-3 * min(t / 0.3, 1.0))


def _run(cfg, n, twists: str, sphere=False):
    s = HapticSession(make_tool(cfg), SessionParams(max_stamp_age_s=0.0))
    rng = np.random.default_rng(1)
    out = []
    for k in range(n):
        stamp = T0 + k * MS
        pos = _press_path(k)
        if twists == "all" or (twists == "some" and rng.random() < 0.5):
            s.on_twist(stamp, "tissue", tuple(rng.normal(scale=0.05, size=3)))  # any velocity: none enters the force
        s.on_pose(stamp, "tissue", pos)
        out.append(s.tick(stamp, MS).force_n)
    return np.array(out)


@pytest.mark.parametrize("shape", ["flat", "sphere"])
def test_same_poses_give_the_same_force_bit_for_bit_whatever_the_twists(default_cfg, shape):
    cfg = default_cfg.replace(**{"tool.shape": shape})
    a, b, c = (_run(cfg, 1200, t) for t in ("all", "none", "some"))
    assert np.abs(a[:, 0]).max() > 0.01  # friction acts
    assert np.array_equal(a, b) and np.array_equal(a, c)


def test_anchor_persists_through_a_stall_and_resets_on_lift_off(default_cfg):
    p = SessionParams(max_stamp_age_s=0.0)
    s = HapticSession(make_tool(default_cfg), p)
    k = 0
    for k in range(700):  # press 1.5 mm and stretch the skin 0.5 mm sideways (stick)
        stamp = T0 + k * MS
        s.on_pose(stamp, "tissue", (0.5e-3 * min(max(k - 500, 0) / 100, 1.0), 0.0, -1.5e-3 * min(k / 300, 1.0)))
        r = s.tick(stamp, MS)
    before = np.array(r.force_n)
    anchor = s.model.state()["_out"][OUT_ZX : OUT_ZZ + 1].copy()
    assert before[0] < -0.1
    # a stall: no pose for 200 ms, the watchdog fires (force zero, tissue released)
    now = T0 + k * MS
    for j in range(1, 201):
        r = s.tick(now + j * MS, MS)
    assert r.stale and not any(r.force_n)
    np.testing.assert_array_equal(s.model.state()["_out"][OUT_ZX : OUT_ZZ + 1], anchor)
    # the hand kept still: the sideways force returns with the old anchor (the stretch was kept)
    stamp = now + 201 * MS
    s.on_pose(stamp, "tissue", (0.5e-3, 0.0, -1.5e-3), now_ns=stamp)
    r = s.tick(stamp, MS)
    assert r.force_n[0] == pytest.approx(-default_cfg.tangential_stiffness_n_per_m * 0.5e-3, rel=1e-9)
    # a true lift-off lets go: the next contact starts its anchor at the tool, no sideways force at once
    for j in range(1, 300):
        stamp += MS
        z = -1.5e-3 + 3.5e-3 * min(j / 50, 1.0) if j < 250 else -1.5e-3 + 3.5e-3 * max(1.0 - (j - 250) / 40, 0.0)
        s.on_pose(stamp, "tissue", (0.5e-3, 0.0, z), now_ns=stamp)
        r = s.tick(stamp, MS)
        if j == 100:
            assert s.model.state()["_out"][OUT_ANCHORED] == 0.0
    assert abs(r.force_n[0]) < 1e-12


def test_contact_model_carries_anchor_stiffness_and_slip_level_and_renders_f0_at_x0(default_cfg):
    s = HapticSession(make_tool(default_cfg), SessionParams(max_stamp_age_s=0.0))
    msg = _plain_contact_model_msg()
    checked = 0
    for k in range(1200):
        stamp = T0 + k * MS
        pos = _press_path(k)
        s.on_pose(stamp, "tissue", pos)
        r = s.tick(stamp, MS)
        m = read_contact_model(fill_contact_model_from_tick(msg, r, stamp, "tissue"))
        if not r.tangent.in_contact:
            assert m.tangential_stiffness_n_per_m == 0.0 and m.slip_speed_m_s == 0.0
            continue
        assert m.tangential_stiffness_n_per_m == default_cfg.tangential_stiffness_n_per_m
        assert m.slip_force_n == pytest.approx(default_cfg.friction_coefficient * m.normal_force_n, rel=1e-12)
        assert not m.damping_n_s_per_m.any() and m.slip_speed_m_s == 0.0  # no velocity in the law
        ren = ContactRenderer(max_force_n=math.inf, max_stiffness_n_per_m=math.inf)
        ren.set_model(m, 0.0)
        for j in range(25):  # past the blend in from zero, at x0: the law gives f0
            f = ren.render(j * 1e-3, m.x0_m)
        np.testing.assert_allclose(f, m.f0_n, rtol=1e-12, atol=1e-14)
        checked += 1
        if checked > 40:
            break
    assert checked > 40


# --- at the device --------------------------------------------------------------------------------------------------
def test_device_drag_renders_within_5_percent_and_needs_no_velocity():
    law = device_drag(250.0, periods=1)
    nov = device_drag(250.0, periods=1, device_velocity=False)
    assert law["render_p99_pct"] <= 5.0 and law["render_p99_pct"] < law["hold_p99_pct"]
    np.testing.assert_array_equal(law["f_render"], nov["f_render"])  # positions alone


def test_closed_loop_presliding_has_no_friction_flips_and_the_chatter_guard_never_engages():
    """The bridge's renderer (chatter guard on) with the stylus in the loop: the presliding law never flips the
    sideways force over the slide and the guard never engages; issue 19's velocity law in the same run does both."""
    f, r = closed_loop_drag()
    assert r.counts_chatter == 0 and stick_flips(f[:, 0]) == 0
    assert r.passivity.energy_j > 0 and r.passivity.active_ticks == 0
    old, r_old = closed_loop_drag({"stick_slope_n_s_per_m": math.inf}, legacy=True)
    assert stick_flips(old[:, 0]) > 10
    _, r_guard = closed_loop_drag(legacy=True)
    assert r_guard.counts_chatter > 0  # the chatter_guard parameter still works on the velocity law


def test_renderer_caps_the_tangential_stiffness_and_keeps_f0(default_cfg):
    s = HapticSession(make_tool(default_cfg), SessionParams(max_stamp_age_s=0.0))
    msg = _plain_contact_model_msg()
    for k in range(700):
        stamp = T0 + k * MS
        s.on_pose(stamp, "tissue", _press_path(k))
        r = s.tick(stamp, MS)
    m = read_contact_model(fill_contact_model_from_tick(msg, r, stamp, "tissue"))
    cap = 50.0
    ren = ContactRenderer(max_force_n=math.inf, max_stiffness_n_per_m=cap)
    ren.set_model(m, 0.0)
    for j in range(25):
        f0 = ren.render(j * 1e-3, m.x0_m)
    np.testing.assert_allclose(f0, m.f0_n, rtol=1e-9, atol=1e-12)
    u = np.array([0.0, 1.0, 0.0])
    f1 = ren.render(0.026, m.x0_m + 1e-5 * u)
    assert np.linalg.norm(f1 - f0) / 1e-5 <= cap * (1 + 1e-6)


def test_zero_tangential_stiffness_means_no_friction(default_cfg):
    c = default_cfg.replace(**{"contact.tangential_stiffness_n_per_m": 0.0})
    m = SkinModel(c)
    for k in range(800):
        m.step(_press_path(k), (0, 0, 0), 1e-3)
    f = m.force_vector_n
    assert abs(f[0]) < 1e-15  # k_t 0: no friction


def test_live_view_header_carries_the_friction_anchor(default_cfg):
    """The view draws the anchor (issue 30) from tool/contact_model: the live source's header carries it in contact
    with the presliding law, and not without one."""
    from skin_sim_node.view.live import LiveSource

    s = HapticSession(make_tool(default_cfg), SessionParams(max_stamp_age_s=0.0))
    msg = _plain_contact_model_msg()
    src = LiveSource.__new__(LiveSource)  # no rclpy: only the header
    src.pose = src.wrench = src.contact = None
    src.form, src.frames = "layered", 0
    assert "anchor" not in src.header()
    for k in range(700):
        stamp = T0 + k * MS
        s.on_pose(stamp, "tissue", _press_path(k))
        r = s.tick(stamp, MS)
    src.contact_model = fill_contact_model_from_tick(msg, r, stamp, "tissue")
    np.testing.assert_array_equal(src.header()["anchor"], r.tangent.friction_anchor_m)
    src.contact_model = fill_contact_model_from_tick(msg, s.tick(stamp + 200 * MS, MS), stamp, "tissue")  # stale
    assert "anchor" not in src.header()


def test_closed_loop_press_kicked_sideways_settles_with_presliding():
    """The demo's press with the stylus in the loop, kicked sideways at 5 mm/s during the hold: the presliding law
    rings elastically (k_t times the stylus' excursion) and settles; issue 19's velocity law swings +-mu F_n."""
    from skin_sim_lab.perf.force_path import print_closed_loop_press

    out = print_closed_loop_press()
    fmin, fmax, fx_max, fx_late, _, guard = out["presliding law"]
    assert fx_max < 0.02 and fx_late < 1e-3 and guard == 0 and fmax - fmin < 0.05
    assert out["velocity law"][2] > 0.1 and out["velocity law"][2] > 10 * fx_max
