"""The session's time-step policy under irregular timing (issue 19 item 7; what makes the DDS tests deterministic).

The stamps define time: a pose is stepped by the stamp difference to the pose before it, whatever the node's
own clock did in between. Pose-less ticks (no new pose, input not yet stale) hold the model and the force, so
they neither eat the next pose's time (the dt = 0 rigid-damper jolt) nor change the answer to any pose. The
live node answering a pose stream therefore gives, pose for pose, what the offline replay of the same stream
gives, however the poses arrived.
"""

from __future__ import annotations

import math

import numpy as np
import pytest

from skin_sim_node.model import SkinModel
from skin_sim_node.session import HapticSession, SessionParams
from skin_sim_node.tools import make_tool

MS = 1_000_000
T0 = 1_700_000_000 * 1_000_000_000


def press(n: int, depth_m: float = 2e-3, speed_m_s: float = 0.02):
    """(stamp, z, vz) of a press from 0.5 mm above the surface down to ``depth_m`` at ``speed_m_s``, then held."""
    out = []
    for i in range(n):
        z = max(0.5e-3 - speed_m_s * i * 1e-3, -depth_m)
        out.append((T0 + i * MS, z, -speed_m_s if z > -depth_m else 0.0))
    return out


def session(cfg, **kw) -> HapticSession:
    return HapticSession(make_tool(cfg), SessionParams(max_stamp_age_s=0.0, **kw))


def offline(cfg, poses):
    """Each pose answered at once, ``tick(stamp, stamp - previous)``: the offline replay's drive."""
    s, out, prev = session(cfg), [], None
    for st, z, vz in poses:
        s.on_twist(st, "tissue", (0.0, 0.0, vz))
        s.on_pose(st, "tissue", (0.0, 0.0, z))
        out.append(s.tick(st, 0 if prev is None else st - prev).force_n)
        prev = st
    return out


def live(cfg, poses, rng, max_gap_ticks=30, burst_share=0.1, **kw):
    """The same poses as a loaded node gets them: arrival delayed by up to ``max_gap_ticks`` ms of pose-less
    1 kHz fallback ticks between poses, and bursts where several poses arrive in one instant (elapsed 0).
    Returns the force that answered each pose."""
    s, out = session(cfg, **kw), []
    now = T0
    last_tick = now
    for st, z, vz in poses:
        if rng.random() > burst_share:  # not a burst: time passes on the node's clock, with pose-less ticks
            for _ in range(int(rng.integers(0, max_gap_ticks))):
                now += MS
                s.tick(now, now - last_tick)
                last_tick = now
            now = max(now, st) + int(rng.integers(0, MS))
        s.on_twist(st, "tissue", (0.0, 0.0, vz))
        s.on_pose(st, "tissue", (0.0, 0.0, z), rx_ns=now)
        r = s.tick(now, now - last_tick)
        last_tick = now
        assert r.answered
        out.append(r.force_n)
    return out


@pytest.mark.parametrize("seed", [1, 2, 3])
def test_pose_less_ticks_and_bursts_do_not_change_the_answer_to_any_pose(default_cfg, seed):
    poses = press(400)
    ref = offline(default_cfg, poses)
    got = live(default_cfg, poses, np.random.default_rng(seed))
    assert np.array_equal(np.array(got), np.array(ref))  # bit for bit: the stamps alone define the model's time


def test_irregular_timing_never_exceeds_the_instantaneous_force_at_the_deepest_pose(default_cfg):
    """Gaps up to 40 ms, bursts, pose-less ticks and a watchdog release with the tool 1-2 mm deep: every
    published force stays within 1.2 x the instantaneous elastic force at the deepest pose so far + 0.05 N: the
    static force with every layer at its unrelaxed modulus G(0) = 1 + g1 + g2 (viscoelastic arms unrelaxed: the most
    any press rate can give; a dt = 0 rigid damper gave 9 N where this bound is 2.6 N)."""
    from skin_sim_lab.validation.methods import static_force_n

    rng = np.random.default_rng(7)
    ve = default_cfg.viscoelastic
    g0 = 1.0 + ve.g1 + ve.g2
    unrelaxed = default_cfg.replace(
        **{f"layers.{la.name}.stiffness_n_per_m": g0 * la.stiffness_n_per_m for la in default_cfg.layers}
    )
    ref_model = SkinModel(unrelaxed)
    quasi = {}

    def qs(depth_m: float) -> float:
        key = round(depth_m, 5)
        if key not in quasi:
            quasi[key] = static_force_n(ref_model, 0.0, 0.0, depth_m) if depth_m > 0 else 0.0
        return quasi[key]

    s = session(default_cfg)
    now, last_tick, deepest, worst = T0, T0, 0.0, -math.inf
    stamp = T0
    for i in range(3000):
        z = max(0.5e-3 - 2e-5 * i, -2e-3)  # 20 mm/s down to 2 mm, then held
        stamp += MS if rng.random() > 0.05 else int(rng.integers(2, 40)) * MS  # the device's own gaps
        if i in (1200, 2000):  # the input stops past the watchdog with the tool deep: the tissue is released
            for _ in range(80):
                now += MS
                s.tick(now, now - last_tick)
                last_tick = now
            stamp = now
        if rng.random() > 0.1:
            now = max(now + MS, stamp)
        s.on_twist(stamp, "tissue", (0.0, 0.0, -0.02 if z > -2e-3 else 0.0))
        s.on_pose(stamp, "tissue", (0.0, 0.0, z), rx_ns=now)
        for _ in range(int(rng.integers(0, 3))):  # pose-less ticks after it
            r = s.tick(now, now - last_tick)
            last_tick = now
            now += MS
        r = s.tick(now, now - last_tick)
        last_tick = now
        deepest = max(deepest, -z)
        f = float(np.linalg.norm(r.force_n))
        worst = max(worst, f - (1.2 * qs(deepest) + 0.05))
    assert worst <= 0.0, f"a force {worst:.3f} N above 1.2 x the instantaneous elastic force + 0.05 N"


def test_a_volley_of_absurd_poses_is_rejected_and_the_next_press_answers_at_once(default_cfg):
    """25 poses at +-1e30 m (a device or mapping fault): each rejected as outside the workspace, counted, logged once,
    the tissue untouched; the next valid 1 mm press answers on its first pose with the press's own force."""
    from skin_sim_node.session import OUTSIDE_WORKSPACE

    logged = []
    s = HapticSession(make_tool(default_cfg), SessionParams(max_stamp_age_s=0.0), log=lambda k, m: logged.append(k))
    ref = session(default_cfg)
    stamp = T0
    for st, z, vz in press(60, depth_m=1e-3, speed_m_s=0.02)[:40]:  # lifted, then onto the surface
        for x in (s, ref):
            x.on_twist(st, "tissue", (0.0, 0.0, vz))
            x.on_pose(st, "tissue", (0.0, 0.0, z), now_ns=st, rx_ns=st)
            x.tick(st, MS)
        stamp = st
    for k in range(25):
        stamp += MS
        bad = 1e30 if k % 2 else -1e30
        assert s.on_pose(stamp, "tissue", (bad, -bad, bad), now_ns=stamp, rx_ns=stamp) == OUTSIDE_WORKSPACE
        s.tick(stamp, MS)  # pose-less: held
    assert s.counts[OUTSIDE_WORKSPACE] == 25 and logged.count(OUTSIDE_WORKSPACE) == 1
    stamp += MS
    for x in (s, ref):
        x.on_twist(stamp, "tissue", (0.0, 0.0, -0.02))
        x.on_pose(stamp, "tissue", (0.0, 0.0, -1e-3), now_ns=stamp, rx_ns=stamp)
    got, want = s.tick(stamp, MS), ref.tick(stamp, 26 * MS)
    assert got.answered and got.force_z_n > 0.1
    assert got.force_n == want.force_n  # the volley changed nothing: the press's own force, at once


def test_rate_lever_throttles_the_answers_on_the_pose_stamps():
    from skin_sim_node.session import AnswerThrottle

    rng = np.random.default_rng(5)
    stamps = T0 + np.arange(4000) * MS + rng.integers(-200_000, 200_000, 4000)  # 1 kHz with +-0.2 ms stamp jitter
    for rate_hz, lo, hi in ((250.0, 0.245, 0.255), (500.0, 0.48, 0.505), (1000.0, 1.0, 1.0), (2000.0, 1.0, 1.0)):
        th = AnswerThrottle(rate_hz)
        share = np.mean([th.due(int(s)) for s in stamps])
        assert lo <= share <= hi, (rate_hz, share)  # 1 kHz and above: every pose (live replay's contract)
    th = AnswerThrottle(250.0)
    assert th.due(T0) and not th.due(T0 + MS) and th.due(T0 + 4 * MS)
    assert th.due(T0 + 500 * MS)  # after a gap the next pose is answered at once
    assert th.due(T0 - 10_000 * MS)  # a new time line (a restarted driver)
