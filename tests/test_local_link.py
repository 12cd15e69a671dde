"""A composed bridge's link to the node in its process (``skin_sim_node.device.links.LocalLink``): the servo thread
answers its own due pose when the node's lock is free, else the link's thread does; a failing node tick never
reaches the servo loop. The node here is a stand-in that records its calls (no DDS, no model); nothing depends on
timing beyond waiting, with a generous bound, for the link's thread to act."""

from __future__ import annotations

import threading
import time

import pytest

from skin_sim_node.device.links import LocalLink

WAIT_S = 10.0


class _Node:
    """What a LocalLink needs of ``SkinSimNode``: its hands' queues, the non-blocking and the blocking take."""

    def __init__(self, lock_free: bool = True, fail: bool = False):
        self.local_model_sinks: dict = {}
        self.lock_free = lock_free
        self.fail = fail
        self.posted: list[tuple] = []
        self.takes: list[tuple[str, int]] = []  # (thread name, hand) of each take that answered
        self.failed = 0  # takes that raised

    def post_pose(self, stamp, frame, xyz, quat, hand=0):
        self.posted.append(("pose", stamp, hand))

    def post_twist(self, stamp, frame, lin, hand=0):
        self.posted.append(("twist", stamp, hand))

    def take_inputs(self, hand=0, blocking=True):
        if not blocking and not self.lock_free:
            return False
        if self.fail:
            self.failed += 1
            raise RuntimeError("tick failed")
        self.takes.append((threading.current_thread().name, hand))
        return True


class _Bridge:
    tissue_frame = "tissue"

    def _on_local_model(self, msg):  # pragma: no cover - the stand-in node never ticks
        pass


def _link(node, hand=1):
    return LocalLink(_Bridge(), node, hand=hand)


def _until(cond) -> bool:
    t_end = time.monotonic() + WAIT_S
    while time.monotonic() < t_end and not cond():
        time.sleep(0.005)
    return cond()


def test_the_lock_free_the_pose_is_answered_on_the_callers_thread_and_the_link_stays_asleep():
    node = _Node(lock_free=True)
    link = _link(node)
    try:
        link.send((5, (0.0, 0.0, -1e-3), (0.0, 0.0, 0.0, 1.0)), (5, (0.0, 0.0, 0.0)))
        assert node.posted == [("twist", 5, 1), ("pose", 5, 1)]  # the twist first, then its pose, in the hand's queue
        assert node.takes == [(threading.current_thread().name, 1)]  # answered here, once
        assert link.served_here == 1 and link.forwarded == 1
        time.sleep(0.1)  # the link's thread would have answered by now had it been woken
        assert len(node.takes) == 1
    finally:
        link.close()


def test_the_lock_held_the_links_thread_answers_and_the_caller_returns_at_once():
    node = _Node(lock_free=False)
    link = _link(node)
    try:
        link.send((7, (0.0, 0.0, -1e-3), (0.0, 0.0, 0.0, 1.0)))
        assert link.served_here == 0
        assert _until(lambda: node.takes == [("local-link", 1)])  # answered on the link's thread, for its hand
    finally:
        link.close()


def test_a_failing_node_tick_is_reported_once_and_never_reaches_the_servo_loop(capsys):
    node = _Node(lock_free=True, fail=True)
    link = _link(node)
    try:
        for k in range(3):
            link.send((k, (0.0, 0.0, -1e-3), (0.0, 0.0, 0.0, 1.0)))  # does not raise
        out = capsys.readouterr().out
        assert out.count("node tick failed for hand 1: RuntimeError('tick failed') (reported once)") == 1
        assert link.served_here == 3  # its inputs were taken with the failed tick: no link thread woken for them
    finally:
        link.close()


@pytest.mark.parametrize("lock_free", [True, False])
def test_close_removes_the_hands_model_sink(lock_free):
    node = _Node(lock_free=lock_free)
    link = _link(node, hand=0)
    assert 0 in node.local_model_sinks
    link.close()
    assert 0 not in node.local_model_sinks


def test_the_links_thread_outlives_a_failing_node_tick_and_failing_diagnostics(capsys):
    """A tick that raises on the link's thread (the lock held when the pose came) and a raising diagnostics call are
    each reported once; the thread goes on and answers the hand's next pose (it used to end silently, and the hand's
    models stopped)."""
    node = _Node(lock_free=False, fail=True)
    calls = []

    def diagnostics():
        calls.append(1)
        raise ValueError("diagnostics broke")

    link = LocalLink(_Bridge(), node, periodic=(0.01, diagnostics), hand=1)
    try:
        for k in range(3):
            link.send((k, (0.0, 0.0, -1e-3), (0.0, 0.0, 0.0, 1.0)))
            assert _until(lambda k=k: node.failed == k + 1)  # the link's thread took it, and its tick raised
        assert _until(lambda: len(calls) >= 3)
        node.fail = False
        link.send((9, (0.0, 0.0, -1e-3), (0.0, 0.0, 0.0, 1.0)))
        assert _until(lambda: node.takes == [("local-link", 1)])  # still answering, on its own thread
        out = capsys.readouterr().out
        assert out.count("node tick failed for hand 1: RuntimeError('tick failed') (reported once)") == 1
        assert out.count("diagnostics failed for hand 1: ValueError('diagnostics broke') (reported once)") == 1
    finally:
        link.close()


class _ServerBridge:
    tissue_frame = "tissue"
    model_source = True

    def get_name(self):
        return "skin_sim_bridge_test"

    def _on_local_model(self, msg):  # pragma: no cover - a server link hands models to on_model
        pass


def test_the_server_links_thread_outlives_a_model_it_cannot_take_and_failing_diagnostics(ros_domain, capsys):
    """The bridge's DDS link to a node in another participant: a contact model whose handler raises and a raising
    diagnostics call are each reported once; the thread goes on taking models and forwarding poses (it used to
    re-raise and end, and the hand's models stopped)."""
    rclpy = pytest.importorskip("rclpy")
    from msgs_schema.qos import publisher, subscription
    from skin_sim_node.device.links import ServerLink

    taken = []

    def on_model(data):
        taken.append(data)
        if len(taken) == 1:
            raise ValueError("model broke")

    def diagnostics():
        raise RuntimeError("diagnostics broke")

    ctx = rclpy.Context()
    rclpy.init(context=ctx)
    node = rclpy.create_node("server_link_test_node", context=ctx)
    poses = []
    subscription(node, "tool_pose", poses.append, raw=True)
    pub = publisher(node, "contact_model")
    link = ServerLink(_ServerBridge(), [], on_model, periodic=(0.01, diagnostics))
    try:
        msg = pub.msg_type()
        assert _until_spin(node, ctx, lambda: pub.get_subscription_count() > 0)
        for k in range(2):  # the first raises, the second is taken (best effort: sent until one arrives)
            msg.sequence = k
            assert _until_spin(node, ctx, lambda k=k: len(taken) > k, lambda: pub.publish(msg))
        pose = (11, (0.0, 0.0, -1e-3), (0.0, 0.0, 0.0, 1.0))
        assert _until_spin(node, ctx, lambda: len(poses) >= 1, lambda: link.send(pose))  # still forwarding after both failures
        out = capsys.readouterr().out
        assert out.count("the node's model failed: ValueError('model broke') (reported once)") == 1
        assert out.count("diagnostics failed: RuntimeError('diagnostics broke') (reported once)") == 1
    finally:
        link.close()
        node.destroy_node()
        rclpy.shutdown(context=ctx)


def _until_spin(node, ctx, cond, each=None) -> bool:
    """Spin ``node`` until ``cond`` holds (at most :data:`WAIT_S`), calling ``each`` before every spin."""
    import rclpy

    ex = rclpy.executors.SingleThreadedExecutor(context=ctx)
    ex.add_node(node)
    try:
        t_end = time.monotonic() + WAIT_S
        while time.monotonic() < t_end and not cond():
            if each is not None:
                each()
            ex.spin_once(timeout_sec=0.01)
        return cond()
    finally:
        ex.remove_node(node)


def test_the_server_links_thread_outlives_a_failing_wait(ros_domain, capsys, monkeypatch):
    """A wait on the node's topics that raises (three times here) is reported once; the link's thread waits
    ``WAIT_RETRY_S`` and goes on: it still forwards poses and takes models (it used to re-raise and end)."""
    rclpy = pytest.importorskip("rclpy")
    from msgs_schema.qos import publisher, subscription
    from skin_sim_node.device import links

    real = links._rclpy
    fails = {"left": 3}

    class _FlakyWaitSet:
        def __init__(self, *args):
            self._ws = real.WaitSet(*args)

        def __getattr__(self, name):
            return getattr(self._ws, name)

        def wait(self, timeout):
            if fails["left"] > 0:
                fails["left"] -= 1
                raise RuntimeError("wait broke")
            return self._ws.wait(timeout)

    class _Impl:
        WaitSet = _FlakyWaitSet

    monkeypatch.setattr(links, "_rclpy", _Impl)
    taken = []
    ctx = rclpy.Context()
    rclpy.init(context=ctx)
    node = rclpy.create_node("server_link_wait_test_node", context=ctx)
    poses = []
    subscription(node, "tool_pose", poses.append, raw=True)
    pub = publisher(node, "contact_model")
    link = links.ServerLink(_ServerBridge(), [], taken.append)
    try:
        msg = pub.msg_type()
        assert _until_spin(node, ctx, lambda: pub.get_subscription_count() > 0)
        assert _until_spin(node, ctx, lambda: fails["left"] == 0)
        assert _until_spin(node, ctx, lambda: len(taken) >= 1, lambda: pub.publish(msg))  # models after the failures
        pose = (12, (0.0, 0.0, -1e-3), (0.0, 0.0, 0.0, 1.0))
        assert _until_spin(node, ctx, lambda: len(poses) >= 1, lambda: link.send(pose))  # and poses
        assert link._thread.is_alive()
        out = capsys.readouterr().out
        assert out.count("the link's wait failed: RuntimeError('wait broke') (reported once)") == 1
    finally:
        link.close()
        node.destroy_node()
        rclpy.shutdown(context=ctx)
