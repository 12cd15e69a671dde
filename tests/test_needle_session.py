"""The needle through the session and the contract (issue 22): orientation in, the whole vector and its law out."""

from __future__ import annotations

import math

import numpy as np
import pytest

from msgs_schema.contact_model import read_contact_model
from msgs_schema.convert import fill_needle_state
from msgs_schema.parameters import SessionParams
from skin_sim_node.device.trajectories import TRAJECTORIES, needle_orientation
from skin_sim_node.model import preset
from skin_sim_node.session.events import BAD_ORIENTATION
from skin_sim_node.session.haptic import HapticSession
from skin_sim_node.session.inputs import quaternion_axis
from skin_sim_node.tools import TOOLS, FlatPunch, NeedleTool, SpherePunch, make_tool

MS = 1_000_000


def _session(shape: str = "needle", **tissue) -> HapticSession:
    cfg = preset("default").replace(**{"tool.shape": shape, **tissue})
    return HapticSession(make_tool(cfg), SessionParams())


def _insert(s: HapticSession, path: str, dt_ns: int = MS):
    """Run a needle trajectory through the session; yields (tick result, tip)."""
    traj = TRAJECTORIES[path]
    n = int(traj.duration_s * 1e9 / dt_ns)
    for k in range(1, n + 1):
        p, _ = traj.sample(k * dt_ns * 1e-9)
        assert s.on_pose(k * dt_ns, "tissue", p, quat=traj.orientation) is None
        yield s.tick(k * dt_ns, dt_ns), np.array(p)


def test_each_tool_shape_gives_its_tool():
    assert type(make_tool(preset("needle"))) is NeedleTool
    assert type(make_tool(preset("default"))) is FlatPunch
    assert type(make_tool(preset("default").replace(**{"tool.shape": "sphere"}))) is SpherePunch
    assert set(TOOLS) == {"flat", "sphere", "needle"}


def test_orientation_is_validated_for_the_needle_only():
    s = _session()
    assert s.on_pose(MS, "tissue", (0.0, 0.0, 0.001), quat=(0.0, 0.0, 0.0, 0.0)) == BAD_ORIENTATION
    assert s.on_pose(2 * MS, "tissue", (0.0, 0.0, 0.001), quat=(0.0, 0.0, 0.0, 1.1)) == BAD_ORIENTATION
    assert s.on_pose(3 * MS, "tissue", (0.0, 0.0, 0.001), quat=(0.0, 0.0, math.nan, 1.0)) is not None
    assert s.on_pose(4 * MS, "tissue", (0.0, 0.0, 0.001), quat=(0.0, 0.0, 0.0, 1.0)) is None
    assert s.counts[BAD_ORIENTATION] == 2
    flat = _session("flat")  # the flat punch ignores the orientation: a zero quaternion is no reason to drop a pose
    assert flat.on_pose(MS, "tissue", (0.0, 0.0, 0.001), quat=(0.0, 0.0, 0.0, 0.0)) is None


@pytest.mark.parametrize("deg", [90.0, 60.0, 30.0])
def test_the_paths_orientation_is_the_needles_axis(deg):
    e = math.radians(deg)
    assert quaternion_axis(*needle_orientation(e)) == pytest.approx((math.cos(e), 0.0, -math.sin(e)), abs=1e-12)


@pytest.mark.parametrize("path", ["needle_straight", "needle_oblique_30", "needle_oblique_60"])
def test_published_force_is_the_models_vector_and_its_law_gives_f0(path):
    s = _session()
    seen_law = most = 0
    for r, _ in _insert(s, path):
        most = max(most, s.tool.needle.ruptured)
        f = np.array(r.force_n)
        law = r.tangent.needle
        assert np.isfinite(f).all()
        if law is None:
            continue
        seen_law += 1
        u = np.asarray(law.axis)
        # the law's resistance at x0 is the published axial force, and K's axial part is its slope (or steeper)
        assert law.resistance_n == pytest.approx(-u @ f, abs=1e-9)
        assert u @ r.tangent.stiffness_n_per_m @ u <= 1e-9
        assert law.finite
    assert seen_law > 100
    assert most == 3  # every layer cut by 5.2 mm deep


def test_puncture_drop_is_published_within_one_tick_and_not_rate_limited():
    s = _session()
    forces = [math.hypot(*r.force_n) for r, _ in _insert(s, "needle_straight")]
    drops = np.diff(forces)
    i = int(np.argmin(drops))
    peak = forces[i]
    assert peak == pytest.approx(s.tool.needle.params.puncture_force_n(1), rel=0.01)  # the skin's (dermis) peak
    assert forces[i + 1] < 0.3 * peak  # the drop lands in one tick


def test_latched_track_on_reinsertion_and_peak_returns_after_withdrawal():
    s = _session()
    forces = np.array([math.hypot(*r.force_n) for r, _ in _insert(s, "needle_reinsert")])
    peak = s.tool.needle.params.puncture_force_n(1)
    big = np.flatnonzero(forces > 0.95 * peak)
    runs = np.split(big, np.flatnonzero(np.diff(big) > 50) + 1)
    assert len(runs) == 2  # the first insertion and the one after the withdrawal; none on the latched re-insertion


def test_needle_state_message_round_trip():
    from skin_sim_msgs.msg import NeedleState

    s = _session()
    for _ in _insert(s, "needle_oblique_30"):
        pass
    st = s.readout()
    msg = fill_needle_state(NeedleState(), st, 5 * MS, "tissue")
    assert msg.ruptured_layers == st["ruptured_layers"] and len(msg.crossing_m) == len(st["crossing_m"])
    assert list(msg.axis) == pytest.approx(list(st["axis"]))


def test_contact_model_message_carries_the_needle_law():
    from skin_sim_msgs.msg import ContactModel

    from msgs_schema.contact_model import fill_contact_model_from_tick

    s = _session()
    last = None
    for r, _ in _insert(s, "needle_straight"):
        if r.tangent.needle is not None and r.tangent.needle.rupture_distance_m > 0:
            last = r
            if math.hypot(*r.force_n) > 1.0:
                break
    assert last is not None
    lm = read_contact_model(fill_contact_model_from_tick(ContactModel(), last, last.stamp_ns, "tissue"))
    assert lm.needle is not None and lm.finite
    assert lm.needle.rupture_distance_m == pytest.approx(last.tangent.needle.rupture_distance_m)
    assert (
        lm.needle.post_rupture_force_n < lm.needle.axial_force_n + lm.needle.axial_gradient_n_per_m * lm.needle.rupture_distance_m
    )


def test_needle_check_passes_its_data_checks(capsys):
    from skin_sim_lab.validation import needle_check

    assert needle_check.main([]) == 0
    out = capsys.readouterr().out
    assert "needle_check PASS: 9 checks" in out


def _drive(s: HapticSession, tips, quat=(0.0, 0.0, 0.0, 1.0), t0: int = 0):
    """Poses at 1 kHz through the session; returns the published forces (n, 3) and the tips (n, 3)."""
    out = []
    for k, p in enumerate(tips):
        st = t0 + (k + 1) * MS
        s.on_pose(st, "tissue", tuple(float(c) for c in p), quat=quat)
        out.append(s.tick(st, MS).force_n)
    return np.array(out), np.asarray(tips, dtype=float)


def _line(a, b, n):
    return [np.asarray(a) + (np.asarray(b) - np.asarray(a)) * i / n for i in range(1, n + 1)]


def _work_j(forces, tips) -> float:
    """Work the tissue does on the needle, each force booked over the next move."""
    return float(np.einsum("ij,ij->i", forces[:-1], np.diff(tips, axis=0)).sum())


@pytest.mark.parametrize("reverse", [False, True])
def test_a_closed_sideways_loop_of_an_inserted_needle_does_no_net_work(reverse):
    """The lateral bed is the gradient of a potential (its axial part included): around a closed loop in and
    sideways the tissue takes energy (Dahl friction), it never gives the hand any, either way round."""
    s = _session()
    _drive(s, _line((0, 0, 1e-3), (0, 0, -4.5e-3), 5500))
    a, b, c, d = (0, 0, -1e-3), (3e-3, 0, -1e-3), (3e-3, 0, -4.5e-3), (0, 0, -4.5e-3)
    corners = [d, c, b, a, d] if reverse else [d, a, b, c, d]
    tips = [p for u, v in zip(corners[:-1], corners[1:]) for p in _line(u, v, 1000)]
    works = []
    for cycle in range(3):
        f, x = _drive(s, tips, t0=(6000 + cycle * 4000) * MS)
        works.append(_work_j(f, x))
    assert max(works) <= 0.0, works


@pytest.mark.parametrize("layer", [1, 2])
def test_dithering_across_an_interface_toggles_no_force(layer):
    """Backing out of a dimple into the cut layer above it meets no cutting force (that layer is cut through): a tip
    dithering +-2 um across the crossing gets no force step at it."""
    s = _session()
    peak_depth = 2.2e-3 if layer == 1 else 3.4e-3  # layer 1: the epidermis cut, the dermis dimpled
    _drive(s, _line((0, 0, 1e-3), (0, 0, -peak_depth), 3200))
    c = float(s.tool.needle.crossings[min(layer, s.tool.needle.ruptured)])
    back = _line((0, 0, -peak_depth), (0, 0, -(c + 2e-6)), 2000)
    dither = [np.array((0, 0, -(c + 2e-6 * (-1) ** k))) for k in range(20)]
    f, _ = _drive(s, back + dither, t0=5000 * MS)
    mag = np.linalg.norm(f[-20:], axis=1)
    assert mag.max() - mag.min() < 0.02, mag


def test_a_needle_too_flat_for_a_track_presses_the_surface_and_steepening_it_in_place_starts_none():
    s = _session()
    q9 = needle_orientation(math.radians(9.0))
    u9 = np.array(quaternion_axis(*q9))
    f, _ = _drive(s, [p * u9 for p in np.linspace(-1e-3, 2e-3 / math.sin(math.radians(9.0)), 2000)], quat=q9)
    assert not s.tool.needle.inserted and np.linalg.norm(f[-1]) > 0.05 and f[-1][2] > 0.0  # pushed back out
    tip = 2e-3 / math.sin(math.radians(9.0)) * u9
    _drive(s, [tip] * 50, quat=(0.0, 0.0, 0.0, 1.0), t0=3000 * MS)  # rotated to vertical where it is
    assert not s.tool.needle.inserted


def test_no_track_off_the_sheet():
    s = _session()
    hx = 0.5 * s.model.cfg.sheet_size_m[0]
    f, _ = _drive(s, _line((hx + 2e-3, 0, 1e-3), (hx + 2e-3, 0, -4e-3), 2000))
    assert not s.tool.needle.inserted and not np.abs(f).any()
    assert s.regime_counts.get("tool_off_sheet", 0) > 0


def test_pushed_sideways_the_needle_tears_its_way_and_a_new_entry_punctures_again():
    """Withdrawn to 20 um and dragged 3 mm sideways, the needle cuts a slot (the bed's force stays under the slot-cutting
    force) and pushing in at the new place punctures the skin again."""
    s = _session()
    peak = s.tool.needle.params.puncture_force_n(1)
    _drive(s, _line((0, 0, 1e-3), (0, 0, -4.5e-3), 5500))
    _drive(s, _line((0, 0, -4.5e-3), (0, 0, -20e-6), 4500), t0=6000 * MS)
    f_drag, _ = _drive(s, _line((0, 0, -20e-6), (3e-3, 0, -20e-6), 3000), t0=11000 * MS)
    assert np.abs(f_drag[:, 0]).max() < 0.1 and s.tool.tears > 0
    f_in, _ = _drive(s, _line((3e-3, 0, -20e-6), (3e-3, 0, -4.5e-3), 4500), t0=15000 * MS)
    assert np.linalg.norm(f_in, axis=1).max() == pytest.approx(peak, rel=0.01)


def test_a_quaternion_with_huge_finite_components_is_a_bad_orientation():
    s = _session()
    assert s.on_pose(MS, "tissue", (0.0, 0.0, 0.001), quat=(1e308, 1e308, 0.0, 0.0)) == BAD_ORIENTATION


def test_before_the_first_rupture_the_track_follows_the_tip_and_the_tent_holds_it_by_friction():
    """Pressed 1.5 mm (nothing cut yet), moved 3 mm sideways and pushed in: the tip's friction on the tent resists the
    slide (a presliding spring, then at most ``mu N``: the anchor dragged along, issue 31's review) and the skin ruptures
    under the tip's new place, at the same normal peak, not along the first contact's track."""
    s = _session()
    peak = s.tool.needle.params.puncture_force_n(1)
    mu = s.tool.needle.params.tip_friction
    _drive(s, _line((0, 0, 1e-3), (0, 0, -1.5e-3), 2500))
    assert s.tool.needle.ruptured == 0
    f_slide, _ = _drive(s, _line((0, 0, -1.5e-3), (3e-3, 0, -1.5e-3), 3000), t0=3000 * MS)
    assert (f_slide[:, 0] < 0.0).all()  # against the slide
    assert (np.abs(f_slide[:, 0]) <= mu * f_slide[:, 2] * (1.0 + 1e-9)).all()  # at most mu N
    assert -f_slide[-1, 0] == pytest.approx(mu * f_slide[-1, 2], rel=1e-6)  # sliding: at the cap
    f_in, _ = _drive(s, _line((3e-3, 0, -1.5e-3), (3e-3, 0, -4.5e-3), 3000), t0=7000 * MS)
    assert f_in[:, 2].max() == pytest.approx(peak, rel=0.01)  # the normal reaction's peak: the criterion
    assert s.tool.needle.entry[0] == pytest.approx(3e-3, abs=1e-6)
