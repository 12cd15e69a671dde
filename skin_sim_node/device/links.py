"""The bridge's two links towards the node: :class:`ServerLink` (its own DDS participant and one thread, the default)
and :class:`LocalLink` (the node in the same process, ``skin-sim bridge --with-node``). Both take the newest due pose
from the servo thread (:meth:`send`) and give the node's contact models back to the bridge."""

from __future__ import annotations

import threading
import time
from collections.abc import Callable
from typing import Protocol

import rclpy
from geometry_msgs.msg import TwistStamped
from rclpy.guard_condition import GuardCondition
from rclpy.impl.implementation_singleton import rclpy_implementation as _rclpy

from msgs_schema.convert import PoseCdr, fill_twist
from msgs_schema.qos import publisher, subscription
from msgs_schema.topics import FRAMES

from ..ros_util import set_realtime, start_own_thread
from .base import publish_while_ok
from .mapping import without_namespace_remap


class BridgeNode(Protocol):
    """What a link needs of the bridge (:class:`skin_sim_node.device.bridge.BridgeNode`)."""

    tissue_frame: str
    model_source: bool

    def get_name(self) -> str: ...

    def _on_local_model(self, msg) -> None: ...


def _report_once(reported: set[tuple[str, str]], what: str, exc: Exception, where: str = "") -> None:
    """Print a link's failure of ``what`` (a node tick, a model, forwarding a pose, the diagnostics) once per kind of
    exception, ``reported`` holding the kinds already said: the link's thread goes on serving its hand."""
    if (what, type(exc).__name__) not in reported:
        reported.add((what, type(exc).__name__))
        print(f"skin-sim bridge: {what} failed{where}: {exc!r} (reported once)", flush=True)


LINK_JOIN_S = 2.0
"""How long the bridge waits at shutdown for each of its node-link threads (they poll every 50 ms)."""

WAIT_RETRY_S = 0.01
"""After a failed wait on the node's topics, the server link's thread waits this long before the next (10 ms, a
server period at 100 Hz): a wait set that keeps failing costs a wake-up every 10 ms instead of a core at SCHED_FIFO,
and a pose handed meanwhile still goes out."""


class ServerLink:
    """The bridge's side towards the node, on its own DDS participant (an rclpy context) and one thread.

    Measured (tests/test_force_path_ros.py): a node killed with SIGKILL while writing into a participant's
    shared-memory port stalls that port for 1000 ms (Fast DDS's health-check timeout). With one participant the
    device's poses then stopped reaching the bridge: no tick to render on, the force held, then a watchdog step.
    Here the node writes only into this participant's port, the device only into the bridge's own, and the tool
    pose goes out from this link's thread (a latest-value hand-off), so a dead node cannot stall the servo path.

    The thread blocks in one wait set (``rcl_wait``, the GIL released) on the node's contact model (serialized: read
    by :class:`msgs_schema.contact_model.ContactModelCdr`, no message object), a guard condition the servo thread
    triggers when a pose is due, and the diagnostics' period: no executor, nothing that polls (issue 27).
    """

    def __init__(
        self,
        bridge: BridgeNode,
        ros_args: list[str],
        on_model: Callable[[bytes], None],
        node_ns: str = "",
        rt_priority: int = 0,
        periodic: tuple[float, Callable[[], None]] | None = None,
        forward_twist: bool = False,
    ):
        self._periodic = periodic
        self._reported: set[tuple[str, str]] = set()  # (what, exception type) of the failures reported: _report
        self.ctx = rclpy.Context()
        rclpy.init(args=without_namespace_remap(ros_args) if node_ns else ros_args, context=self.ctx)
        self.node = rclpy.create_node(
            f"{bridge.get_name()}_server", context=self.ctx, namespace=node_ns or None, start_parameter_services=False
        )
        self.rt_priority = rt_priority
        self._pose_pub = publisher(self.node, "tool_pose")
        self._twist_pub = publisher(self.node, "tool_twist") if forward_twist else None
        self._pose_cdr = PoseCdr(bridge.tissue_frame)
        self._twist = TwistStamped()
        self._on_model = on_model
        key = "contact_model" if bridge.model_source else "tool_wrench"
        # taken by this link's wait set only (the node is in no executor)
        self._sub = subscription(self.node, key, _never_called, raw=True)
        self._latest: tuple | None = None
        self._lock = threading.Lock()
        self._wake = GuardCondition(None, None, context=self.ctx)
        self._stop = threading.Event()
        self.forwarded = 0
        self._thread = threading.Thread(target=self._run, name="server-link", daemon=True)
        start_own_thread(self._thread, f"link-{getattr(bridge, 'hand', 0)}")  # named before a second bridge's change

    def send(self, pose: tuple, twist: tuple | None = None) -> None:
        """Hand the newest due pose ``(stamp, xyz, quat)`` (and the device's twist ``(stamp, linear)``) to the thread."""
        with self._lock:
            self._latest = (pose, twist)
        self._wake.trigger()

    def _run(self) -> None:
        """Wait for a model, a pose to forward or the diagnostics' time; handle each; until :meth:`close`."""
        if self.rt_priority > 1:  # one below the servo thread: no priority inversion through the GIL
            set_realtime(self.rt_priority - 1)
        period_ns = int(self._periodic[0] * 1e9) if self._periodic is not None else 0
        next_ns = time.monotonic_ns() + period_ns  # the first after one period: the bridge finishes its start first
        ws = _rclpy.WaitSet(1, 1, 0, 0, 0, 0, self.ctx.handle)
        sub = self._sub
        sub_handle, wake_handle = sub.handle, self._wake.handle  # once: rclpy's properties cost per call
        while not self._stop.is_set() and self.ctx.ok():
            timeout = max(next_ns - time.monotonic_ns(), 0) if period_ns else 50_000_000
            taken_all = []  # kept when a take fails after some: the models taken before it are handled
            try:
                ws.clear_entities()
                ws.add_subscription(sub_handle)
                ws.add_guard_condition(wake_handle)
                ws.wait(timeout)
                while (taken := sub.handle.take_message(sub.msg_type, True)) is not None:
                    taken_all.append(taken[0])
            except Exception as exc:
                if self._stop.is_set() or not self.ctx.ok():
                    return
                # a wait or take that failed: say it once, and try again after WAIT_RETRY_S (not a hot loop at
                # SCHED_FIFO); the pose and the diagnostics below still go out
                self._report("the link's wait", exc)
                self._stop.wait(WAIT_RETRY_S)
            for data in taken_all:
                try:
                    self._on_model(data)
                except Exception as exc:  # one model the bridge could not take: the next one may be fine
                    self._report("the node's model", exc)
            with self._lock:
                latest, self._latest = self._latest, None
            if latest is not None:
                (stamp, x, q), tw = latest
                try:
                    if tw is not None and self._twist_pub is not None:  # twist first, as the device publishes them
                        tw_msg = fill_twist(self._twist, tw[0], FRAMES["tissue"], tw[1])
                        publish_while_ok(self.node, self._twist_pub, tw_msg)
                    publish_while_ok(self.node, self._pose_pub, self._pose_cdr.fill(stamp, x, q))
                    self.forwarded += 1
                except Exception as exc:
                    self._report("forwarding a pose", exc)
            if self._periodic is not None and time.monotonic_ns() >= next_ns:
                next_ns = time.monotonic_ns() + period_ns
                try:
                    self._periodic[1]()
                except Exception as exc:  # never let it stop the tool pose going to the node
                    self._report("diagnostics", exc)

    def _report(self, what: str, exc: Exception) -> None:
        _report_once(self._reported, what, exc)

    def close(self) -> None:
        """Stop the link's thread, then destroy its node and context, never under a thread still inside them.

        A thread still running after :data:`LINK_JOIN_S` (starved on a loaded machine) keeps the node and the
        context alive until the process exits: destroying them under its wait corrupted the heap at exit
        (``malloc_consolidate(): unaligned fastbin chunk``, exit -6, once in 15 shutdowns beside four busy processes).
        """
        self._stop.set()
        try:
            self._wake.trigger()
        except Exception:
            pass
        self._thread.join(timeout=LINK_JOIN_S)
        if self._thread.is_alive():
            return
        try:
            self.node.destroy_node()
        except Exception:
            pass
        rclpy.try_shutdown(context=self.ctx)


class LocalLink:
    """The node in this process (``skin-sim bridge --with-node``, issue 27 item 5): no DDS hop between them.

    A due pose is queued in the node's hand by the servo thread itself (``SkinSimNode.post_pose``: no lock, a few us)
    and, once the device's command is out, answered on that thread when the node's lock is free
    (``SkinSimNode.take_inputs`` without blocking), else on this link's thread, or by the node's clock when this thread
    is held off (it runs one priority below the servo threads, and the GIL goes to the higher priority first): a
    starved link thread delays an answer but never hides a pose from the node's watchdog, and the servo thread never
    waits for the node's lock (it does run its own hand's tick, after its device's command). Answering on the servo
    thread saves a thread wake-up and a GIL hand-over per answer (docs/two_hands.md, "Session 14": node and bridges
    used less CPU in 12 of 15 alternating quiet pairs, medians 78.4 % of a core against 85.4 %). The node's tick hands
    each contact model back through its ``local_model_sinks`` entry for that hand: per answer, four rclpy messages
    fewer (pose out and in, model out and in). The node still publishes ``tool/wrench`` (and the contact model, for
    other readers) over DDS.
    """

    def __init__(
        self,
        bridge: BridgeNode,
        node,
        rt_priority: int = 0,
        periodic: tuple[float, Callable[[], None]] | None = None,
        hand: int = 0,
    ):
        self.node = node
        self.hand = hand
        """The node's hand this link serves (its index in ``node.hands``)."""
        self._frame = bridge.tissue_frame
        self._periodic = periodic
        self.rt_priority = rt_priority
        node.local_model_sinks[hand] = bridge._on_local_model
        self._pending = False
        self._sent_ns = 0
        self._lock = threading.Lock()
        self._wake = threading.Event()
        self._stop = threading.Event()
        self.forwarded = 0
        self.served_here = 0
        """Poses of :attr:`forwarded` that needed no link thread: answered on the servo thread (the node's lock was
        free), or left to the node's clock (timer mode)."""
        self.longest_ms = {"pickup": 0.0, "answer": 0.0, "here": 0.0, "periodic": 0.0}
        """The link's longest waits (ms): a handed pose before its thread took it (``pickup``), the node's answer to
        it on the link's thread (``answer``: its lock and its tick), on the servo thread (``here``: how long the
        servo thread was away from its device), the periodic call (``periodic``): where a hand's poses stop reaching
        the node while its device streams."""
        self._reported: set[tuple[str, str]] = set()  # (what, exception type) of the failures reported: _report
        self._thread = threading.Thread(target=self._run, name="local-link", daemon=True)
        start_own_thread(self._thread, f"link-{hand}")  # named before a second bridge's change

    def send(self, pose: tuple, twist: tuple | None = None) -> None:
        """Queue the due pose ``(stamp, xyz, quat)`` (and twist ``(stamp, linear)``) in the node's hand (no lock: the
        node's clock takes it if this link's thread is held off) and answer it here if the node's lock is free, else
        wake the link's thread to answer it. A failure of the node's tick here is reported once and does not reach
        the servo loop."""
        if twist is not None:
            self.node.post_twist(twist[0], self._frame, twist[1], hand=self.hand)
        stamp, x, q = pose
        self.node.post_pose(stamp, self._frame, x, q, hand=self.hand)
        self.forwarded += 1
        t0 = time.monotonic_ns()
        try:
            done = self.node.take_inputs(self.hand, blocking=False)  # answered on the caller's (the servo) thread
        except Exception as exc:  # the node's tick failed: the device's command is out; say so once, serve on
            done = True  # its inputs were taken with it
            self._report("node tick", exc)
        if done:
            self.served_here += 1
            self._longest("here", t0)
            return
        with self._lock:
            if not self._pending:
                self._sent_ns = time.monotonic_ns()  # the oldest pose not yet answered: how long the thread kept it waiting
            self._pending = True
        self._wake.set()

    def _longest(self, key: str, since_ns: int) -> None:
        ms = (time.monotonic_ns() - since_ns) * 1e-6
        if ms > self.longest_ms[key]:
            self.longest_ms[key] = ms

    def _run(self) -> None:
        if self.rt_priority > 0:
            # the servo thread's priority, not one below: this thread ticks the node, and below the servo threads,
            # the node's clock and the DDS threads the node starved (docs/two_hands.md, "Session 10"); until session
            # 16 the second bridge's start raised the first hand's link to it by accident, and with both at 79 the
            # alternating pairs answered fewer poses ("Session 16")
            set_realtime(self.rt_priority)
        period_ns = int(self._periodic[0] * 1e9) if self._periodic is not None else 0
        next_ns = time.monotonic_ns() + period_ns
        while not self._stop.is_set():
            self._wake.wait(max(next_ns - time.monotonic_ns(), 0) * 1e-9 if period_ns else 0.05)
            self._wake.clear()
            with self._lock:
                pending, self._pending = self._pending, False
                sent = self._sent_ns
            if pending and not self._stop.is_set():
                self._longest("pickup", sent)
                t0 = time.monotonic_ns()
                try:
                    self.node.take_inputs(self.hand)  # answered here, or already by the node's clock
                except Exception as exc:  # the node's tick failed: say so once and go on answering (as send does)
                    self._report("node tick", exc)
                self._longest("answer", t0)
            if self._periodic is not None and time.monotonic_ns() >= next_ns:
                t0 = next_ns = time.monotonic_ns()
                next_ns += period_ns
                try:
                    self._periodic[1]()
                except Exception as exc:  # the bridge's diagnostics: never the end of this hand's answers
                    self._report("diagnostics", exc)
                self._longest("periodic", t0)

    def _report(self, what: str, exc: Exception) -> None:
        _report_once(self._reported, what, exc, f" for hand {self.hand}")

    def close(self) -> None:
        """Stop the link's thread (the node stops after it: it was built first)."""
        self._stop.set()
        self._wake.set()
        self._thread.join(timeout=LINK_JOIN_S)
        self.node.local_model_sinks.pop(self.hand, None)


def _never_called(_msg) -> None:  # pragma: no cover - the wait-set readers' subscriptions are in no executor
    """The callback of a subscription that only a wait set takes from."""
