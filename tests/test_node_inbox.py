"""The node's input queue per hand (``Hand.inbox``): poses reach the session without their thread waiting for the lock.

In one process with two hands (``skin-sim bridge --with-node``) each hand's link thread runs one priority below the
servo threads and shares one lock with the other hand and the node's clock; a lock is not fair, and the two-hand
device bench found a held hand's link waiting 55-90 ms for it while its device streamed, so the node's watchdog
released a hand whose poses were arriving. Here every case is driven by hand (the node's clock thread is stopped and
its tick called with chosen times), so nothing depends on scheduling.
"""

from __future__ import annotations

import threading
import time

import pytest
from conftest import node_in_process

from skin_sim_node.session import WATCHDOG

pytestmark = [pytest.mark.ros, pytest.mark.usefixtures("ros_domain")]

MS = 1_000_000


@pytest.fixture
def node():
    """The two-hand node in-process, its clock thread stopped (each test calls its tick itself)."""
    with node_in_process(
        hand_ns="right",
        second_hand_ns="left",
        max_stamp_age_s=0.0,  # stamps are the test's, not the clock's
        display_rate_hz=0.0,
    ) as n:
        yield n


def _press(n, hand: int, stamp: int, depth_m: float = 1e-3) -> None:
    """Queue one pose of ``hand`` (as a composed bridge's servo thread does), ``depth_m`` into the tissue."""
    x = -0.008 if hand else 0.0
    n.post_pose(stamp, "tissue", (x, 0.0, -depth_m), (0.0, 0.0, 0.0, 1.0), hand=hand)


def test_a_pose_whose_thread_is_held_off_is_answered_by_the_clock_and_the_watchdog_stays_quiet(node):
    """A pose queued but never taken by its own thread (a starved link) is taken and answered by the clock's tick;
    with poses still arriving for longer than the watchdog, the hand is never released. Without poses it is."""
    h = node.hands[1]
    stamp0 = time.time_ns()
    for k in range(12):  # 12 poses 10 ms apart (120 ms, over twice the 50 ms watchdog), only the clock takes them
        _press(node, 1, stamp0 + k * 10 * MS)
        node._on_clock(time.perf_counter_ns(), 0)
        assert h.last is not None and h.last.answered and h.last.stamp_ns == stamp0 + k * 10 * MS
        assert not h.session.stale
        time.sleep(0.01)
    assert h.session.force_n > 0.0
    assert h.session.counts.get(WATCHDOG, 0) == 0
    # no pose for longer than the watchdog: the clock's tick releases the hand, as before
    node._on_clock(time.perf_counter_ns() + 60 * MS, 0)
    assert h.session.stale and h.last.force_n == (0.0, 0.0, 0.0)


def test_a_newer_pose_supersedes_one_not_yet_taken(node):
    """Three poses queued before any thread takes them: the newest is answered, in one tick; the older two are
    counted, as the latest-value hand-off before the queue dropped them."""
    h = node.hands[0]
    stamp0 = time.time_ns()
    ticks = h.n_ticks
    for k in range(3):
        _press(node, 0, stamp0 + k * MS, depth_m=(k + 1) * 0.5e-3)
    node.take_inputs(0)
    assert h.n_ticks == ticks + 1 and h.poses_superseded == 2
    assert h.last.answered and h.last.stamp_ns == stamp0 + 2 * MS
    assert h.session.pose[2] == pytest.approx(-1.5e-3)


def test_in_timer_mode_a_pose_never_waits_for_the_lock(node):
    """Timer mode: the clock answers the newest pose each tick, so the thread that brings a pose does not take the
    lock at all; here the lock is held while it delivers one, and the clock's next tick takes it."""
    from rclpy.parameter import Parameter

    assert node.set_parameters([Parameter("loop_mode", value="timer")])[0].successful
    h = node.hands[0]
    stamp = time.time_ns()
    with node._lock:
        t = threading.Thread(target=node.answer_pose, args=(stamp, "tissue", (0.0, 0.0, -1e-3), None, 0))
        t.start()
        t.join(timeout=30.0)  # a liveness check, not a timing one: with the lock held a waiting thread never ends
        delivered = not t.is_alive()
    t.join()
    assert delivered
    node._on_clock(time.perf_counter_ns(), 0)
    assert h.last.answered and h.last.stamp_ns == stamp and not h.session.stale


def test_a_non_blocking_take_answers_only_when_the_lock_is_free_and_never_waits_for_it(node):
    """``take_inputs(hand, blocking=False)`` (what a composed bridge's servo thread calls, tests/test_local_link.py):
    while another thread holds the lock it returns False at once and the pose stays queued, nothing lost; with the
    lock free it answers the pose."""
    h = node.hands[1]
    stamp = time.time_ns()
    ticks = h.n_ticks
    _press(node, 1, stamp)
    results: list[bool] = []
    with node._lock:  # the other hand's tick, say
        t = threading.Thread(target=lambda: results.append(node.take_inputs(1, blocking=False)))
        t.start()
        t.join(timeout=30.0)  # a liveness check, not a timing one: a blocking take would never end here
        returned = not t.is_alive()
    t.join()
    assert returned and results == [False]
    assert h.n_ticks == ticks and len(h.inbox) == 1  # not answered, still queued
    assert node.take_inputs(1, blocking=False)  # the lock free: answered at once
    assert h.n_ticks == ticks + 1 and not h.inbox
    assert h.last.answered and h.last.stamp_ns == stamp
