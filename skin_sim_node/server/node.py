"""``skin_sim_node``: the rclpy haptic server. Thin: parameters in, messages <-> arrays, model out.

Loop modes (parameter ``loop_mode``):

- ``input`` (default): each accepted tool pose is answered at once, in its callback, with a
  model tick and a wrench stamped with the pose's stamp (lowest pose-to-force latency). A
  ``fallback_rate_hz`` clock in its own thread ticks whenever no pose came for 1.5 of its
  periods, so the tissue keeps relaxing and the watchdog fires when the input stops; those
  wrenches carry the node's clock, as they answer no pose.
- ``timer``: a ``rate_hz`` thread ticks with the newest pose held (zero-order hold); its
  wrenches carry the node's clock.

The model kernels are ``nogil``; one lock orders ticks, parameter swaps and display snapshots.

Size (issue 28: over 500 lines, with a reason): the node is the server's whole ROS surface, its parameter
declarations and live sets, its I/O, the haptic tick's publishes and its diagnostics; the physics, the session, the
server rate and the display live in their own modules.
"""

from __future__ import annotations

import argparse
import functools
import math
import os
import sys
import threading
import time
from collections.abc import Callable

import numpy as np
from diagnostic_msgs.msg import DiagnosticArray, DiagnosticStatus, KeyValue
from rcl_interfaces.msg import FloatingPointRange, IntegerRange, ParameterDescriptor, SetParametersResult
from rclpy.node import Node
from rclpy.parameter import Parameter
from skin_sim_msgs.msg import ContactModel

from msgs_schema import convert as cv
from msgs_schema.parameters import (
    ALL_PARAMETERS,
    NODE_NAME,
    SPEC_BY_NAME,
    TISSUE_PREFIX,
    NodeParams,
    check_overrides,
    check_value,
)
from msgs_schema.qos import publisher
from msgs_schema.spec import check_names
from msgs_schema.tissue import TISSUE_PARAMETERS
from msgs_schema.topics import FRAMES

from ..configure import configure, hand_configs
from ..model import ConfigError, TissueConfig
from ..ros_util import LoopTiming, PeriodicLoop, localhost_udp_env, run_nodes, set_process_realtime, set_realtime
from ..session import WATCHDOG, HapticSession, TickResult
from ..startup import start_line
from ..tools import make_tools, warm_up
from .display import DisplayProcess
from .hand import Hand
from .journal import HELP as JOURNAL_HELP
from .journal import AnswerJournal

STATS_LEN = 16384


def descriptor(spec) -> ParameterDescriptor:
    """The ROS descriptor of a schema entry: description with unit, range, read-only for start-only parameters."""
    read_only = " (read-only: read at start; set it with --ros-args -p or a parameter file)" if spec.read_only else ""
    d = ParameterDescriptor(description=f"{spec.description} [{spec.unit}]{read_only}", read_only=spec.read_only)
    if spec.type is float and spec.min is not None and spec.max is not None:
        d.floating_point_range = [FloatingPointRange(from_value=float(spec.min), to_value=float(spec.max), step=0.0)]
    elif spec.type is int and spec.min is not None and spec.max is not None:
        d.integer_range = [IntegerRange(from_value=int(spec.min), to_value=int(spec.max), step=1)]
    elif spec.min is not None:
        d.additional_constraints = f"{'>' if spec.min_exclusive else '>='} {spec.min}"
    return d


_TISSUE_NAMES = {s.name for s in TISSUE_PARAMETERS}


def reason(exc: Exception) -> str:
    """A rejection reason naming the parameter as the node declares it (``tissue.`` prefix kept).

    Parameters
    ----------
    exc : Exception
        A :class:`ConfigError` of the contract's checks or the model's geometry checks.

    Returns
    -------
    str
    """
    msg = str(exc)
    head = msg.split(" ", 1)[0].rstrip(":")
    return TISSUE_PREFIX + msg if head in _TISSUE_NAMES else msg


def validate(flat: dict, changed=()) -> tuple[NodeParams, TissueConfig]:
    """The node parameters and the built tissue config of a full dotted parameter dict.

    :func:`skin_sim_node.configure.configure`: the contract validates the node parameters, the tissue goes the one way
    every tissue configuration is built (:func:`skin_sim_node.model.config.config_from_flat`, with its geometry checks).

    Parameters
    ----------
    flat : dict
        Declared name -> value.
    changed : iterable of str
        Names checked first against their declared spec, so that the reason names them as declared.

    Returns
    -------
    NodeParams, TissueConfig

    Raises
    ------
    ConfigError
        With the reason.
    """
    return configure(flat, changed)


class SkinSimNode(Node):
    """The haptic server node. See the module docstring and ``docs/ros.md``."""

    TRANSPORT_NOTE = ""  # what localhost_udp_env decided before rclpy started (logged at start)

    def __init__(self, ros_args: list[str] | None = None, journal: AnswerJournal | None = None, **kwargs):
        super().__init__(NODE_NAME, **kwargs)
        # Every override rcl resolved for this node (matching file entries, -p) is checked against the contract before
        # anything is declared: rclpy would silently ignore an unknown name (the node then runs on the defaults) and
        # raise a traceback on a wrong type. The names rclpy declared itself (use_sim_time, ...) are its own.
        # rclpy keeps the overrides in Node._parameter_overrides; it has no public accessor for them.
        self._builtin_parameters = frozenset(self._parameters)
        given = check_overrides({n: p.value for n, p in self._parameter_overrides.items()}, self._builtin_parameters)
        for spec in ALL_PARAMETERS:  # the checked value, so an integer in a file sets a float parameter
            self.declare_parameter(spec.name, given.get(spec.name, spec.default), descriptor(spec), ignore_override=True)
        self._flat = {s.name: self.get_parameter(s.name).value for s in ALL_PARAMETERS}
        self.params, cfg = validate(self._flat, self._flat)  # ConfigError: refuse to start, with the reason
        self.get_logger().info(start_line(self._flat, ros_args, self.get_fully_qualified_name()))  # form, preset, tool
        t0 = time.perf_counter()
        cfgs = hand_configs(self._flat, cfg)
        for c in cfgs:
            warm_up(c)
        self._warmup_s = time.perf_counter() - t0
        self._lock = threading.Lock()
        self._stopped = False  # set under the lock by stop(): no tick, so no publish, after it
        self._frame = FRAMES["tissue"]
        self._sim_time = bool(self.get_parameter("use_sim_time").value)
        # the hands: each its session (a tool of the one tissue), server rate and topics (issue 32)
        names = [self.params.hand_ns] + ([self.params.second_hand_ns] if self.params.second_hand_ns else [])
        self.hands: list[Hand] = []
        for i, (ns, tool) in enumerate(zip(names, make_tools(cfgs))):
            log = functools.partial(self._log_event, hand=i)
            self.hands.append(Hand(self, ns, tool, self.params, self._frame, self._sim_time, log, index=i))
        self._n_undecodable = 0
        self._diag = DiagnosticArray()
        # statistics (ring buffers, written under the lock)
        self._kernel_us = np.zeros(STATS_LEN)
        self._period_us = np.zeros(STATS_LEN)
        self._n_ticks = 0
        self._n_pose_ticks = 0
        self._stats_from = 0
        self._cpu_last = (time.perf_counter_ns(), time.process_time())
        self._cpu_pct = float("nan")
        self._last_diag_ns = time.perf_counter_ns()
        self._display_key: tuple | None = None
        self._pub_diag = publisher(self, "diagnostics")
        self.local_model_sinks: dict[int, Callable[[ContactModel], None]] = {}
        """Per hand index, the composed bridge's in-memory entry for that hand's contact models (``skin-sim bridge
        --with-node``: :class:`~skin_sim_node.device.links.LocalLink`), called with each contact model in the tick (no
        DDS hop, no copy kept)."""
        self.journal: AnswerJournal | None = journal
        """Every answered pose and its force, written at :meth:`stop` (``skin-sim bridge --with-node --journal``).
        Given to the constructor, so it holds the clock's first ticks too: set after it, a heartbeat wrench published
        before could reach a reader and not the journal (a CI-equivalent run: 549 delivered, 548 in it)."""
        self._journal_pose: dict[int, tuple] = {}  # per hand, the last accepted pose (stamp, xyz, quat), for the journal
        self._accepted: tuple[dict, dict, NodeParams, TissueConfig] | None = None  # on_set's validated set, for post_set
        self.add_on_set_parameters_callback(self._on_set_parameters)  # validate (ros2/demos: on_set checks)
        self.add_post_set_parameters_callback(self._post_set_parameters)  # apply the accepted set
        depth = self.params.input_queue_depth
        # serialized in, serialized out: no rclpy message objects on the 1 kHz path (msgs_schema/convert.py)
        for i, hand in enumerate(self.hands):
            hand.subscribe(functools.partial(self._on_pose, hand=i), functools.partial(self._on_twist, hand=i), depth=depth)
        self._diag_timer = self.create_timer(self.params.diagnostics_period_s, self._publish_diagnostics)
        # display work runs in its own process; this thread only copies the modal state to it
        args = [a for a in (ros_args or []) if "__node:=" not in a]
        self._display = DisplayProcess(cfgs, self._display_settings(), args, self.get_namespace())
        self._next_display_ns = 0  # the haptic tick copies the state for the display at display_rate_hz (no thread of its own)
        self._loop = PeriodicLoop(
            self._clock_period_ns(), self._on_clock, name="node-clock", timing=self._haptic_timing(), on_warning=self._warn
        )
        self._apply_rt_scope()
        self._loop.start()
        if self.TRANSPORT_NOTE:
            self.get_logger().info(f"transports: {self.TRANSPORT_NOTE}")
        self.get_logger().info(
            f"live: {self.params.loop_mode} loop at {self.params.rate_hz:.0f} Hz, grid {cfg.grid_shape[1]}x{cfg.grid_shape[0]}, "
            f"numba warm-up {self._warmup_s:.2f} s; {self.session.describe_modes()}"
            + (f"; hands: {self._describe_hands()}" if len(self.hands) > 1 else "")
        )

    # --- hands --------------------------------------------------------------------------
    @property
    def session(self) -> HapticSession:
        """The first hand's session (the only one of a single-tool node)."""
        return self.hands[0].session

    @property
    def _last(self) -> TickResult | None:
        """The first hand's last tick."""
        return self.hands[0].last

    def _describe_hands(self) -> str:
        return ", ".join(f"{h.ns or '(unnamed)'}: {h.session.tool.cfg.tool_shape} ({h.topic('tool_pose')})" for h in self.hands)

    # --- lifecycle --------------------------------------------------------------------
    def stop(self) -> None:
        self._loop.stop()
        with self._lock:  # no tick after this (a composed bridge's link thread may still post and take): the journal
            self._stopped = True  # written below holds every wrench published (a CI run: 868 delivered, 867 in it)
        self._display.close()
        if self.journal is not None:
            path = self.journal.save()
            self.get_logger().info(f"journal: {len(self.journal)} answers written to {path}")

    @property
    def clock_thread_id(self) -> int | None:
        """The kernel thread id of the node's clock (its :class:`~skin_sim_node.ros_util.PeriodicLoop`): a bridge in
        this process runs it at the device path's priority."""
        return self._loop.native_id

    def _warn(self, message: str) -> None:
        self.get_logger().warning(message)

    def _haptic_timing(self) -> LoopTiming:
        p = self.params
        return LoopTiming(
            abs_sleep=p.precise_sleep,
            spin_ns=int(p.spin_tail_us * 1e3),
            rt_priority=p.rt_priority,
            cpus=(p.haptic_cpu,) if p.haptic_cpu >= 0 else (),
        )

    def _apply_rt_scope(self) -> None:
        """SCHED_FIFO beyond the tick clock (which its loop sets itself, at ``rt_priority``).

        The executor thread (this one; it runs the pose callbacks) gets ``rt_priority``; the threads
        that take the haptic lock or the GIL beside it get one less, so a normal-priority holder
        preempted by another process cannot stall a tick (priority inversion): every other thread
        (DDS included) in ``process`` scope; none in ``haptic`` scope (the display snapshot is taken by the
        tick itself).
        """
        p = self.params
        if p.rt_priority <= 0:
            return
        lower = max(p.rt_priority - 1, 1)
        # no SCHED_RESET_ON_FORK in process scope: threads started later (the executor's) inherit it;
        # the display worker process already runs, and the node starts no other process
        problems = [set_process_realtime(lower, reset_on_fork=False, skip_own=True)] if p.rt_scope == "process" else []
        problems.append(set_realtime(p.rt_priority, reset_on_fork=p.rt_scope != "process"))
        problem = next((m for m in problems if m), None)
        if problem:
            self._warn(problem)
        else:
            self.get_logger().info(f"SCHED_FIFO {p.rt_priority} for the haptic threads ({p.rt_scope} scope)")

    def _clock_period_ns(self) -> int:
        """The thread clock: rate_hz in timer mode, fallback_rate_hz in input mode."""
        p = self.params
        return int(1e9 / (p.rate_hz if p.loop_mode == "timer" else min(p.rate_hz, p.fallback_rate_hz)))

    def _display_period_ns(self) -> int:
        return int(1e9 / self.params.display_rate_hz) if self.params.display_rate_hz > 0 else 1_000_000_000

    def _ros_now_ns(self) -> int:
        """ROS time; the system clock directly unless use_sim_time (6 us less per pose)."""
        return self.get_clock().now().nanoseconds if self._sim_time else time.time_ns()

    def _decode(self, key: str, data: bytes):
        """(stamp_ns, frame, position, orientation) of a serialized pose or (stamp_ns, frame, linear) of a twist; None
        for a buffer that is not one (dropped, counted in diagnostics, logged once)."""
        try:
            return cv.read_pose_cdr(data) if key == "tool_pose" else cv.read_stamped_vec3_cdr(data)
        except ValueError as exc:
            self._n_undecodable += 1
            if self._n_undecodable == 1:
                self._log_event("undecodable", f"{key}: {exc}")
            return None

    def _log_event(self, kind: str, message: str, hand: int = 0) -> None:
        """Log a session event once: a warning, except the watchdog after a tool that had left the tissue (the
        normal end of a session: the force was already zero). A second hand's events name it."""
        h = self.hands[hand] if hand < len(getattr(self, "hands", ())) else None
        who = f"{h.ns}: " if h is not None and len(self.hands) > 1 else ""
        text = f"[{kind}] {who}{message} (logged once; counted in diagnostics)"
        if kind == WATCHDOG and h is not None and h.session.force_n == 0.0:  # rclpy: one severity per call site
            self.get_logger().info(text)
        else:
            self.get_logger().warning(text)

    # --- inputs -----------------------------------------------------------------------
    def _on_pose(self, data: bytes, hand: int = 0) -> None:
        if (pose := self._decode("tool_pose", data)) is None:
            return
        stamp, frame, xyz, quat = pose
        self.answer_pose(stamp, frame, xyz, quat, hand=hand)

    def answer_pose(self, stamp: int, frame: str, xyz, quat, hand: int = 0) -> None:
        """Take one tool pose of hand ``hand`` and, in input mode when it is due, answer it at once (a tick, its
        publishes).

        The pose callback's work; also the in-process entry of a composed bridge (``skin-sim bridge --with-node``),
        whose local model then arrives through :attr:`local_model_sinks` (the hand's).
        """
        self.post_pose(stamp, frame, xyz, quat, hand)
        self.take_inputs(hand)

    def post_pose(self, stamp: int, frame: str, xyz, quat, hand: int = 0) -> None:
        """Queue one tool pose of hand ``hand`` for its session (:attr:`Hand.inbox`), stamped with its arrival; takes
        no lock (a composed bridge's servo thread calls it). :meth:`take_inputs` or the clock's next tick takes it."""
        self.hands[hand].post(("pose", stamp, frame, xyz, quat, time.perf_counter_ns(), self._ros_now_ns()))

    def post_twist(self, stamp: int, frame: str, lin, hand: int = 0) -> None:
        """Queue one tool twist of hand ``hand`` (as :meth:`post_pose`), taken before the pose that follows it."""
        self.hands[hand].post(("twist", stamp, frame, lin))

    def take_inputs(self, hand: int = 0, blocking: bool = True) -> bool:
        """In input mode, take hand ``hand``'s queued inputs under the lock and answer each due pose at once; in timer
        mode nothing (the clock's next tick takes them: no thread waits for the lock for them). Without ``blocking``,
        only if the lock is free now. Returns False only when the lock was held by another thread (the inputs stay
        queued); True when they were taken, or need no taking here (timer mode; after :meth:`stop`)."""
        if self.params.loop_mode != "input":
            return True
        if not self._lock.acquire(blocking):
            return False
        try:
            if not self._stopped:
                self._take_inputs(self.hands[hand], answer=True)
        finally:
            self._lock.release()
        return True

    def _take_inputs(self, h: Hand, answer: bool) -> None:
        """Give hand ``h``'s queued inputs (:attr:`Hand.inbox`) to its session, under the lock: every twist in arrival
        order, and the newest pose (a newer pose supersedes an older one not yet taken, as the latest-value hand-offs
        and the keep-last queues before it do; counted in :attr:`Hand.poses_superseded`); with ``answer`` (input
        mode), a tick at once when that pose is due, as its own thread would have made.

        Whichever thread holds the lock takes them: the clock's tick, or the thread of another input. So a thread kept
        waiting for the lock (with two hands, the other hand's tick and the clock take it in turn, and a lock is not
        fair) does not hold its poses back from the session, and the watchdog fires only when no pose reached the node
        (:meth:`post_pose`), not when one waited for the lock.
        """
        inbox = h.inbox
        items = []
        while inbox:
            items.append(inbox.popleft())
        newest = max((i for i, item in enumerate(items) if item[0] == "pose"), default=-1)
        for i, item in enumerate(items):
            if item[0] == "twist":
                h.session.on_twist(*item[1:])
                continue
            if i != newest:
                h.poses_superseded += 1
                continue
            _, stamp, frame, xyz, quat, rx, ros_now = item
            rejected = h.session.on_pose(stamp, frame, xyz, now_ns=ros_now, rx_ns=rx, quat=quat)
            if rejected is None and self.journal is not None:  # what the tick that answers this stamp stepped
                self._journal_pose[h.index] = (stamp, xyz, quat if quat is not None else (math.nan,) * 4)
            if rejected is None and answer and h.rate.due(stamp, rx):
                self._tick(h, rx, pose_driven=True)

    def _on_twist(self, data: bytes, hand: int = 0) -> None:
        if (twist := self._decode("tool_twist", data)) is None:
            return
        stamp, frame, lin = twist[:3]
        self.post_twist(stamp, frame, lin, hand=hand)  # taken with the hand's next pose or tick, in arrival order

    def _on_clock(self, now_ns: int, _elapsed_ns: int) -> None:
        with self._lock:
            if self._stopped:
                return
            answer = self.params.loop_mode == "input"
            for h in self.hands:  # each hand's fallback tick: its poses stopped (watchdog), or timer mode
                self._take_inputs(h, answer)  # a pose queued while its thread waits for the lock is answered here
                if answer and now_ns - h.last_tick_ns < 1.5 * self._clock_period_ns():
                    continue
                self._tick(h, now_ns, pose_driven=False)

    # --- the haptic tick (under the lock) ---------------------------------------------
    def _tick(self, h: Hand, now_ns: int, pose_driven: bool) -> None:
        s = h.session
        elapsed = now_ns - h.last_tick_ns
        t0 = time.perf_counter_ns()
        r = s.tick(now_ns, elapsed)
        t1 = time.perf_counter_ns()
        h.last = r
        h.n_ticks += 1
        h.last_tick_ns = now_ns
        if h is self.hands[0]:  # the loop statistics are the first hand's (each hand's rate: diagnostics)
            i = self._n_ticks % STATS_LEN
            self._kernel_us[i] = (t1 - t0) * 1e-3
            self._period_us[i] = elapsed * 1e-3
            self._n_ticks += 1
            self._n_pose_ticks += pose_driven
        if pose_driven and (msg := h.rate.answered(r.stamp_ns, now_ns, time.time_ns())) is not None:
            if "not held" in msg:  # rclpy: one severity per call site
                self.get_logger().warning(msg)
            else:
                self.get_logger().info(msg)
        stamp = r.stamp_ns if pose_driven else self._ros_now_ns()
        h.publish(r, now_ns, stamp, self.params.idle_heartbeat_hz, self.local_model_sinks.get(h.index))
        if self.journal is not None:  # every tick: the pose it answered (its clock's tick may answer one), or none
            pose = self._journal_pose.get(h.index)
            answered = r.answered and pose is not None and pose[0] == r.stamp_ns
            if answered and pose is not None:
                self.journal.append(h.index, r.stamp_ns, pose[1], pose[2], r.force_n)
            if not answered or stamp != r.stamp_ns:  # the wrench's own stamp, the node's clock's: what DDS carries
                self.journal.append(h.index, stamp, (math.nan,) * 3, (math.nan,) * 4, r.force_n)
        if now_ns >= self._next_display_ns and self.params.display_rate_hz > 0:
            self._next_display_ns = now_ns + self._display_period_ns()
            self._snapshot_display()  # after the publishes: the wrench never waits for it
            stamp_now = self._ros_now_ns()
            for hand in self.hands:
                hand.publish_readout(stamp_now)

    # --- display (built and published by the display worker process) -------------------
    def _display_settings(self) -> dict:
        p = self.params
        return {
            "display_rate_hz": p.display_rate_hz,
            "mesh_rate_hz": p.mesh_rate_hz,
            "publish_mesh": p.publish_mesh,
            "mesh_stride": p.mesh_stride,
            "on_change": p.display_on_change,
        }

    def _snapshot_display(self) -> None:
        """Copy the modal state (a few kB per hand) for the display worker; called by the tick, under the lock.

        Taken in the haptic thread rather than by a display clock thread of its own: such a thread
        woke 60 times a second to contend for the GIL and the lock with the pose callbacks.
        """
        key = tuple(h.session.state_key for h in self.hands)
        if self.params.display_on_change and key == self._display_key:
            return  # lod: the model did not change since the last snapshot (idle)
        self._display_key = key
        self._display.write([h.session.display_state() for h in self.hands])

    # --- diagnostics ------------------------------------------------------------------
    def _publish_diagnostics(self) -> None:
        with self._lock:
            n = self._n_ticks - self._stats_from
            idx = np.arange(self._stats_from, self._n_ticks)[-STATS_LEN:] % STATS_LEN
            kern = self._kernel_us[idx].copy()
            per = self._period_us[idx].copy()
            self._stats_from = self._n_ticks
            s = self.session
            age_ms = (time.perf_counter_ns() - s.pose_rx_ns) * 1e-6 if s.pose_rx_ns else float("inf")
            counts = dict(s.counts)
            regime = dict(s.regime_counts)
            last = self._last
            stale, force = s.stale, s.force_n
            flags, n_aff = (last.flags, last.n_affected) if last is not None else (0, 0)
            kernel_calls, idle_ticks, modes = s.kernel_calls, s.idle_ticks, s.modes_per_axis
            pose_ticks = self._n_pose_ticks
            overruns = self._loop.overruns
            rate_diag = self.hands[0].rate.diagnostics()
            idle_skipped = self.hands[0].n_idle_skipped
            others = [self._hand_values(h) for h in self.hands[1:]]
            stale_others = [h.ns for h in self.hands[1:] if h.session.stale]
        now = time.perf_counter_ns()
        wall = (now - self._last_diag_ns) * 1e-9
        self._last_diag_ns = now
        target_us = 1e6 / self.params.rate_hz
        late = int(np.sum(per > 1.5 * target_us)) if per.size else 0
        missed = int(np.sum(np.maximum(np.rint(per / target_us) - 1, 0))) if per.size else 0  # empty 1/rate slots

        def pct(a, q):
            return f"{np.percentile(a, q):.1f}" if a.size else "nan"

        cpu_now = (time.perf_counter_ns(), time.process_time())
        cpu_wall = (cpu_now[0] - self._cpu_last[0]) * 1e-9
        cpu_pct = 100 * (cpu_now[1] - self._cpu_last[1]) / cpu_wall if cpu_wall > 0 else float("nan")
        self._cpu_last = cpu_now
        values = {
            "achieved_rate_hz": f"{n / wall:.1f}" if wall > 0 else "nan",
            "target_rate_hz": f"{self.params.rate_hz:.1f}",
            **rate_diag,
            "cpu_pct": f"{cpu_pct:.1f}",
            "loop_mode": self.params.loop_mode,
            "ticks_total": str(self._n_ticks),
            "ticks_pose_driven": str(pose_ticks),
            "late_ticks_window": str(late),
            "missed_slots_window": str(missed),
            "clock_overruns_total": str(overruns),
            "period_us_p50": pct(per, 50),
            "period_us_p99": pct(per, 99),
            "kernel_us_p50": pct(kern, 50),
            "kernel_us_p99": pct(kern, 99),
            "kernel_us_max": f"{kern.max():.1f}" if kern.size else "nan",
            "input_age_ms": f"{age_ms:.1f}",
            "input_stale": str(stale),
            "inputs_dropped": str(self.hands[0].inbox_dropped),
            "poses_superseded": str(self.hands[0].poses_superseded),
            "force_n": f"{force:.4f}",
            "n_affected_layers": str(n_aff),
            "model_flags": str(flags),
            "warmup_s": f"{self._warmup_s:.3f}",
            "kernel_calls_total": str(kernel_calls),
            "idle_ticks_total": str(idle_ticks),
            "modes_per_axis": ",".join(map(str, modes)),  # per layer, now (adaptive modes: each layer's level)
            "idle_unpublished_total": str(idle_skipped),
            "undecodable_inputs_total": str(self._n_undecodable),
        }
        values.update({f"count_{k}": str(v) for k, v in sorted(counts.items())})
        values.update({f"regime_{k}": str(v) for k, v in sorted(regime.items())})  # docs/stability.md
        for other in others:  # a second hand's own (the loop statistics above are the first hand's)
            values.update(other)
        st = DiagnosticStatus()
        st.name = f"{self.get_fully_qualified_name()}: haptic loop"
        st.hardware_id = "skin_sim"
        if stale or stale_others:  # any hand: a stalled second device is a warning too
            who = ", ".join(([self.hands[0].ns or "the tool"] if stale else []) + stale_others)
            st.level, st.message = (
                DiagnosticStatus.WARN,
                "input stale: force held at zero" + (f" ({who})" if len(self.hands) > 1 else ""),
            )
        elif late > 0.01 * max(n, 1):
            st.level, st.message = DiagnosticStatus.WARN, f"{late} late ticks in the last {wall:.1f} s"
        else:
            st.level, st.message = DiagnosticStatus.OK, "running"
        st.values = [KeyValue(key=k, value=v) for k, v in values.items()]
        cv.set_stamp(self._diag.header, self.get_clock().now().nanoseconds)
        self._diag.status = [st]
        self._pub_diag.publish(self._diag)

    @staticmethod
    def _hand_values(h: Hand) -> dict[str, str]:
        """A second hand's diagnostics, keyed ``hand_<ns>_...`` (under the lock)."""
        s, key = h.session, f"hand_{h.ns}_"
        age_ms = (time.perf_counter_ns() - s.pose_rx_ns) * 1e-6 if s.pose_rx_ns else float("inf")
        return {
            key + "tool_shape": s.tool.cfg.tool_shape,
            key + "ticks_total": str(h.n_ticks),
            key + "rate_hz": f"{h.rate.rate_hz:.1f}",
            key + "input_age_ms": f"{age_ms:.1f}",
            key + "input_stale": str(s.stale),
            key + "force_n": f"{s.force_n:.4f}",
            key + "inputs_dropped": str(h.inbox_dropped),
            key + "poses_superseded": str(h.poses_superseded),
            **{key + f"count_{k}": str(v) for k, v in sorted(s.counts.items())},
        }

    # --- live parameters: validated once in on_set, applied in post_set (as ros2/demos) -------------
    def set_parameters_atomically(self, parameter_list: list[Parameter]) -> SetParametersResult:
        """A live set (the parameter services call this for both set services): names and values checked against the
        contract first, so a refusal gives the reason start-up gives (rclpy's own would be "Invalid access to
        undeclared parameter(s)" or its descriptor's range message); an integer for a float parameter is accepted.

        Parameters
        ----------
        parameter_list : list of rclpy.parameter.Parameter

        Returns
        -------
        SetParametersResult
        """
        try:
            check_names((p.name for p in parameter_list), set(SPEC_BY_NAME) | self._builtin_parameters)
            checked = [
                Parameter(p.name, value=check_value(p.name, p.value)) if p.name in SPEC_BY_NAME else p for p in parameter_list
            ]
        except ConfigError as exc:
            why = reason(exc)
            self.get_logger().warning(f"parameter change rejected: {why}")
            return SetParametersResult(successful=False, reason=why)
        return super().set_parameters_atomically(checked)

    def _on_set_parameters(self, params) -> SetParametersResult:
        """Validate a set against the whole parameter set and keep the result for :meth:`_post_set_parameters`.

        Parameters
        ----------
        params : list of rclpy.parameter.Parameter

        Returns
        -------
        SetParametersResult
            Refused with the reason on a :class:`ConfigError`; nothing is applied here.
        """
        ours = [p for p in params if p.name in SPEC_BY_NAME]  # use_sim_time, qos overrides: rclpy's own
        if not ours:
            return SetParametersResult(successful=True)
        changes = {p.name: p.value for p in ours}
        flat = self._flat | changes
        try:
            node_params, cfg = validate(flat, changes)
            hand_configs(flat, cfg)  # the second hand's tool on the new tissue too (a refusal names why)
        except ConfigError as exc:
            why = reason(exc)
            self.get_logger().warning(f"parameter change rejected: {why}")
            return SetParametersResult(successful=False, reason=why)
        self._accepted = (changes, flat, node_params, cfg)
        return SetParametersResult(successful=True)

    def _post_set_parameters(self, params) -> None:
        """Apply the set on_set accepted: new session limits, loop periods, display settings; a new model on a
        tissue change.

        Parameters
        ----------
        params : list of rclpy.parameter.Parameter
        """
        ours = [p for p in params if p.name in SPEC_BY_NAME]
        if not ours:
            return
        changes = {p.name: p.value for p in ours}
        accepted, self._accepted = self._accepted, None
        if accepted is None or accepted[0] != changes:  # rclpy calls post_set right after on_set accepted this set
            accepted = (changes, self._flat | changes, *validate(self._flat | changes, changes))
        _, flat, node_params, cfg = accepted
        tissue_set = any(p.name.startswith(TISSUE_PREFIX) for p in ours)
        new_tools = make_tools(hand_configs(flat, cfg)) if tissue_set else None
        with self._lock:
            now = time.perf_counter_ns()
            for i, h in enumerate(self.hands):
                if new_tools is not None:
                    h.session.set_tool(new_tools[i])
                    h.add_readout()
                h.set_params(node_params, now)
            if new_tools is not None:
                self._display.set_tissue(
                    [h.session.tool.cfg for h in self.hands]
                )  # under the lock: snapshots carry the new version
            self.params = node_params
            self._flat = flat
            self._loop.period_ns = self._clock_period_ns()
        self._next_display_ns = 0  # a new display rate applies at the next tick
        self._display.set_display(self._display_settings())
        self.get_logger().info(
            "parameters applied: "
            + ", ".join(f"{p.name}={p.value}" for p in ours)
            + (" (tissue restarts at rest)" if new_tools else "")
        )


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(prog="skin-sim node", description="Run skin_sim_node (ROS args after --ros-args).")
    ap.add_argument("--executor", choices=("events", "single"), default="events", help="rclpy executor (default events)")
    ap.add_argument(
        "--switch-interval-s",
        type=float,
        default=2e-4,
        help="Python GIL switch interval (default 0.2 ms, not 5 ms, so the haptic thread preempts display work quickly)",
    )
    ap.add_argument(
        "--localhost-shm",
        action="store_true",
        help="under ROS_AUTOMATIC_DISCOVERY_RANGE=LOCALHOST keep rmw_fastrtps's shared memory (default: UDPv4 on this "
        "host only, no multicast: a joining reader's shared-memory port froze the node's receive path for ~335 ms)",
    )
    ap.add_argument(
        "--journal",
        metavar="FILE",
        default=None,
        help=JOURNAL_HELP,
    )
    args, rest = ap.parse_known_args(argv)
    sys.setswitchinterval(args.switch_interval_s)
    updates, SkinSimNode.TRANSPORT_NOTE = localhost_udp_env(os.environ, keep_shm=args.localhost_shm)
    os.environ.update(updates)  # before rclpy creates a participant (the display worker inherits it)

    def build() -> SkinSimNode:
        return SkinSimNode(ros_args=rest, journal=None if args.journal is None else AnswerJournal(args.journal))

    return run_nodes([build], args=rest, executor=args.executor)


if __name__ == "__main__":
    raise SystemExit(main())
