"""The needle's physics reference (issue 22, first cut; skin_sim_node/model/needle.py): puncture per layer at
``lambda Gamma d``, latched track, cutting, Dahl shaft friction, oblique tracks through the egg-carton, passivity."""

from __future__ import annotations

import math

import numpy as np
import pytest

from skin_sim_node.model.config import preset
from skin_sim_node.model.needle import (
    GAUGE_OUTER_DIAMETER_M,
    RENDER_STIFFNESS_N_PER_M,
    TIP_FRICTION_COEFFICIENT,
    NeedleModel,
    NeedleParams,
)


@pytest.fixture(scope="module")
def cfg():
    return preset("default")


def drive(m, path, axis=(0.0, 0.0, -1.0)):
    return [m.step(p, axis) for p in path]


def straight(z0, z1, n):
    return [(0.0, 0.0, z) for z in np.linspace(z0, z1, n)]


def test_skin_peak_is_the_dermis_threshold_and_scales_with_the_diameter(cfg):
    """Straight in at the centre: the peak is the dermis' rupture, lambda Gamma_D d; 18 G meets the cadaver skin
    peak 2.75-2.80 N (J Endourol, doi 10.1089/end.2016.0342); the peak grows with the diameter (Maloney)."""
    peaks = {}
    for g in (18, 21, 25):
        m = NeedleModel(cfg, NeedleParams.gauge(g))
        ticks = drive(m, straight(0.2e-3, -6e-3, 24801))  # 0.25 um steps: the dimple near the bottom is steep
        peaks[g] = max(t.axial_n for t in ticks)
        assert peaks[g] == pytest.approx(m.params.puncture_force_n(1), rel=2e-3)
        assert ticks[-1].ruptured == 3
        events = [t.punctured for t in ticks if t.punctured]
        assert [p for e in events for p in e] == [0, 1, 2]  # layer by layer, never twice
    assert 2.75 <= peaks[18] <= 2.80
    ratios = [peaks[g] / GAUGE_OUTER_DIAMETER_M[g] for g in (18, 21, 25)]
    assert max(ratios) == pytest.approx(min(ratios), rel=2e-3)


def test_the_drop_is_one_tick_and_the_fat_is_weaker_than_the_skin(cfg):
    m = NeedleModel(cfg, NeedleParams.gauge(21))
    ticks = drive(m, straight(0.2e-3, -6e-3, 6201))
    k = next(i for i, t in enumerate(ticks) if 1 in t.punctured)
    assert ticks[k].axial_n < 0.25 * ticks[k - 1].axial_n  # the dermis drop lands within its tick
    assert m.params.puncture_force_n(2) < 0.2 * m.params.puncture_force_n(1) * 1.0001  # fat threshold < 20 % of skin's


def test_the_track_is_latched_until_the_needle_leaves(cfg):
    """Back 1 mm and in again: friction and then cutting at the old front, no second peak; out of the tissue and in
    again: the dimple and the peak come back."""
    m = NeedleModel(cfg, NeedleParams.gauge(21))
    first = drive(m, straight(0.2e-3, -5.6e-3, 5801))  # past the last rupture (5.23 mm at 21 G)
    assert first[-1].ruptured == 3
    back = drive(m, straight(-5.6e-3, -4.6e-3, 1001))
    again = drive(m, straight(-4.6e-3, -5.6e-3, 1001))
    cut = m.params.cutting_ratio * m.params.puncture_force_n(2)
    assert max(t.axial_n for t in again) <= cut + max(abs(t.friction_n) for t in again) + 1e-9
    assert min(t.axial_n for t in back) < 0.0  # the shaft's friction holds the needle on the way out
    out = drive(m, straight(-5.6e-3, 0.5e-3, 6101))
    assert out[-1].insertion_m == 0.0 and not m.inserted
    second = drive(m, straight(0.2e-3, -5.6e-3, 5801))
    assert max(t.axial_n for t in second) == pytest.approx(max(t.axial_n for t in first), rel=1e-9)


def test_friction_is_rate_independent_and_dissipative(cfg):
    """Dahl's law depends on positions only: the same path at any speed gives the same forces; an insert-retract
    cycle takes work from the hand (>= 0), with the puncture and cutting energies on top."""
    a, b = NeedleModel(cfg, NeedleParams.gauge(21)), NeedleModel(cfg, NeedleParams.gauge(21))
    path = straight(0.2e-3, -5.5e-3, 1141) + straight(-5.5e-3, 0.3e-3, 1161)
    fa = [t.axial_n for t in drive(a, path)]
    fb = [t.axial_n for t in drive(b, path[::1])]
    np.testing.assert_array_equal(fa, fb)
    c = NeedleModel(cfg, NeedleParams.gauge(21))
    work, z_prev, f_prev = 0.0, path[0][2], 0.0
    for p in path:
        t = c.step(p, (0.0, 0.0, -1.0))
        work += 0.5 * (t.axial_n + f_prev) * (z_prev - p[2])  # axial force along -z times the insertion step
        f_prev, z_prev = t.axial_n, p[2]
    assert work > 0.0


@pytest.mark.parametrize("angle_deg", [30.0, 60.0])
def test_oblique_tracks_meet_the_interfaces_along_the_axis(cfg, angle_deg):
    """At 30 and 60 degrees below the surface the axis meets each interface at depth / sin(angle) along it (to the
    egg-carton's amplitude), the threshold is on the tent's normal reaction ``N``, and at the peak the force is that
    reaction plus the tip's friction on the tent (``N e_z + f_t``, issue 31 and its review), not along the axis."""
    th = math.radians(angle_deg)
    u = np.array([math.cos(th), 0.0, -math.sin(th)])
    m = NeedleModel(cfg, NeedleParams.gauge(21))
    start = np.array([0.0, 0.0, 0.0]) - 0.2e-3 * u
    ticks = [m.step(start + s * u, u) for s in np.linspace(0.0, 14e-3, 7001)]
    top_fat = cfg.interfaces[1]
    assert m.crossings[2] * math.sin(th) == pytest.approx(top_fat.mean_depth_m, abs=top_fat.amplitude_m + 1e-6)
    peak = max(ticks, key=lambda t: t.normal_n)
    assert peak.normal_n == pytest.approx(m.params.puncture_force_n(1), rel=5e-3)
    c = peak.tangential_n / peak.normal_n
    assert 0.0 < c <= TIP_FRICTION_COEFFICIENT * (1.0 + 1e-12)
    expect = np.array([-c, 0.0, 1.0]) / math.hypot(1.0, c)
    # to the cut epidermis' shaft friction along the axis (< 0.1 % of the force)
    np.testing.assert_allclose(peak.force_n / np.linalg.norm(peak.force_n), expect, atol=2e-3)


def test_the_crossing_depth_follows_the_egg_carton(cfg):
    """Straight in at a fat peak and at a fat valley: the fat's top is met 2 x its amplitude apart."""
    i = cfg.interfaces[1]
    depths = []
    for x in (0.0, 0.5 * i.wavelength_x_m):
        m = NeedleModel(cfg)
        m.step((x, 0.0, -1e-6), (0.0, 0.0, -1.0))
        depths.append(m.crossings[2])
    assert abs(depths[1] - depths[0]) == pytest.approx(2 * i.amplitude_m, rel=1e-3)


def test_the_shaft_is_held_in_its_track(cfg):
    """Inserted 3 mm, the tip moved 0.1 mm sideways: a restoring lateral force, growing with the inserted length."""
    m = NeedleModel(cfg, NeedleParams.gauge(21))
    drive(m, straight(0.2e-3, -5.4e-3, 2801))
    t = m.step((1e-4, 0.0, -5.4e-3), (0.0, 0.0, -1.0))
    assert t.lateral_n[0] < 0.0 and abs(t.lateral_n[1]) < 1e-12


def test_a_shallow_needle_starts_no_track(cfg):
    m = NeedleModel(cfg)
    u = np.array([math.cos(math.radians(5.0)), 0.0, -math.sin(math.radians(5.0))])
    assert not np.any(m.step((0.0, 0.0, -1e-4), u).force_n) and not m.inserted


# --- issue 31: oblique insertion from the tent's contact, withdrawal -------------------------------------------------


def along(u, s_from, s_to, n, x0=0.0):
    """Tips along the axis ``u`` through ``(x0, 0, 0)`` from axis length ``s_from`` to ``s_to`` (m)."""
    return [np.array([x0, 0.0, 0.0]) + s * u for s in np.linspace(s_from, s_to, n)]


def axis_deg(deg):
    th = math.radians(deg)
    return np.array([math.cos(th), 0.0, -math.sin(th)])


def to_puncture(cfg, deg, gauge=21):
    """Insert along the axis until the skin (dermis) ruptures; the tick at the largest axial force before it."""
    u = axis_deg(deg)
    m = NeedleModel(cfg, NeedleParams.gauge(gauge))
    peak = None
    for p in along(u, -0.2e-3, 25e-3, 25201):
        t = m.step(p, u)
        if m.ruptured >= 2:
            break
        if peak is None or t.normal_n > peak[0].normal_n:
            peak = (t, p, t.tangential_n >= (1.0 - 1e-9) * TIP_FRICTION_COEFFICIENT * t.normal_n > 0.0)
    return m, u, peak


@pytest.mark.parametrize("deg", [90.0, 60.0, 45.0, 30.0, 15.0])
def test_the_puncture_is_on_the_tents_normal_reaction_and_the_friction_is_capped(cfg, deg):
    """Before the skin gives, the force is ``N e_z + f_t``: ``N`` from the tip's normal depth, ``f_t`` the presliding
    friction of the tip on the tent, ``|f_t| <= mu N``. The skin ruptures when ``N`` reaches ``lambda Gamma d`` at every
    angle (the normal load at rupture does not depend on the angle; the axial force there is
    ``N sin(theta) + |f_t| cos(theta)``, at 90 degrees ``N``: the vertical calibration unchanged), and the force's
    angle to the axis is ``90 - theta - atan(|f_t| / N)`` degrees."""
    m, u, (t, p, _) = to_puncture(cfg, deg)
    th = math.radians(deg)
    fp = m.params.puncture_force_n(1)
    assert t.normal_n == pytest.approx(fp, rel=2e-3)
    assert t.tangential_n <= TIP_FRICTION_COEFFICIENT * t.normal_n * (1.0 + 1e-12)
    c = t.tangential_n / t.normal_n
    assert t.dimple_n == pytest.approx(t.normal_n * (math.sin(th) + c * math.cos(th)), rel=1e-9)
    if deg == 90.0:
        assert t.tangential_n < 1e-12 and t.axial_n == pytest.approx(fp, rel=2e-3)
    angle = math.degrees(math.acos(-t.force_n @ u / np.linalg.norm(t.force_n)))
    # to the cut epidermis' shaft friction along the axis (< 0.2 % of the force: its 0.29 mm at 15 degrees)
    assert angle == pytest.approx(90.0 - deg - math.degrees(math.atan(c)) if deg < 90.0 else 0.0, abs=0.1)
    assert np.linalg.norm(t.tent_lateral_n) == pytest.approx(np.linalg.norm(t.force_n) * math.sin(math.radians(angle)), rel=1e-6)


def test_at_15_degrees_the_tip_skates_and_the_skin_holds_only_friction(cfg):
    """The issue's case: at a shallow angle the skin holds along its surface no more than ``mu N`` (not a force along
    the axis): the tip skates (its anchor is dragged at the cap) and the force is far off the axis. At 30 degrees the
    stiffening tent's growing ``mu N`` catches the spring again before the rupture: just under the cap."""
    _, u, (t, _, skating) = to_puncture(cfg, 15.0)
    assert skating
    assert t.tangential_n == pytest.approx(TIP_FRICTION_COEFFICIENT * t.normal_n, rel=1e-9)
    assert abs(t.force_n[0]) == pytest.approx(t.tangential_n, rel=0.02)  # plus the cut epidermis' shaft friction
    assert math.degrees(math.acos(-t.force_n @ u / np.linalg.norm(t.force_n))) > 45.0
    _, u, (t, _, _) = to_puncture(cfg, 30.0)
    assert 0.9 * TIP_FRICTION_COEFFICIENT * t.normal_n < t.tangential_n <= TIP_FRICTION_COEFFICIENT * t.normal_n
    assert math.degrees(math.acos(-t.force_n @ u / np.linalg.norm(t.force_n))) > 30.0


def _loop_work(cfg, deg, reverse, via):
    from skin_sim_lab.validation.needle_angle import loop_energy

    return loop_energy(cfg, deg, reverse, via, cycles=2)


@pytest.mark.parametrize("deg", [70.0, 45.0, 30.0])
@pytest.mark.parametrize("reverse", [False, True])
def test_a_closed_loop_of_the_tip_on_the_tent_returns_no_energy(cfg, deg, reverse):
    """Issue 31's review: a closed 1 x 1.15 mm loop in x-z of a tip pressing the tent (nothing ruptured) took energy from
    nowhere (+57 to +252 uJ a cycle before: the tangential force depended on the axial dimple only, and the tool's
    track restarts re-stuck it). Now ``N`` is a function of the tip's depth (a potential) and the friction a presliding
    anchor kept across the restarts (passive): the model and the tool take energy from the hand, either way round."""
    for via in ("model", "tool"):
        works = _loop_work(cfg, deg, reverse, via)
        assert max(works) <= 1e-9, (via, works)
        assert max(works) < -1e-5  # the tip drags its anchor: friction dissipates


def test_a_closed_loop_through_the_session_returns_no_energy(cfg):
    """The same loop through the haptic session at 1 kHz (each published force held over the next 1 um move)."""
    for reverse in (False, True):
        assert max(_loop_work(cfg, 45.0, reverse, "session")) <= 1e-9


def test_a_tent_keeps_its_anchor_across_the_tools_track_restarts(cfg):
    """Before the first rupture the tool restarts the track under a tip moved off it; the tent's anchor (the skin's
    stuck point) stays where it was, so a sideways move within the slip distance meets a spring, not a fresh contact."""
    from skin_sim_node.tools import make_tool
    from skin_sim_node.tools.base import ToolPose

    tool = make_tool(cfg.replace(**{"tool.shape": "needle"}))
    u = tuple(axis_deg(90.0).tolist())
    for z in np.linspace(1e-4, -1e-3, 1101):
        tool.step(ToolPose((0.0, 0.0, float(z)), (0.0, 0.0, 0.0), u, 1e-3, False))
    a0 = tool.needle.anchor.copy()
    f = [tool.step(ToolPose((x, 0.0, -1e-3), (0.0, 0.0, 0.0), u, 1e-3, False)).force_n[0] for x in np.linspace(0.0, 2e-6, 3)]
    np.testing.assert_array_equal(tool.needle.anchor, a0)  # stuck: the restarts kept it
    from skin_sim_node.model.layout import NL_TENT_K

    k_t = tool.needle.nlp[NL_TENT_K, 0]  # the epidermis' tent
    assert f[-1] == pytest.approx(-k_t * 2e-6, rel=1e-9)


@pytest.mark.parametrize("deg", [90.0, 30.0])
def test_a_tent_pressed_and_released_takes_energy_from_the_hand(cfg, deg):
    """In 1.5 mm along the axis (nothing ruptures) and back out: the stuck tent is elastic (the work returns), a skating
    one dissipates (the tissue does net negative work on the needle)."""
    u = axis_deg(deg)
    m = NeedleModel(cfg, NeedleParams.gauge(21))
    path = along(u, -0.1e-3, 1.5e-3, 1601) + along(u, 1.5e-3, -0.1e-3, 1601)
    work, f_prev, p_prev = 0.0, np.zeros(3), path[0]
    for p in path:
        t = m.step(p, u)
        work += float(0.5 * (f_prev + t.force_n) @ (p - p_prev))  # trapezoid: an elastic loop closes to rounding
        f_prev, p_prev = t.force_n, p
        assert m.ruptured == 0
    assert work <= 1e-9
    if deg < 53.0:
        assert work < -1e-5  # skating: friction's loop


def test_withdrawal_resists_within_the_rendered_fades_and_the_cycle_is_dissipative(cfg):
    """21 G through every layer to 4.5 mm, then out: the outward push at the reversal lasts only as long as the cutting
    fade ``beta F_p / K_render`` and the Dahl reversal ``x_0 ln 2`` (< 0.2 mm, 0.5-0.6 mm before issue 31), returns
    less than 25 uJ (about 40 uJ before), and the whole cycle takes energy from the hand."""
    m = NeedleModel(cfg, NeedleParams.gauge(21))
    ins = straight(0.2e-3, -5.5e-3, 5701)
    out = straight(-5.5e-3, 0.3e-3, 5801)
    work, f_prev, z_prev, returned, last_push = 0.0, 0.0, ins[0][2], 0.0, 0.0
    for i, p in enumerate(ins + out):
        t = m.step(p, (0.0, 0.0, -1.0))
        dz = z_prev - p[2]  # insertion step
        work -= f_prev * dz  # the tissue's work on the needle: the resistance against the step
        if i >= len(ins) and f_prev > 0.0:
            returned += f_prev * -dz  # withdrawing while the tissue still pushes out
            last_push = -5.5e-3 - p[2] if False else abs(p[2] + 5.5e-3)
        f_prev, z_prev = t.axial_n, p[2]
    assert m.params.cut_fade_m(2) == pytest.approx(m.params.cutting_ratio * m.params.puncture_force_n(2) / 1020.0)
    assert last_push < 0.2e-3
    assert 0.0 < returned < 25e-6
    assert work < 0.0


def test_the_render_stiffness_is_the_devices():
    from skin_sim_node.device.mapping import TOUCH_MAX_STIFFNESS_N_PER_M

    assert RENDER_STIFFNESS_N_PER_M == TOUCH_MAX_STIFFNESS_N_PER_M


def test_needle_angle_command_prints_its_tables_and_passes(capsys):
    """``skin-sim needle-angle``: the angle table, the withdrawal table and the tip-travel band, every check met."""
    from skin_sim_lab.validation import needle_angle

    assert needle_angle.main([]) == 0
    out = capsys.readouterr().out
    assert "needle_angle PASS" in out and "force to axis" in out and "Energy per insert-withdraw cycle" in out
