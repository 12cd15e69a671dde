"""The needle through the session and the contract (issue 22): orientation in, the whole vector and its law out."""

from __future__ import annotations

import math

import numpy as np
import pytest

from msgs_schema.contact_model import read_contact_model
from msgs_schema.convert import fill_needle_state
from msgs_schema.parameters import SessionParams
from skin_sim_node.device.trajectories import TRAJECTORIES, needle_orientation
from skin_sim_node.model import NeedleSkin, SkinModel, preset
from skin_sim_node.session.events import BAD_ORIENTATION
from skin_sim_node.session.haptic import HapticSession
from skin_sim_node.session.inputs import quaternion_axis

MS = 1_000_000


def _session(shape: str = "needle", **tissue) -> HapticSession:
    cfg = preset("default").replace(**{"tool.shape": shape, **tissue})
    return HapticSession(SkinModel(cfg), SessionParams())


def _insert(s: HapticSession, path: str, dt_ns: int = MS):
    """Run a needle trajectory through the session; yields (tick result, tip)."""
    traj = TRAJECTORIES[path]
    n = int(traj.duration_s * 1e9 / dt_ns)
    for k in range(1, n + 1):
        p, _ = traj.sample(k * dt_ns * 1e-9)
        assert s.on_pose(k * dt_ns, "tissue", p, quat=traj.orientation) is None
        yield s.tick(k * dt_ns, dt_ns), np.array(p)


def test_needle_config_gives_the_needle_model():
    assert isinstance(SkinModel(preset("needle")), NeedleSkin)
    assert type(SkinModel(preset("default"))) is SkinModel


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
        most = max(most, s.model.needle.ruptured)
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
    assert most == 3  # every layer cut by 4.5 mm deep


def test_puncture_drop_is_published_within_one_tick_and_not_rate_limited():
    s = _session()
    forces = [math.hypot(*r.force_n) for r, _ in _insert(s, "needle_straight")]
    drops = np.diff(forces)
    i = int(np.argmin(drops))
    peak = forces[i]
    assert peak == pytest.approx(s.model.needle.params.puncture_force_n(1), rel=0.01)  # the skin's (dermis) peak
    assert forces[i + 1] < 0.3 * peak  # the drop lands in one tick


def test_latched_track_on_reinsertion_and_peak_returns_after_withdrawal():
    s = _session()
    forces = np.array([math.hypot(*r.force_n) for r, _ in _insert(s, "needle_reinsert")])
    peak = s.model.needle.params.puncture_force_n(1)
    big = np.flatnonzero(forces > 0.95 * peak)
    runs = np.split(big, np.flatnonzero(np.diff(big) > 50) + 1)
    assert len(runs) == 2  # the first insertion and the one after the withdrawal; none on the latched re-insertion


def test_needle_state_message_round_trip():
    from skin_sim_msgs.msg import NeedleState

    s = _session()
    for _ in _insert(s, "needle_oblique_30"):
        pass
    st = s.needle_state()
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
    from skin_sim_node.validation import needle_check

    assert needle_check.main([]) == 0
    out = capsys.readouterr().out
    assert "needle_check PASS: 6 checks" in out
