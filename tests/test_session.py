"""HapticSession: input checks, watchdog, velocity, force safety (no ROS)."""

import dataclasses
import math

import numpy as np
import pytest

from skin_sim_node.model.contact import ContactTangent
from skin_sim_node.session import (
    FORCE_CLAMPED,
    FUTURE_STAMP,
    NON_FINITE,
    RATE_ALLOWANCE_S,
    STALE_STAMP,
    STALL_RELEASED,
    STALL_RESUMED,
    STAMP_BACKWARDS,
    STAMP_DUPLICATE,
    STAMP_RESYNC,
    TELEPORT,
    TICK_CLAMPED,
    UNKNOWN_FRAME,
    WATCHDOG,
    HapticSession,
    SessionParams,
)
from skin_sim_node.tools import make_tool

MS = 1_000_000
T0 = 1_000_000 * 1_000_000_000  # an arbitrary epoch, ns


@pytest.fixture
def session(default_cfg):
    logged = []
    s = HapticSession(make_tool(default_cfg), SessionParams(), log=lambda kind, msg: logged.append(kind))
    s.logged = logged
    return s


def feed(s, stamps_z, now_offset=0, vz=None):
    out = []
    for st, z in stamps_z:
        r = s.on_pose(st, "tissue", (0.0, 0.0, z), now_ns=st + now_offset, rx_ns=st)
        if vz is not None:
            s.on_twist(st, "tissue", (0.0, 0.0, vz))
        out.append((r, s.tick(st, MS).force_z_n))
    return out


def test_rejections_each_logged_once(session):
    feed(session, [(T0 + i * MS, -1e-3) for i in range(5)])
    s = session
    assert s.on_pose(T0 + 6 * MS, "tissue", (math.nan, 0, 0)) == NON_FINITE
    assert s.on_pose(T0 + 7 * MS, "tissue", (0, math.inf, 0)) == NON_FINITE
    assert s.on_pose(T0 + 8 * MS, "world", (0, 0, -1e-3)) == UNKNOWN_FRAME
    assert s.on_pose(T0 + 2 * MS, "tissue", (0, 0, -1e-3)) == STAMP_BACKWARDS
    assert s.on_pose(T0 + 4 * MS, "tissue", (0, 0, -1e-3)) == STAMP_DUPLICATE
    assert s.on_pose(T0 - 5_000 * MS, "tissue", (0, 0, -1e-3), now_ns=T0) == STALE_STAMP
    assert s.on_pose(T0 + 900 * MS, "tissue", (0, 0, -1e-3), now_ns=T0 + 5 * MS) == FUTURE_STAMP
    assert s.on_pose(T0 + 9 * MS, "world", (0, 0, -1e-3)) == UNKNOWN_FRAME
    assert s.counts[NON_FINITE] == 2 and s.counts[UNKNOWN_FRAME] == 2
    assert sorted(s.logged) == sorted(set(s.logged))  # each kind logged once
    assert s.on_pose(T0 + 10 * MS, "tissue", (0, 0, -1e-3), now_ns=T0 + 10 * MS) is None  # good input still accepted


def test_future_stamp_cannot_lock_out_input(session):
    feed(session, [(T0 + i * MS, -1e-3) for i in range(5)])
    # one pose 0.9 s ahead of the clock is rejected, so later good poses are not "backwards"
    assert session.on_pose(T0 + 900 * MS, "tissue", (0, 0, -1e-3), now_ns=T0 + 5 * MS) == FUTURE_STAMP
    res = feed(session, [(T0 + (6 + i) * MS, -1e-3) for i in range(20)])
    assert all(r is None for r, _ in res) and res[-1][1] > 0


def test_new_time_line_is_followed_after_resync(session):
    """Offline (no clock) a restarted driver's stamps go back: after resync_after of them, follow."""
    feed(session, [(T0 + i * MS, -1e-3) for i in range(5)])
    restart = [(T0 // 2 + i * MS, -1e-3) for i in range(60)]
    res = [(session.on_pose(st, "tissue", (0, 0, z)), session.tick(st, MS).force_z_n) for st, z in restart]
    rejected = sum(r is not None for r, _ in res)
    assert rejected == session.params.resync_after - 1
    assert session.counts[STAMP_RESYNC] == 1 and res[-1][0] is None and res[-1][1] > 0


def test_watchdog_zeroes_force_and_holds_the_tissue_then_releases_past_stall_hold(session):
    """Issue 31: a stall is not a restart. The watchdog zeroes the published force at once, the tissue stays pressed
    by the tool held at its last pose; only a stall past stall_hold_s takes the tool as gone and releases it."""
    res = feed(session, [(T0 + i * MS, -2e-3) for i in range(20)])
    assert res[-1][1] > 0
    now = T0 + 19 * MS
    for k in range(1, 80):
        r = session.tick(now + k * MS, MS)
    assert r.force_z_n == 0.0 and r.stale and session.counts[WATCHDOG] == 1
    assert session.model.driven.any() and r.x0_m == (0.0, 0.0, -2e-3)  # still pressed, where the tool was
    assert session.model.force_vector_n[2] > 0.5 * res[-1][1]  # the tissue's own force: held, relaxing
    hold_ms = int(session.params.stall_hold_s * 1e3)
    for k in range(80, hold_ms + 80):
        r = session.tick(now + k * MS, MS)
    assert r.stale and r.x0_m[2] == 1.0 and session.counts[STALL_RELEASED] == 1
    assert not session.model.driven.any()


def test_teleport_restarts_contact(session):
    feed(session, [(T0 + i * MS, -2e-3) for i in range(10)])
    assert session.on_pose(T0 + 10 * MS, "tissue", (0.05, 0.0, -2e-3)) is None  # 50 mm in 1 ms
    session.tick(T0 + 10 * MS, MS)
    assert session.counts[TELEPORT] == 1 and session.velocity == (0.0, 0.0, 0.0)


def test_velocity_from_twist_or_pose_difference(session):
    feed(session, [(T0 + i * MS, -1e-3 - i * 1e-5) for i in range(5)], vz=-0.25)
    assert session.velocity[2] == pytest.approx(-0.25)
    s2 = HapticSession(make_tool(session.model.cfg), SessionParams())
    feed(s2, [(T0 + i * MS, -1e-3 - i * 1e-5) for i in range(5)])  # no twist: differentiate poses
    assert s2.velocity[2] == pytest.approx(-0.01)
    s3 = HapticSession(make_tool(session.model.cfg), SessionParams())
    feed(s3, [(T0 + i * MS, -1e-3) for i in range(3)], vz=-50.0)  # capped at max_tool_speed_m_s
    assert math.hypot(*s3.velocity) == pytest.approx(s3.params.max_tool_speed_m_s)


def test_force_clamped_to_limit(default_cfg):
    s = HapticSession(make_tool(default_cfg), SessionParams(max_force_n=0.01))
    res = feed(s, [(T0 + i * MS, -3e-3) for i in range(5)])
    assert res[-1][1] == 0.01 and s.counts[FORCE_CLAMPED] >= 1


def test_several_poses_per_tick_lose_no_time(default_cfg):
    """Timer mode: 1 kHz poses, 500 Hz ticks; the model must still advance 1 s per second."""
    s = HapticSession(make_tool(default_cfg), SessionParams())
    advanced = []
    orig = s.model.step
    s.model.step = lambda pos, v, dt, restart=False: (advanced.append(dt), orig(pos, v, dt, restart))[1]
    for i in range(1000):
        s.on_pose(T0 + i * MS, "tissue", (0.0, 0.0, 0.01))
        if i % 2 == 1:
            s.tick(T0 + i * MS, 2 * MS)
    # the first pose starts contact from the quasi-static state (one max_dt_s step); then 1 ms per stamp
    assert advanced[0] == s.params.max_dt_s and sum(advanced[1:]) == pytest.approx(0.998, abs=1e-9)


def test_non_finite_model_state_recovers(default_cfg):
    s = HapticSession(make_tool(default_cfg), SessionParams())
    feed(s, [(T0 + i * MS, -2e-3) for i in range(3)])
    s.model.q[:] = math.nan
    s.model.driven[:] = 0
    for i in range(3, 200):
        s.on_pose(T0 + i * MS, "tissue", (0.0, 0.0, 0.01))
        f = s.tick(T0 + i * MS, MS).force_z_n
        assert math.isfinite(f)
    assert math.isfinite(s.model.energy())


def _held_press(s, depth_m=1e-3, n=400):
    """Press to ``depth_m`` at 5 mm/s and hold: returns the next stamp."""
    st = T0
    for i in range(n):
        st = T0 + i * MS
        s.on_pose(st, "tissue", (0.0, 0.0, -depth_m * min(1.0, (i + 1) / 200)), now_ns=st, rx_ns=st)
        s.tick(st, MS)
    return st + MS


def test_force_rate_bound_holds_on_the_stamp_clock_in_a_burst(default_cfg):
    """Poses stamped 1 ms apart but processed 20 us apart (DDS catching up): the bound is on the stamps, so the
    burst gets the answer the offline replay gives the same poses, and the change is bounded per stamp interval."""
    rate = 100.0
    s = HapticSession(make_tool(default_cfg), SessionParams(max_force_rate_n_per_s=rate, max_stamp_age_s=0.0))
    st = _held_press(s, depth_m=2e-3)  # the whole stack compressed: a few tenths of a newton
    f0 = s.force_n
    assert f0 > 0.2
    s.counts.clear()
    forces = []
    for k in range(5):  # a fast lift to the surface: each pose alone allows rate * 1 ms
        stamp = st + k * MS
        s.on_pose(stamp, "tissue", (0.0, 0.0, -2e-3 + 0.4e-3 * (k + 1)), now_ns=stamp, rx_ns=stamp)
        forces.append(s.tick(stamp, 20_000).force_z_n)
    steps = np.abs(np.diff([f0, *forces]))
    assert np.all(steps <= rate * MS * 1e-9 + 1e-12) and abs(forces[-1] - f0) <= rate * (5e-3 + RATE_ALLOWANCE_S)
    assert s.counts["force_rate_limited"] >= 1


def test_live_lowering_of_max_force_applies_at_once(default_cfg):
    s = HapticSession(make_tool(default_cfg), SessionParams(max_force_rate_n_per_s=10.0, max_stamp_age_s=0.0))
    st = _held_press(s, depth_m=2e-3, n=1000)
    assert s.force_n > 0.2
    s.params = SessionParams(max_force_rate_n_per_s=10.0, max_stamp_age_s=0.0, max_force_n=0.05)
    s.on_pose(st, "tissue", (0.0, 0.0, -2e-3), now_ns=st, rx_ns=st)
    assert s.tick(st, MS).force_z_n <= 0.05


def test_tick_result_is_the_frozen_sequenced_output(session):
    """Every tick returns a frozen TickResult: sequence, answered pose, force vector, tangent, events."""
    res = [session.tick(T0, MS)]  # no pose yet: stale, nothing answered
    for i in range(1, 40):
        st = T0 + i * MS
        session.on_pose(st, "tissue", (0.0, 0.0, -2e-3 * i / 40), now_ns=st, rx_ns=st)
        res.append(session.tick(st, MS))
    assert [r.seq for r in res] == list(range(1, 41))
    assert res[0].stale and not res[0].answered and res[0].force_n == (0.0, 0.0, 0.0)
    r = res[-1]
    assert r.answered and r.stamp_ns == T0 + 39 * MS and r.x0_m == (0.0, 0.0, -2e-3 * 39 / 40)
    assert r.force_z_n == session.force_n > 0 and r.force_n[:2] == (0.0, 0.0)
    assert isinstance(r.tangent, ContactTangent) and r.tangent.force_n[2] == pytest.approx(r.force_z_n)
    assert r.tangent.stiffness_n_per_m[2, 2] < 0  # a deeper press pushes back harder
    assert r.depth_m > 0 and len(r.compression_m) == 3 and sum(r.compression_m) == pytest.approx(r.depth_m)
    with pytest.raises(dataclasses.FrozenInstanceError):
        r.seq = 0
    session.on_pose(T0 + 40 * MS, "world", (0.0, 0.0, -1e-3))  # rejected: reported by the next tick
    assert UNKNOWN_FRAME in session.tick(T0 + 40 * MS, MS).events
    assert session.tick(T0 + 41 * MS, MS).events == ()


def test_converter_fills_wrench_and_contact_from_a_tick(session):
    """The one converter: the messages carry exactly the TickResult's numbers."""
    from geometry_msgs.msg import WrenchStamped
    from sensor_msgs.msg import JointState

    from msgs_schema import convert as cv

    for i in range(30):
        st = T0 + i * MS
        session.on_pose(st, "tissue", (0.0, 0.0, -3e-3 * i / 30), now_ns=st, rx_ns=st)
        session.on_twist(st, "tissue", (0.0, 0.0, -0.1))
        r = session.tick(st, MS)
    w = cv.fill_wrench_from_tick(WrenchStamped(), r, r.stamp_ns, "tissue")
    assert cv.read_wrench(w) == (r.stamp_ns, "tissue", r.force_n)
    c = cv.fill_contact_from_tick(JointState(), r, r.stamp_ns, "tissue")
    stamp, comp, rate, stress = cv.read_contact(c)
    assert stamp == r.stamp_ns and list(comp) == list(r.compression_m) and list(stress) == list(r.stress_pa)
    assert rate == pytest.approx([0.1 * x / r.depth_m for x in r.compression_m])  # normal speed shared as compressed
    assert stress[: r.n_affected] == pytest.approx([r.stress_pa[0]] * r.n_affected) and r.stress_pa[0] > 0


def test_params_are_views_of_the_one_schema():
    """NodeParams and SessionParams are generated from msgs_schema.parameters: same names, types and defaults."""
    from dataclasses import fields

    from msgs_schema.parameters import (
        NODE_PARAMETERS,
        READ_ONLY,
        SESSION_KEYS,
        SESSION_PARAMETERS,
        NodeParams,
        node_params_from_flat,
        session_params,
    )

    assert [(f.name, f.type, f.default) for f in fields(NodeParams)] == [(s.name, s.type, s.default) for s in NODE_PARAMETERS]
    assert [(f.name, f.default) for f in fields(SessionParams)] == [(s.name, s.default) for s in SESSION_PARAMETERS]
    node = node_params_from_flat({"watchdog_s": 0.2, "tissue.tool.radius_m": 1e-3})
    sp = session_params(node, max_stamp_age_s=0.0)
    assert sp.watchdog_s == 0.2 and sp.max_stamp_age_s == 0.0 and set(SESSION_KEYS) < {f.name for f in fields(sp)}
    assert sp == SessionParams(watchdog_s=0.2, max_stamp_age_s=0.0)  # the defaults are the schema's, written once
    assert set(READ_ONLY) == {
        "input_queue_depth", "rt_priority", "rt_scope", "haptic_cpu", "spin_tail_us", "precise_sleep",
        "hand_ns", "second_hand_ns", "second_tool_shape", "second_tool_radius_m",  # the hands (issue 32): at start only
    }  # fmt: skip


def test_mode_counts_are_described_as_the_model_runs_them(default_cfg):
    """The node logs what the model runs: adaptive levels (not the unused modes.m x n) or the fixed count."""
    s = HapticSession(make_tool(default_cfg), SessionParams())
    assert s.modes_per_axis == (1, 1, 1)  # at rest every layer sits at its lowest level
    text = s.describe_modes()
    m, n = default_cfg.modes
    assert text.startswith("adaptive modes on") and f"{m}x{n} applies only with it off" in text
    feed(s, [(T0 + i * MS, -3e-3 * i / 200) for i in range(1, 201)])
    assert max(s.modes_per_axis) > 1  # a deep press raises the levels
    fixed = HapticSession(make_tool(default_cfg.replace(**{"lod.adaptive_modes": False})), SessionParams())
    assert fixed.describe_modes().startswith(f"fixed modes: {m}x{n} per axis") and fixed.modes_per_axis == (max(m, n),) * 3


@pytest.mark.parametrize("form", ["layered", "paper"])
def test_warm_up_compiles_every_kernel_a_press_through_the_session_uses(form):
    """After ``warm_up`` a press, drag and release through the session compiles (or loads) no kernel: the node calls
    ``warm_up`` at start, and the first contact once loaded ``contact_jacobians`` inside the tick (a 100 ms stall)."""
    import gc

    from numba.core.registry import CPUDispatcher

    from skin_sim_node.model import config_from_flat, preset
    from skin_sim_node.model.config import default_flat
    from skin_sim_node.model.skin_model import warm_up

    cfg = preset("default") if form == "layered" else config_from_flat({**default_flat(), "form": "paper"})
    warm_up(cfg)

    def signatures():
        return {id(o): (o.__name__, len(o.signatures)) for o in gc.get_objects() if isinstance(o, CPUDispatcher)}

    before = signatures()
    s = HapticSession(make_tool(cfg), SessionParams())
    now = 1_700_000_000_000_000_000
    for i in range(600):
        d = 3e-3 * min(i, 200) / 200 if i < 400 else -1e-3
        now += 1_000_000
        s.on_pose(now, "tissue", (2e-5 * max(i - 200, 0), 0.0, -d), now_ns=now, rx_ns=now)
        s.tick(now, 1_000_000)
    after = signatures()
    grown = [(name, before.get(k, (name, 0))[1], n) for k, (name, n) in after.items() if n != before.get(k, (name, 0))[1]]
    assert not grown, f"kernels compiled after warm_up: {grown}"


# --- the seams on their own: input policy and force limits without a model ---------------------------------


def _policy(**params):
    from skin_sim_node.session import EventLog, InputPolicy

    events = EventLog()
    return InputPolicy(SessionParams(**params), events), events


def test_input_policy_alone_decides_what_a_tick_runs_at():
    """No model: accepted poses are answered once, at the stamps' interval; a pose-less tick holds the pose."""
    pol, events = _policy()
    assert pol.take(T0, MS)[:6] == (False, True, (0.0, 0.0, 1.0), (0.0, 0.0, 0.0), 1e-3, False)  # no pose yet: stale, lifted
    assert pol.on_pose(T0, "tissue", (0.0, 0.0, -1e-3), now_ns=T0, rx_ns=T0) is None
    first = pol.take(T0, MS)
    # the first pose restarts contact from the quasi-static state: one max_dt_s step, no rigid damper
    assert first.answered and not first.stale and first.pos == (0.0, 0.0, -1e-3) and first.dt_s == 0.1
    pol.on_pose(T0 + 2 * MS, "tissue", (0.0, 0.0, -1.2e-3), now_ns=T0 + 2 * MS, rx_ns=T0 + 2 * MS)
    second = pol.take(T0 + 2 * MS, MS)  # elapsed 1 ms, stamps 2 ms apart: the stamps win
    assert second.answered and second.dt_s == pytest.approx(2e-3) and second.velocity[2] == pytest.approx(-0.1)
    held = pol.take(T0 + 3 * MS, MS)  # no new pose: held (no step: model time is the stamps'), not released
    assert held.hold and held.dt_s == 0.0 and not held.answered and held.pos == (0.0, 0.0, -1.2e-3) and not held.release
    pol.on_pose(T0 + 4 * MS, "tissue", (0.0, 0.0, -1.2e-3), now_ns=T0 + 9 * MS, rx_ns=T0 + 9 * MS)
    late = pol.take(T0 + 9 * MS, 0)  # arrived 5 ms late after a held tick: stepped by its stamps' 2 ms
    assert late.answered and late.dt_s == pytest.approx(2e-3) and late.rate_dt_ns == 2 * MS
    assert pol.answered_stamp_ns == T0 + 4 * MS and events.take() == ()


def test_input_policy_alone_watchdog_stall_teleport_and_interval_parts():
    pol, events = _policy(watchdog_s=0.01, max_dt_s=0.005, stall_hold_s=0.1)
    pol.on_pose(T0, "tissue", (0.0, 0.0, -1e-3), now_ns=T0, rx_ns=T0)
    pol.take(T0, MS)
    stale = pol.take(T0 + 20 * MS, 20 * MS)  # past the watchdog: force zero, the tissue held unstepped, no release
    assert stale.stale and stale.hold and not stale.release and not stale.restart and stale.pos == (0.0, 0.0, -1e-3)
    assert stale.dt_s == 0.0 and events.take() == (WATCHDOG,)
    pol.on_pose(T0 + 30 * MS, "tissue", (0.0, 0.0, -1.2e-3), now_ns=T0 + 30 * MS, rx_ns=T0 + 30 * MS)
    resumed = pol.take(T0 + 30 * MS, MS)  # the whole 30 ms gap, from the held pose: as the offline replay steps it
    assert resumed.answered and not resumed.restart and not resumed.release and resumed.from_pos == (0.0, 0.0, -1e-3)
    assert resumed.dt_s == pytest.approx(0.030) and resumed.rate_dt_ns == MS  # the force returns at the rate bound
    assert events.take() == (STALL_RESUMED, TICK_CLAMPED)  # 30 ms is stepped in parts of max_dt_s
    gone = pol.take(T0 + 131 * MS, MS)  # 101 ms without a pose (caller's clock): past stall_hold_s, the tool is gone
    assert gone.stale and gone.release and gone.pos == (0.0, 0.0, 1.0) and events.take() == (WATCHDOG, STALL_RELEASED)
    pol.on_pose(T0 + 140 * MS, "tissue", (0.0, 0.0, -1e-3), now_ns=T0 + 140 * MS, rx_ns=T0 + 140 * MS)
    back = pol.take(T0 + 140 * MS, MS)  # the next pose restarts contact
    assert back.restart and back.from_pos is None and back.dt_s == 0.005
    pol.on_pose(T0 + 141 * MS, "tissue", (0.05, 0.0, -1e-3), now_ns=T0 + 141 * MS, rx_ns=T0 + 141 * MS)  # 50 mm jump
    jumped = pol.take(T0 + 141 * MS, MS)
    assert jumped.answered and jumped.release and jumped.restart and jumped.velocity == (0.0, 0.0, 0.0)
    assert events.take() == (TELEPORT,)
    pol.on_pose(T0 + 160 * MS, "tissue", (0.05, 0.0, -1e-3), now_ns=T0 + 160 * MS, rx_ns=T0 + 160 * MS)
    gap = pol.take(T0 + 160 * MS, MS)  # an answered pose 19 ms after the last: stepped in parts, and that is an event
    assert gap.answered and gap.dt_s == pytest.approx(0.019) and gap.from_pos == (0.05, 0.0, -1e-3)
    assert events.take() == (TICK_CLAMPED,)
    pol.on_pose(T0 + 300 * MS, "tissue", (0.05, 0.0, -1e-3))  # offline (no clock): a stamp gap past stall_hold_s
    offline = pol.take(T0 + 300 * MS, MS)
    assert offline.restart and offline.release and events.take() == (STALL_RELEASED,)
    assert events.counts == {WATCHDOG: 2, STALL_RESUMED: 1, TICK_CLAMPED: 2, STALL_RELEASED: 2, TELEPORT: 1}


def test_velocity_estimate_alone():
    from skin_sim_node.session import velocity_estimate

    p = SessionParams()
    twist = velocity_estimate(p, T0, (0.0, 0.0, 0.0), T0 - MS, (0.0, 0.0, 1e-4), T0 + 2 * MS, (0.1, 0.0, 0.0))
    assert twist == (0.1, 0.0, 0.0)  # the twist, within twist_max_skew_s of the pose
    diff = velocity_estimate(p, T0, (0.0, 0.0, 0.0), T0 - MS, (0.0, 0.0, 1e-4), T0 + 20 * MS, (0.1, 0.0, 0.0))
    assert diff == pytest.approx((0.0, 0.0, -0.1))  # twist too far from the pose: the pose difference
    capped = velocity_estimate(p, T0, (0.0, 0.0, 0.0), T0 - MS, (0.0, 0.0, 1.0), None, None)
    assert math.hypot(*capped) == pytest.approx(p.max_tool_speed_m_s)
    assert velocity_estimate(p, T0, (0.0, 0.0, 0.0), None, (0.0, 0.0, 1.0), None, None) == (0.0, 0.0, 0.0)


def _limits(**params):
    from skin_sim_node.session import EventLog, ForceLimits

    events = EventLog()
    return ForceLimits(SessionParams(**params), events), events


def test_force_limits_alone_clamp_non_finite_and_stale():
    lim, events = _limits(max_force_n=2.0, max_force_rate_n_per_s=0.0)
    assert lim.apply(1.5, MS, False) == (1.5, False)
    assert lim.apply(5.0, MS, False) == (2.0, False) and events.take() == (FORCE_CLAMPED,)
    assert lim.apply(math.nan, MS, False) == (0.0, True) and events.take() == ("force_non_finite",)
    assert lim.apply(1.0, MS, False, state_finite=lambda: False) == (0.0, True)  # a NaN elsewhere in the state
    assert lim.apply(1.0, MS, True) == (0.0, False) and lim.force_n == 0.0  # stale: zero, whatever the model says


def test_force_limits_alone_rate_bound_is_a_token_bucket():
    """Over any window W the force moves at most rate (W + RATE_ALLOWANCE_S); a lowered clamp applies at once."""
    rate = 100.0
    lim, events = _limits(max_force_rate_n_per_s=rate)
    lim.apply(0.0, MS, False)  # the first tick fills the bucket to one allowance
    out = [lim.apply(1.0, MS, False)[0] for _ in range(5)]
    assert out == pytest.approx([0.1 * (k + 1) for k in range(5)])  # 1 ms ticks: rate * 1 ms each
    assert events.counts["force_rate_limited"] == 5
    burst = [lim.apply(1.0, 20_000, False)[0] for _ in range(5)]  # five ticks 20 us apart share 100 us of budget
    assert burst[-1] - out[-1] == pytest.approx(rate * 5 * 20e-6)
    lim.params = SessionParams(max_force_rate_n_per_s=rate, max_force_n=0.05)
    assert lim.apply(1.0, MS, False)[0] == 0.05  # the clamp is the hard limit, even right after a lowering


def test_session_imports_only_the_models_public_api():
    """The session (every module of skin_sim_node.session) imports the model package, none of its modules."""
    from test_architecture import import_graph

    graph = import_graph()
    session = {m: ts for m, ts in graph.items() if m == "skin_sim_node.session" or m.startswith("skin_sim_node.session.")}
    assert len(session) >= 4, sorted(session)
    model = {m: sorted(t for t in ts if t.startswith("skin_sim_node.model.")) for m, ts in session.items()}
    assert {m: ts for m, ts in model.items() if ts} == {}
    assert "skin_sim_node.model" in graph["skin_sim_node.session.haptic"]
