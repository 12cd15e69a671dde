"""A stall is not a restart, over real DDS (issue 31 item 2): node, bridge and simulated Touch as three processes.

The node is stopped (SIGSTOP) for 150 ms just after a 21 G needle punctured the epidermis (the simulated hand's spring
does not push it through the dermis), while the hand goes on inserting;
its watchdog fires when it runs again. The needle keeps its track (the same entry, no layer ruptured again), the node's
forces after the stall are the offline session's answer to the poses it answered (within 1.2 x + 0.05 N), and so are the
device's commands. The offline stall matrix (18 and 21 G, 60 / 150 / 500 ms, every phase) is tests/test_stall.py.
"""

from __future__ import annotations

import os
import signal
import threading
import time

import numpy as np
import pytest

rclpy = pytest.importorskip("rclpy")

from geometry_msgs.msg import WrenchStamped  # noqa: E402

from msgs_schema.convert import read_wrench  # noqa: E402
from msgs_schema.parameters import SessionParams  # noqa: E402
from msgs_schema.qos import PROFILES, subscription  # noqa: E402
from skin_sim_node.model.config import load_tissue_config  # noqa: E402
from skin_sim_node.ros_util import set_process_realtime  # noqa: E402
from skin_sim_node.scenes import REPO, Scene  # noqa: E402
from skin_sim_node.server.display import restore_priority  # noqa: E402
from skin_sim_node.session import HapticSession  # noqa: E402
from skin_sim_node.tools import make_tool  # noqa: E402

pytestmark = [pytest.mark.ros, pytest.mark.usefixtures("ros_domain")]
NEEDLE_PARAMS = REPO / "config" / "needle.yaml"
STALL_S = 0.15
RAMP_ANSWERS = 10
"""Consecutive answers a dip below the offline answer may last, whatever their pose time: the force comes back at the
rate bound, 1 N per ms of the node's clock, within a tick or two of that clock; a node starved again right after (beside
busy processes) may answer those few poses hundreds of ms of pose time apart."""
OBSERVER_RT = 10
"""SCHED_FIFO priority of this test's observer threads (DDS ones included), below the node's 50 and the bridge's 80:
beside busy processes a normal-priority observer missed seconds of poses and wrenches, and the offline session it
builds then steps another viscoelastic path than the node did. Not permitted: it runs at normal priority."""
RAMP_S = 0.1
"""Pose time in which a published force below the offline answer must have come back to it (s): its return at the rate
bound (1 N per ms of the node's clock) from a stall's zero, with the poses the node answers in a burst after it."""


class Observer:
    """Records the needle read-out, the node's wrenches, the poses the bridge forwards and the device's commands."""

    def __init__(self):
        self.ctx = rclpy.Context()
        rclpy.init(context=self.ctx)
        self.needle: list[tuple] = []  # (rx_ns, ruptured, inserted, entry)
        self.wrench: dict[int, np.ndarray] = {}  # stamp -> force
        self.poses: dict[int, tuple] = {}  # stamp -> (xyz, quat)
        self.commands: list[tuple] = []  # (stamp, fx, fy, fz)
        # the needle read-out (60 Hz) has a node and an executor of its own: the 1 kHz streams must not delay it
        trigger = rclpy.create_node(f"stall_trigger_{os.getpid()}", context=self.ctx)
        subscription(trigger, "needle", self._on_needle, depth=100)
        record = rclpy.create_node(f"stall_observer_{os.getpid()}", context=self.ctx)
        subscription(record, "tool_wrench", self._on_wrench, depth=1000)
        subscription(record, "tool_pose", self._on_pose, depth=1000)
        record.create_subscription(WrenchStamped, "device/servo_cf", self._on_command, PROFILES["driver"])
        self.nodes = (trigger, record)
        self.executors = []
        self._stop = threading.Event()
        self.threads = []
        for n in self.nodes:
            ex = rclpy.executors.SingleThreadedExecutor(context=self.ctx)
            ex.add_node(n)
            self.executors.append(ex)
            self.threads.append(threading.Thread(target=self._spin, args=(ex,), daemon=True))
            self.threads[-1].start()
        set_process_realtime(OBSERVER_RT)  # every thread of this process; restored to normal in close()

    def _spin(self, ex):
        while not self._stop.is_set():
            ex.spin_once(timeout_sec=0.05)

    def _on_needle(self, m):
        self.needle.append((time.monotonic_ns(), int(m.ruptured_layers), bool(m.inserted), tuple(m.entry_m)))

    def _on_wrench(self, m):
        t, _, f = read_wrench(m)
        self.wrench.setdefault(t, np.asarray(f, dtype=float))  # the answer; held or stale ticks repeat its stamp

    def _on_pose(self, m):
        s = m.header.stamp.sec * 1_000_000_000 + m.header.stamp.nanosec
        p, q = m.pose.position, m.pose.orientation
        self.poses[s] = ((p.x, p.y, p.z), (q.x, q.y, q.z, q.w))

    def _on_command(self, m):
        t, _, f = read_wrench(m)
        self.commands.append((t, *f))

    def close(self):
        restore_priority(os.getpid())  # the rest of the test session runs at normal priority
        self._stop.set()
        for t in self.threads:
            t.join(timeout=2)
        for n in self.nodes:
            n.destroy_node()
        rclpy.try_shutdown(context=self.ctx)


@pytest.fixture
def scene(tmp_path):
    with Scene(tmp_path / "logs", domain_id=int(os.environ["ROS_DOMAIN_ID"])) as sc:
        yield sc


def test_a_stalled_node_keeps_the_needles_track_and_resumes_without_a_jolt(scene):
    obs = Observer()
    try:
        node = scene.node(*os.environ.get("STALL_CONTROL", "").split(), params=NEEDLE_PARAMS)
        scene.wait_for_log(node, "live:", timeout_s=180)
        scene.start("bridge", "bridge")
        device = scene.start("device", "device", "--hand-path", "needle_straight", "--start-delay-s", "3.0")
        deadline = time.monotonic() + 120
        while time.monotonic() < deadline and not any(r >= 1 for _, r, _, _ in obs.needle):
            time.sleep(0.002)
        assert any(r >= 1 for _, r, _, _ in obs.needle), "the skin was not punctured: " + node.log()[-2000:]
        before = [n for n in obs.needle if n[1] >= 1][-1]
        node.popen.send_signal(signal.SIGSTOP)
        t_stop = time.monotonic_ns()
        time.sleep(STALL_S)
        node.popen.send_signal(signal.SIGCONT)
        device.popen.wait(timeout=120)
        time.sleep(0.3)
    finally:
        obs.close()
    # the track survives: while the needle is in, the same entry and never fewer layers cut (no second puncture)
    after = [n for n in obs.needle if n[0] > t_stop]
    inside = []
    for n in after:
        if not n[2]:
            break
        inside.append(n)
    assert len(inside) > 5, "the needle was out of the tissue right after the stall: its track was erased"
    assert all(np.allclose(n[3], before[3], atol=1e-9) for n in inside), (before[3], {n[3] for n in inside})
    assert min(n[1] for n in inside) >= before[1]
    # the node's forces are the offline session's answer to the poses it answered (the stall stepped over in parts)
    stamps = sorted(s for s in obs.wrench if s in obs.poses)
    cfg = load_tissue_config(NEEDLE_PARAMS)
    session = HapticSession(make_tool(cfg), SessionParams(max_stamp_age_s=0.0))
    truth, prev = {}, None
    for s in stamps:
        xyz, quat = obs.poses[s]
        session.on_pose(s, "tissue", xyz, quat=quat)
        truth[s] = np.asarray(session.tick(s, 0 if prev is None else s - prev).force_n)
        prev = s
    t_live = np.array([np.linalg.norm(obs.wrench[s]) for s in stamps])
    t_off = np.array([np.linalg.norm(truth[s]) for s in stamps])
    s_arr = np.array(stamps, dtype=float)
    gaps = np.diff(s_arr) * ((t_off[:-1] > 0.05) | (t_off[1:] > 0.05))
    resume = s_arr[int(np.argmax(gaps)) + 1]  # the first answer after the longest in-contact gap: the stall's end
    # never above the offline answer (a restart's jolt); below it only in dips that end within RAMP_S of pose time or
    # RAMP_ANSWERS answers (a
    # force that collapsed, or a track erased, fails). A dip is the force's return at the rate bound on the node's clock
    # from a stall's zero: after the SIGSTOP, and after any other stall the node's watchdog saw on its own clock (a CI
    # run, 2026-12-03: a second one 214 ms after the resume, its first answer 4.8 us after the last, so 0.0048 N),
    # which the offline session, stepping on stamps, does not see
    tol = 0.2 * t_off + 0.05
    above = t_live - t_off - tol
    below = (t_off - t_live - tol) > 0.0
    dips, start = [], None
    for i in range(len(s_arr)):
        if below[i] and start is None:
            start = i
        elif not below[i] and start is not None:
            dips.append((start, i))
            start = None
    if start is not None:
        dips.append((start, len(s_arr)))  # never recovered
    long = [(a, b) for a, b in dips if b == len(s_arr) or (s_arr[b] - s_arr[a] >= RAMP_S * 1e9 and b - a > RAMP_ANSWERS)]
    # the node met the stall in one of three ways, as its threads happened to resume: as a stall (its clock ran first
    # and its watchdog fired), as a long stamp interval stepped in parts (DDS's depth-1 history kept only the newest
    # pose of the backlog), or by answering poses of the backlog at intervals of max_dt_s or less, none stepped in
    # parts (a pose callback ran before the clock and the executor took more than one buffered pose: a CI run,
    # 2026-12-06). Whichever, the checks above and below hold; the third leaves no log line, and the answers show it
    log = node.log()
    max_dt_s = SessionParams().max_dt_s
    seen = "poses resumed after" in log or "stepped in parts" in log
    assert seen or gaps.max() <= max_dt_s * 1e9, (
        f"an in-contact interval of {gaps.max() * 1e-6:.0f} ms between answers, more than max_dt_s = "
        f"{max_dt_s * 1e3:.0f} ms, and the node logged neither a stall nor a stepped interval: " + log[-2000:]
    )
    print(
        f"answered {len(stamps)} poses (as recorded); max live - offline {np.max(t_live - t_off):+.4f} N; "
        f"{len(dips)} dips below the offline answer, the longest "
        f"{max(((s_arr[min(b, len(s_arr) - 1)] - s_arr[a]) * 1e-6 for a, b in dips), default=0.0):.1f} ms"
    )
    assert len(stamps) > 100 and t_off.max() > 0.3
    w = int(np.argmax(above))
    assert above.max() <= 0.0, (
        f"a published force {above.max():.3f} N above the offline answer (0.2 x + 0.05 N): live {t_live[w]:.4f} N, "
        f"offline {t_off[w]:.4f} N, {(s_arr[w] - resume) * 1e-6:+.1f} ms from the resume"
    )
    assert not long, "the force stayed below the offline answer (0.2 x + 0.05 N) for RAMP_S or more: " + ", ".join(
        f"live {t_live[a]:.4f} N, offline {t_off[a]:.4f} N from {(s_arr[a] - resume) * 1e-6:+.1f} ms after the resume"
        for a, _ in long[:3]
    )
    # the device's commands in the 200 ms after the resume (the first answer after the longest in-contact gap), against
    # the truth of the answered poses around each command's stamp (+-20 ms): no jolt from a restart
    c = np.array(obs.commands, dtype=float)
    c = c[(c[:, 0] >= resume) & (c[:, 0] < resume + 0.2e9)]
    worst = -np.inf
    for t, fx, fy, fz in c:
        near = np.abs(s_arr - t) <= 20e6
        if near.any():
            worst = max(worst, float(np.linalg.norm((fx, fy, fz)) - (1.2 * t_off[near].max() + 0.05)))
    print(
        f"longest in-contact gap {gaps.max() * 1e-6:.0f} ms; {len(c)} device commands in the 200 ms after it; the node "
        + ("logged the stall" if seen else "answered buffered poses at intervals of max_dt_s or less")
    )
    # (the observer is a DDS reader: under load it misses commands)
    assert len(c) >= 3 and worst <= 0.0, f"a device command {worst:.3f} N above 1.2 x the true force + 0.05 N"
