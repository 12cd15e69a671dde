"""The needle's physics reference (issue 22, first cut; skin_sim_node/model/needle.py): puncture per layer at
``lambda Gamma d``, latched track, cutting, Dahl shaft friction, oblique tracks through the egg-carton, passivity."""

from __future__ import annotations

import math

import numpy as np
import pytest

from skin_sim_node.model.config import preset
from skin_sim_node.model.needle import GAUGE_OUTER_DIAMETER_M, NeedleModel, NeedleParams


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
    egg-carton's amplitude), the threshold is on the axial force, and the needle is pushed back along its axis."""
    th = math.radians(angle_deg)
    u = np.array([math.cos(th), 0.0, -math.sin(th)])
    m = NeedleModel(cfg, NeedleParams.gauge(21))
    start = np.array([0.0, 0.0, 0.0]) - 0.2e-3 * u
    ticks = [m.step(start + s * u, u) for s in np.linspace(0.0, 14e-3, 7001)]
    top_fat = cfg.interfaces[1]
    assert m.crossings[2] * math.sin(th) == pytest.approx(top_fat.mean_depth_m, abs=top_fat.amplitude_m + 1e-6)
    peak = max(ticks, key=lambda t: t.axial_n)
    assert peak.axial_n == pytest.approx(m.params.puncture_force_n(1), rel=5e-3)
    np.testing.assert_allclose(peak.force_n / np.linalg.norm(peak.force_n), -u, atol=1e-9)


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
