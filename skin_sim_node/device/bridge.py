"""``skin-sim bridge``: a Geomagic Touch (Phantom Omni) ROS 2 driver <-> skin_sim_node.

Device side, under ``device_ns`` (relative, default ``device``):

- ``convention:=crtk`` (jhu-saw sawSensablePhantom): reads ``measured_cp`` (PoseStamped),
  ``measured_cv`` (TwistStamped) and, if the driver publishes it, ``measured_cf`` (the force applied over
  the tick: the passivity observer books it exactly), writes ``servo_cf`` (WrenchStamped): a force every
  servo tick.
- ``convention:=omni`` (omni_common family): reads ``phantom/pose``, writes ``phantom/force_feedback``.

Node side: publishes ``tool/pose`` and ``tool/twist`` in the tissue frame. With ``force_source:=model``
(default) it subscribes ``tool/contact_model`` and, for every device pose, renders the force from the
newest model at that pose (:class:`skin_sim_node.device.render.ContactRenderer`: crossfade, TTL and
radius fade on the device's clock, one-sided normal, friction cone, force, stiffness and damping caps, optional
passivity controller) and sends it
at once: the device gets a force every tick, never a stale one. ``force_source:=wrench`` holds the last
``tool/wrench`` instead (the hold-last bridge, for servers without a contact model), through the same
renderer (a model with no stiffness: held, faded once older than ``watchdog_s``) and passivity controller.

The servo path (device pose in, render, command out) runs at SCHED_FIFO :data:`RT_PRIORITY` where the OS allows it,
answers every queued pose (:data:`DEVICE_QUEUE_DEPTH`), and under ``LOCALHOST`` discovery keeps off shared memory
(:func:`skin_sim_node.ros_util.localhost_udp_env`). ``node_ns`` moves only the node's topics.

A watchdog sends one zero force when the device pose is older than ``watchdog_s`` (the device has
stopped reporting; no tick to render on). Diagnostics (``diagnostics``, 1 Hz) report the render rate,
ticks without a fresh model and the model ages. See ``docs/devices.md``.

Size (issue 28: over 500 lines, with a reason): one node, the device path end to end (servo thread, model hand-off,
watchdog, hints, diagnostics); its links (:mod:`.links`), parameter table (:mod:`.bridge_params`) and renderer
(:mod:`.render`) are modules of their own.
"""

from __future__ import annotations

import math
import os
import sys
import threading
import time

import numpy as np
import rclpy
from diagnostic_msgs.msg import DiagnosticArray, DiagnosticStatus, KeyValue
from geometry_msgs.msg import WrenchStamped
from rclpy.guard_condition import GuardCondition
from rclpy.impl.implementation_singleton import rclpy_implementation as _rclpy
from skin_sim_msgs.msg import ContactModel

from msgs_schema.contact_model import ContactModelCdr, LocalModel, read_contact_model
from msgs_schema.convert import WrenchCdr, read_pose_cdr, read_stamped_vec3_cdr, set_stamp
from msgs_schema.qos import PROFILES, publisher, subscription
from msgs_schema.topics import FRAMES, TOPICS

from ..rate import AnswerThrottle
from ..ros_util import hold_cpu_latency, localhost_udp_env, ros_now_ns, set_pid_realtime, set_realtime, start_own_thread
from ..server.journal import HELP as JOURNAL_HELP
from ..server.journal import AnswerJournal
from .base import DeviceNode, publish_while_ok
from .bridge_params import BRIDGE_PARAMS, FRICTION_RENDERS, RT_PRIORITY, SOURCES, STABILISERS  # noqa: F401
from .links import LINK_JOIN_S, LocalLink, ServerLink, _never_called
from .mapping import (
    CONVENTIONS,
    MEASURED_FORCE,
    DeviceMapping,
    axes_matrix,
    force_to_tissue,
    normalize_namespace,
)
from .render import SERVO_PERIOD_S, ContactRenderer, stable_damping_n_s_per_m

TWIST_MAX_SKEW_NS = 5_000_000  # a device twist this close to the pose's stamp is the pose's velocity (as the node's 5 ms)
HOLD_RADIUS_M = 1.0  # wrench source: a held force does not depend on the pose (any pose on a Touch's workspace)
AGE_RING = 4096  # model ages kept for the diagnostics window (4 s at 1 kHz)
STAMP_MEMORY = 16
"""Device twists and measured forces kept by stamp (16 ticks): a burst of queued device messages is taken topic by
topic, so each pose finds the twist and the applied force of its own tick."""
DEVICE_QUEUE_DEPTH = 10
"""History depth of the device pose, twist and measured-force subscriptions: device poses that arrive while the
servo thread is busy (a burst after a scheduling hiccup) are each answered, in order, with their own stamp, instead
of all but the newest being overwritten (issue 19: depth 1 answered 85 % of the poses). 10 ms at 1 kHz."""
SWITCH_INTERVAL_S = 2e-4
"""``sys.setswitchinterval`` of the bridge (Python's default 5 ms): a servo thread waiting for the GIL gets it
within 0.2 ms of the link thread holding it (the node uses the same)."""


NO_NODE_HINT_NS = 3_000_000_000
"""Device poses without a contact model (or wrench) from the node for this long (3 s; DDS discovery on localhost
takes well under 2 s): the bridge says once that the node seems missing."""


class BridgeNode(DeviceNode):
    """Device driver topics <-> node topics; renders the local contact model every device tick."""

    NODE_NAME = "skin_sim_bridge"
    PROG = "skin-sim bridge"
    DESCRIPTION = (
        "Device bridge: device pose -> tool/pose; tool/contact_model rendered at the device's rate -> force "
        "command (CRTK servo_cf or omni force_feedback). Start it after skin-sim node, before the device."
    )
    PARAMS = BRIDGE_PARAMS

    TRANSPORT_NOTE = ""  # what localhost_udp_env decided before rclpy started (logged at start)
    WITH_NODE = False  # --with-node: skin_sim_node in this process, linked in memory (LocalLink)
    JOURNAL: str | None = None  # --journal FILE: the composed node's answer journal (skin_sim_node.server.journal)

    @classmethod
    def factories(cls, overrides: dict) -> list:
        """The bridge alone, or with ``--with-node`` the node first and the bridge linked to it in memory."""
        if not cls.WITH_NODE:
            return super().factories(overrides)
        from ..server.node import SkinSimNode  # the node's model and numba only when asked for

        built: list = []

        def node():
            built.append(SkinSimNode(ros_args=cls.ROS_ARGS, journal=None if cls.JOURNAL is None else AnswerJournal(cls.JOURNAL)))
            return built[0]

        def bridges():
            host = built[0]
            hands = host.hands
            if len(hands) == 1 and not hands[0].ns:  # one hand, the single-tool names: the process's namespace
                return cls(overrides, local_node=host)
            # a bridge per hand (issue 32), each in its hand's namespace under the node's (its device under
            # /<hand>/<device_ns>, as a bridge started with __ns:=/<hand> has it), linked to its hand in memory. The
            # namespace is a node-local remap: it wins over a global -r __ns:=, which would otherwise put every hand's
            # bridge on the same name and device
            made: list = []
            try:
                for h in hands:
                    ns = "/".join(x for x in (host.get_namespace().strip("/"), h.ns) if x)
                    made.append(cls(overrides, local_node=host, hand=h.index, cli_args=["--ros-args", "-r", f"__ns:=/{ns}"]))
            except BaseException:  # a bridge that did not build: the ones that did stop before the error goes on
                for b in reversed(made):
                    b.stop()
                    b.destroy_node()
                raise
            return made

        return [node, bridges]

    @classmethod
    def add_arguments(cls, ap) -> None:
        """The options beside the parameters: ``--restamp`` and ``--localhost-shm``."""
        ap.add_argument(
            "--restamp",
            dest="restamp",
            action="store_true",
            default=None,
            help="stamp tool poses with the bridge clock instead of the driver's",
        )
        ap.add_argument(
            "--with-node",
            action="store_true",
            help="run skin_sim_node in this process too (its parameters from --ros-args --params-file, keyed "
            "skin_sim_node): poses and contact models handed over in memory, no DDS hop between them; a node with two "
            "hands gets a bridge per hand, each in the hand's namespace",
        )
        ap.add_argument(
            "--journal",
            metavar="FILE",
            default=None,
            help=f"with --with-node: {JOURNAL_HELP}",
        )
        ap.add_argument(
            "--forward-twist",
            dest="forward_twist",
            action="store_true",
            default=None,
            help="also forward the device's measured velocity as tool/twist (default: poses only)",
        )
        ap.add_argument(
            "--localhost-shm",
            action="store_true",
            help="under ROS_AUTOMATIC_DISCOVERY_RANGE=LOCALHOST keep rmw_fastrtps's shared memory (default: UDPv4 on "
            "this host, device/fastdds_localhost_udp.xml: a joining reader cannot freeze the device path)",
        )

    @classmethod
    def before_start(cls, opts) -> int | None:
        """Before rclpy: check ``--axes`` and ``--node-ns`` (a bad one: one line, exit code 2); set the DDS transport."""
        try:
            if opts.axes is not None:
                axes_matrix(opts.axes)
            if opts.node_ns is not None:
                normalize_namespace(opts.node_ns)
        except ValueError as exc:
            print(f"skin-sim bridge: {exc}")
            return 2
        cls.WITH_NODE = bool(opts.with_node)
        if opts.journal is not None and not cls.WITH_NODE:
            print("skin-sim bridge: --journal needs --with-node (the journal is the composed node's)")
            return 2
        cls.JOURNAL = opts.journal
        updates, cls.TRANSPORT_NOTE = localhost_udp_env(os.environ, keep_shm=opts.localhost_shm)
        os.environ.update(updates)  # before rclpy creates a participant: both of the bridge's participants
        return None

    def __init__(self, overrides: dict | None = None, local_node=None, hand: int = 0, **kwargs):
        super().__init__(overrides, **kwargs)
        p = self.p
        self.hand = hand  # the node's hand this bridge serves (its threads' names: servo-<hand>, link-<hand>)
        self.mapping = DeviceMapping(tuple(p.offset_m), p.scale, p.axes, p.force_scale, p.max_force_n)
        if not self.mapping.proper:
            self.get_logger().warn(f"axes {self.mapping.axes!r} is a reflection: tool orientation is published as identity")
        gain = p.force_scale * p.scale  # device N/m per tissue N/m
        self.renderer = ContactRenderer(
            max_force_n=p.max_force_n / p.force_scale if p.force_scale > 0 else math.inf,
            max_stiffness_n_per_m=p.max_stiffness_n_per_m / gain if gain > 0 else math.inf,
            max_damping_n_s_per_m=p.max_damping_n_s_per_m / gain if gain > 0 else math.inf,  # F_dev / v_dev: the same gain
            fade_s=p.fade_s,
            passivity_mass_kg=p.device_mass_kg / gain if p.stabiliser == "passivity" and gain > 0 else None,
            friction_law=p.friction_render == "law",
            slip_speed_floor_m_s=p.slip_speed_floor_m_s * p.scale,  # device m/s -> tissue m/s
            stick_slope_n_s_per_m=stable_damping_n_s_per_m(p.device_mass_kg, SERVO_PERIOD_S) / gain
            if p.chatter_guard == "on" and gain > 0
            else math.inf,
            max_friction_slope_n_s_per_m=(p.max_friction_slope_n_s_per_m / gain if gain > 0 else math.inf)
            if p.max_friction_slope_n_s_per_m > 0
            else math.inf,
        )
        self.model_source = p.force_source == "model"
        self.watchdog_ns = int(p.watchdog_s * 1e9)
        self.device_frame = p.device_frame
        self.tissue_frame = FRAMES["tissue"]
        ns = p.device_ns.strip("/")
        pose_key, twist_key, force_key = CONVENTIONS[p.convention]

        def dev(key):
            return f"{ns}/{TOPICS[key].name}" if ns else TOPICS[key].name

        self._force_cdr: dict[str, WrenchCdr] = {}  # serialized force command per frame id (one in practice)
        self._last_force = (0.0, 0.0, 0.0)
        self._render_lock = threading.Lock()  # the renderer: models from the server link's thread, ticks from this one
        self._force_pub = self.create_publisher(WrenchStamped, dev(force_key), PROFILES["driver"])
        self._diag_pub = publisher(self, "diagnostics")
        self._diag = DiagnosticArray()
        depth = DEVICE_QUEUE_DEPTH
        # The device path's readers sit on a node of their own that no executor spins: the servo thread takes from
        # them in a wait set (serialized CDR, no message objects). Velocity and applied force before the poses they
        # belong to (a burst is taken topic by topic; STAMP_MEMORY pairs them by stamp).
        self._servo_node = rclpy.create_node(  # the bridge's namespace as a node-local remap: it wins over a global one
            f"{self.get_name()}_servo",
            namespace=self.get_namespace(),
            cli_args=["--ros-args", "-r", f"__ns:={self.get_namespace()}"],
            context=self.context,
            start_parameter_services=False,
        )
        self._servo_subs: list[tuple] = []
        cf_key = MEASURED_FORCE[p.convention]
        # the device's velocity only when the rendered law needs it (read_velocity auto: a model with a damping term
        # or the velocity friction law; the presliding friction and the passivity controller work from positions)
        self._velocity_reader = (twist_key, dev(twist_key) if twist_key else "", depth)
        self._reading_velocity = False
        read_now = bool(twist_key) and (p.read_velocity == "always" or p.forward_twist)
        readers = ((twist_key if read_now else None, self._on_device_twist), (cf_key, self._on_device_force))
        for key, handler in (*readers, (pose_key, self._on_device_pose)):
            if key:
                sub = subscription(self._servo_node, key, _never_called, name=dev(key), depth=depth, raw=True)
                self._servo_subs.append((sub, handler))
        self._reading_velocity = read_now
        self._twists: dict[int, tuple] = {}
        self._forces: dict[int, np.ndarray] = {}
        self._forward = AnswerThrottle(math.inf)  # the node's announced answer period (every pose until it says)
        self._model_cdr = ContactModelCdr.from_message_class(ContactModel)
        self._servo_stop = threading.Event()
        self._servo_wake = GuardCondition(None, None, context=self.context)
        self.rt_message = self._device_path_realtime(p.rt_priority, in_process=local_node is not None)
        if local_node is not None and p.rt_priority > 0 and local_node.clock_thread_id is not None:
            # the node's clock takes a hand's queued pose when its link's thread is held off: at the device path's
            # priority (at 79 with the links, the node starved and models expired: docs/two_hands.md, "Session 10")
            set_realtime(p.rt_priority, local_node.clock_thread_id)
        if p.cpu_latency_us >= 0:  # the device path's wake-ups (bridge_params.CPU_LATENCY_US)
            why = hold_cpu_latency(p.cpu_latency_us)
            self.rt_message += f"; CPU wake-up latency held at {p.cpu_latency_us} us" if why is None else f"; {why}"
        self.node_ns = normalize_namespace(p.node_ns)
        self._ages_ms = np.zeros(AGE_RING)
        self._n_age = 0
        self._win = {"rendered": 0, "models": 0, "t_ns": time.monotonic_ns(), "age_from": 0, "period_max_ns": 0}
        # the diagnostics (percentiles, ~20 key-values, a publish: about a millisecond once a second) run on the node
        # link's publishing thread, not on the servo executor: no device pose waits for them (issue 19, gaps)
        link_prio = p.rt_priority if not self.rt_message.startswith("SCHED_FIFO refused") else 0
        self.server: ServerLink | LocalLink
        if local_node is not None:
            self.model_source = True  # in memory: the node's contact model itself
            self.server = LocalLink(
                self, local_node, link_prio, periodic=(p.diagnostics_period_s, self._publish_diagnostics), hand=hand
            )
        else:
            self.server = ServerLink(
                self,
                self.ROS_ARGS,
                self._on_model if self.model_source else self._on_wrench,
                self.node_ns,
                link_prio,
                periodic=(p.diagnostics_period_s, self._publish_diagnostics),
                forward_twist=bool(p.forward_twist and twist_key),
            )
        self._v_tissue: np.ndarray | None = None
        self._v_stamp_ns = 0
        self._wrench_seq = 0
        self.last_pose_rx_ns: int | None = None
        self.stale = False  # the first watchdog check sends one zero force
        self.counts = {
            "poses": 0,
            "twists": 0,
            "models": 0,
            "models_rejected": 0,
            "wrenches": 0,
            "forwarded": 0,
            "poses_forwarded": 0,
            "zeros": 0,
            "non_finite_pose": 0,
            "rendered": 0,
            "rendered_fresh": 0,
            "rendered_no_model": 0,
            "rendered_stale_model": 0,
            "rendered_outside_radius": 0,
            "device_gaps_2ms": 0,
        }
        self._first_model = False
        self._no_node_since: int | None = None  # monotonic ns of the first device pose while no model came
        self._no_node_hinted = False
        self._no_device_hinted = False
        self._started_ns = time.monotonic_ns()
        self.max_model_age_ms = 0.0
        self._rejected_logged: set[str] = set()
        self._watchdog_period_ns = int(1e9 / p.watchdog_rate_hz)
        self._servo = threading.Thread(target=self._servo_loop, name="servo", daemon=True)
        src = self.server.node.resolve_topic_name(TOPICS["contact_model" if self.model_source else "tool_wrench"].name)
        src = f"{src} rendered per device tick" if self.model_source else src
        tool_pose = self.server.node.resolve_topic_name(TOPICS["tool_pose"].name)
        if local_node is not None:
            h_ns = local_node.hands[hand].ns
            who = f" (hand {h_ns or hand})" if len(local_node.hands) > 1 or h_ns else ""
            tool_pose, src = f"skin_sim_node in this process{who}", "its contact model, in memory, rendered per device tick"
        self.get_logger().info(
            f"bridge {p.convention}: {self.resolve_topic_name(dev(pose_key))} -> {tool_pose}; {src} -> "
            f"{self.resolve_topic_name(dev(force_key))}; "
            f"offset {self.mapping.offset_m} m, scale {self.mapping.scale}, axes {self.mapping.axes}, "
            f"force scale {p.force_scale:g} (device N per tissue N), clamp {p.max_force_n} N, "
            f"stiffness cap {p.max_stiffness_n_per_m:g} N/m, damping cap {p.max_damping_n_s_per_m:g} N s/m, "
            f"stabiliser {p.stabiliser}, friction {p.friction_render}"
            + (f" (slope cap {p.max_friction_slope_n_s_per_m:g} N s/m)" if p.max_friction_slope_n_s_per_m > 0 else "")
        )
        (self.get_logger().info if self.rt_message.startswith("device path") else self.get_logger().warning)(self.rt_message)
        if self.TRANSPORT_NOTE:
            self.get_logger().info(f"transports: {self.TRANSPORT_NOTE}")
        start_own_thread(self._servo, f"servo-{self.hand}")  # named before a second bridge's change

    def _device_path_realtime(self, priority: int, in_process: bool = False) -> str:
        """SCHED_FIFO for every thread that exists now: the device-side participant's DDS threads and the main thread
        (its executor only serves the parameter services; it blocks, and at this priority a busy process cannot hold it
        off the GIL). With SCHED_RESET_ON_FORK, threads started after this do not inherit it: the servo thread sets
        ``priority`` itself, the node link one less (``in_process``, the node in this process: the same, as it ticks
        the node). Threads named ``skin-*`` (``ros_util.OWN_THREAD_PREFIX``) keep
        theirs: with the node in this process, the first hand's servo thread and link keep theirs when the second
        hand's bridge starts (its link was raised to 80), and the node's clock is set to ``priority`` on purpose
        (:meth:`__init__`). Every one of them blocks on I/O: nothing spins at SCHED_FIFO.
        Returns the message to log."""
        if priority <= 0:
            return "device path at normal priority (rt_priority 0)"
        sys.setswitchinterval(SWITCH_INTERVAL_S)
        why = set_pid_realtime(os.getpid(), priority, skip_own=True)
        if why is None:
            return (
                f"device path at SCHED_FIFO {priority} (servo thread blocking in rcl_wait, device-side DDS threads; "
                f"node link {priority if in_process else priority - 1})"
            )
        return (
            f"SCHED_FIFO refused for the device path ({why}): it shares the CPU with the node, the display and joining "
            "readers at normal priority; run as root, or grant CAP_SYS_NICE or an rtprio limit, or pass --rt-priority 0"
        )

    # --- device side: the servo thread ------------------------------------------------------
    def _servo_loop(self) -> None:
        """The device path: block in ``rcl_wait`` on the device's pose (and the watchdog's period); take every queued
        message, velocity and applied force first, then each pose, rendered and answered at once.

        Only the pose wakes the thread: a CRTK driver publishes velocity and applied force beside each pose, and
        waking for each would triple the thread's wake-ups (measured: about 0.1 ms of CPU each). A velocity that
        arrives after its pose is the next tick's (the renderer takes the newest within 5 ms); an applied force
        that does, leaves the passivity observer booking the bridge's own command, as without ``measured_cf``.
        """
        prio = self.p.rt_priority if not self.rt_message.startswith("SCHED_FIFO refused") else 0
        if prio > 0:
            set_realtime(prio)
        pose_sub = self._servo_subs[-1][0]  # the tick: a device pose (its velocity and applied force are taken with it)
        pose_handle, wake_handle = pose_sub.handle, self._servo_wake.handle  # once: rclpy's properties cost per call
        ws = _rclpy.WaitSet(1, 1, 0, 0, 0, 0, self.context.handle)
        next_check = time.monotonic_ns() + self._watchdog_period_ns
        failed: set[str] = set()
        while not self._servo_stop.is_set():  # rclpy's shutdown: the wait raises, or the watchdog's check below
            try:
                ws.clear_entities()
                ws.add_subscription(pose_handle)
                ws.add_guard_condition(wake_handle)
                ws.wait(max(next_check - time.monotonic_ns(), 0))
                for sub, handler in self._servo_subs:  # read each tick: a velocity reader may join (read_velocity auto)
                    while (taken := sub.handle.take_message(sub.msg_type, True)) is not None:
                        handler(taken[0])
                if time.monotonic_ns() >= next_check:
                    # the context once per watchdog period, not per pose: Context.ok() takes a lock the two hands'
                    # servo threads (and rclpy's own) share, and a holder that waits for the GIL holds the other up
                    if not self.context.ok():
                        return
                    next_check = time.monotonic_ns() + self._watchdog_period_ns
                    self._watchdog()
            except Exception as exc:
                if self._servo_stop.is_set() or not self.context.ok():
                    return
                if type(exc).__name__ not in failed:  # keep serving the device; say each kind of failure once
                    failed.add(type(exc).__name__)
                    self.get_logger().error(f"servo tick failed: {exc!r} (logged once per kind; the loop goes on)")

    def _stamp(self, t_ns: int) -> int:
        return ros_now_ns(self) if self.p.restamp or t_ns == 0 else t_ns

    def _decode(self, kind: str, read, data: bytes):
        try:
            return read(data)
        except ValueError as exc:
            if kind not in self._rejected_logged:
                self._rejected_logged.add(kind)
                self.get_logger().warning(f"undecodable device {kind} dropped: {exc} (logged once)")
            return None

    def _on_device_twist(self, data: bytes) -> None:
        if (tw := self._decode("twist", read_stamped_vec3_cdr, data)) is None:
            return
        t_ns, _, v = tw
        if not all(math.isfinite(c) for c in v):
            return
        _remember(self._twists, t_ns, (np.array(self.mapping.velocity_to_tissue(v)), self._stamp(t_ns)))
        self.counts["twists"] += 1

    def _on_device_force(self, data: bytes) -> None:
        if (cf := self._decode("measured force", read_stamped_vec3_cdr, data)) is None:
            return
        t_ns, _, f = cf
        _remember(self._forces, t_ns, np.array(force_to_tissue(self.mapping, f)))

    def _twist_at(self, t_ns: int) -> tuple | None:
        """The device twist of the pose stamped ``t_ns``: its own stamp's, else the newest within the skew."""
        if (tw := self._twists.get(t_ns)) is not None:
            return tw
        if self._twists:
            last = next(reversed(self._twists))
            if abs(last - t_ns) <= TWIST_MAX_SKEW_NS:
                return self._twists[last]
        return None

    def _on_device_pose(self, data: bytes) -> None:
        if (pose := self._decode("pose", read_pose_cdr, data)) is None:
            return
        t_ns, frame, pos, quat = pose
        if not all(math.isfinite(c) for c in pos):
            self.counts["non_finite_pose"] += 1
            return
        now = time.monotonic_ns()
        if self.last_pose_rx_ns is not None:
            period = now - self.last_pose_rx_ns
            self._win["period_max_ns"] = max(self._win["period_max_ns"], period)
            self.counts["device_gaps_2ms"] += period > 2_000_000
        self.last_pose_rx_ns = now
        if not self.device_frame and frame:
            self.device_frame = frame
        q = self.mapping.orientation_to_tissue(quat)
        x = self.mapping.to_tissue(pos)
        stamp = self._stamp(t_ns)
        self.counts["poses"] += 1
        # the servo tick: render at this pose and command at once (wrench source: the last force, held)
        tw = self._twist_at(t_ns)
        v = tw[0] if tw is not None else None
        cf = self._forces.get(t_ns)  # applied over the tick that ended here
        n_radius = self.renderer.counts["fades_radius"]
        with self._render_lock:  # on the device's clock: the pose's stamp
            f = self.renderer.render(stamp * 1e-9, x, v, cf)
            due = self._forward.due(stamp)  # the node answers this pose: forward it (else the model renders it)
        if self.renderer.counts["fades_radius"] > n_radius and "radius" not in self._rejected_logged:
            self._rejected_logged.add("radius")
            m = self.renderer.model
            assert m is not None  # a radius fade needs a model
            self.get_logger().warning(
                f"tool left the contact model's validity radius: |x - x0| = {np.linalg.norm(np.subtract(x, m.x0_m)) * 1e3:.2f} mm"
                f" > {m.validity_radius_m * 1e3:.1f} mm (model {m.sequence}, x0 z {m.x0_m[2] * 1e3:.2f} mm, x z "
                f"{x[2] * 1e3:.2f} mm, age {self.renderer.model_age_s() * 1e3:.1f} ms): fading (logged once)"
            )
        self._publish_force(stamp, self.mapping.force_to_device(tuple(f)))
        self._count_render(now)
        if due:
            self.counts["poses_forwarded"] += 1
            self.server.send((stamp, x, q), None if tw is None else (tw[1], tuple(tw[0])))

    def _count_render(self, now_ns: int) -> None:
        c = self.counts
        c["rendered"] += 1
        self._win["rendered"] += 1
        r = self.renderer
        if r.state in ("model", "crossfade"):
            c["rendered_fresh"] += 1
            age = r.model_age_s() * 1e3
            self._ages_ms[self._n_age % AGE_RING] = age
            self._n_age += 1
            self.max_model_age_ms = max(self.max_model_age_ms, age)
        elif self._first_model:
            c["rendered_no_model"] += 1  # a tick without a valid model (TTL or radius fade) once models flowed
            c["rendered_stale_model" if r.outside_reason == "ttl" else "rendered_outside_radius"] += 1

    # --- node side ----------------------------------------------------------------------
    def _on_model(self, data: bytes) -> None:
        m: LocalModel | None = None
        try:
            m = self._model_cdr.read(data)
        except ValueError as exc:
            self._take_model(None, f"undecodable ({exc})")
            return
        self._take_model(m, None)

    def _on_local_model(self, msg) -> None:
        """The contact model of the node in this process (``--with-node``), from its tick."""
        self._take_model(read_contact_model(msg), None)

    def _take_model(self, m: LocalModel | None, why: str | None) -> None:
        if m is None:
            pass
        elif m.frame_id != self.tissue_frame:
            why = f"frame '{m.frame_id}', expected '{self.tissue_frame}'"
        else:
            with self._render_lock:
                why = self.renderer.set_model(m)  # at the latest device tick: the renderer's clock is the device's
                if why is None and m.answer_period_s * 1e9 != self._forward.period_ns:
                    self._forward.set_period_s(m.answer_period_s)  # the node's rate now: forward poses this often
        if why is None and m is not None:
            if not self._reading_velocity and self.p.read_velocity == "auto" and _needs_velocity(m):
                self._read_velocity(m)
            self._check_needle_peak(m)
            self.counts["models"] += 1
            self._win["models"] += 1
            self._first_model = True
            return
        self.counts["models_rejected"] += 1
        why = why or "unknown"
        kind = why.split(" ")[0]
        if kind not in self._rejected_logged:
            self._rejected_logged.add(kind)
            self.get_logger().warning(f"contact model dropped: {why} (logged once per kind)")

    def _read_velocity(self, m: LocalModel) -> None:
        """Start reading the device's velocity (the first model whose law needs it; one line in the log)."""
        key, name, depth = self._velocity_reader
        self._reading_velocity = True
        if not key:
            return
        sub = subscription(self._servo_node, key, _never_called, name=name, depth=depth, raw=True)
        self._servo_subs = [(sub, self._on_device_twist), *self._servo_subs]  # before the poses it belongs to
        law = "a damping term" if m.damping_n_s_per_m.any() else "the velocity friction law"
        self.get_logger().info(f"the contact model renders {law}: reading the device's velocity ({name}) from now on")

    def _check_needle_peak(self, m: LocalModel) -> None:
        """Say once when a needle's puncture peak ahead, times the force scale, is above the device clamp: the clamp
        flattens it (the user feels a plateau at the clamp and a smaller drop), ``--force-scale`` keeps its shape."""
        law = m.needle
        if law is None or "needle_peak" in self._rejected_logged or law.rupture_distance_m <= 0.0:
            return
        peak = law.axial_force_n + max(law.axial_gradient_n_per_m, 0.0) * law.rupture_distance_m
        k, clamp = self.p.force_scale, self.p.max_force_n
        if k * peak > clamp:
            self._rejected_logged.add("needle_peak")
            self.get_logger().warning(
                f"needle puncture peak ahead {peak:.2f} N x force scale {k:g} = {k * peak:.2f} N is above the device "
                f"clamp {clamp:g} N: the clamp flattens the peak and shrinks the drop; --force-scale {clamp / peak:.2f} "
                "or less renders its shape (logged once)"
            )

    def _on_wrench(self, data: bytes) -> None:
        """Wrench source: the node's force as a model with no stiffness (held until the next, faded after watchdog_s)."""
        self.counts["wrenches"] += 1
        if (w := self._decode("wrench", read_stamped_vec3_cdr, data)) is None:
            return
        t_ns, _, f = w
        self._wrench_seq += 1
        m = LocalModel(
            self._wrench_seq,
            t_ns,
            self.tissue_frame,
            x0_m=np.zeros(3),
            v0_m_s=np.zeros(3),
            f0_n=f,
            stiffness_n_per_m=np.zeros((3, 3)),
            damping_n_s_per_m=np.zeros((3, 3)),
            normal=np.array([0.0, 0.0, 1.0]),
            validity_radius_m=HOLD_RADIUS_M,
            time_to_live_s=self.p.watchdog_s,
        )
        with self._render_lock:
            held = self.renderer.set_model(m) is None
        if held:
            self.counts["forwarded"] += 1
            self._first_model = True

    def _publish_force(self, t_ns: int, f) -> None:
        frame = self.device_frame or "device_base"
        if (cdr := self._force_cdr.get(frame)) is None:
            cdr = self._force_cdr[frame] = WrenchCdr(frame)
        self._last_force = tuple(f)
        publish_while_ok(self, self._force_pub, cdr.fill(t_ns, f))

    def _watchdog(self) -> None:
        now = time.monotonic_ns()
        # a stale node is the renderer's business (it fades); a silent device has no tick to render on
        stale = self.last_pose_rx_ns is None or now - self.last_pose_rx_ns > self.watchdog_ns
        if stale and not self.stale:
            held = math.sqrt(sum(c * c for c in self._last_force))
            self._publish_force(ros_now_ns(self), (0.0, 0.0, 0.0))
            self.counts["zeros"] += 1
            if self.counts["poses"]:  # a device that stopped while pushing is a warning; one that ended lifted is not
                text = f"no device pose for {self.watchdog_ns * 1e-6:.0f} ms: device force set to zero (was {held:.3f} N)"
                if held > 0.0:  # rclpy: one severity per call site
                    self.get_logger().warning(text)
                else:
                    self.get_logger().info(text)
        self.stale = stale
        if not self._no_device_hinted and not self.counts["poses"] and now - self._started_ns > NO_NODE_HINT_NS:
            self._no_device_hinted = True
            pose_topic = self._servo_subs[-1][0].topic_name
            node = "skin_sim_node answers" if self._first_model else "no node either"
            self.get_logger().warning(
                f"no device pose on {pose_topic} in {NO_NODE_HINT_NS * 1e-9:.0f} s ({node}): is the driver "
                "(sawSensablePhantom, a Touch driver, or `skin-sim device`) running with the same ROS_DOMAIN_ID, and "
                "are --convention and --device-ns its? The bridge commands nothing until a pose arrives"
            )
        if self._no_node_since is None and self.counts["poses"] and not self._first_model:
            self._no_node_since = now
        if self._first_model:
            self._no_node_since = None
        elif self._no_node_since is not None and not self._no_node_hinted and now - self._no_node_since > NO_NODE_HINT_NS:
            self._no_node_hinted = True
            ns = self.p.node_ns or "(the bridge's namespace)"
            self.get_logger().warning(
                f"device poses arrive but no {'contact model' if self.model_source else 'wrench'} from skin_sim_node "
                f"in {NO_NODE_HINT_NS * 1e-9:.0f} s: is `skin-sim node` running with the same ROS_DOMAIN_ID, in node "
                f"namespace {ns}? The device gets zero force until it answers"
            )

    # --- diagnostics --------------------------------------------------------------------
    def _publish_diagnostics(self) -> None:
        now = time.monotonic_ns()
        w = self._win
        wall = (now - w["t_ns"]) * 1e-9
        n_new = min(self._n_age - w["age_from"], AGE_RING)
        ages = self._ages_ms[(np.arange(self._n_age - n_new, self._n_age)) % AGE_RING] if n_new > 0 else np.zeros(0)
        c = self.counts
        values = {
            "render_rate_hz": f"{w['rendered'] / wall:.1f}" if wall > 0 else "nan",
            "model_rate_hz": f"{w['models'] / wall:.1f}" if wall > 0 else "nan",
            "device_period_ms_max": f"{w['period_max_ns'] * 1e-6:.2f}",
            "model_age_ms_p50": f"{np.percentile(ages, 50):.2f}" if ages.size else "nan",
            "model_age_ms_p99": f"{np.percentile(ages, 99):.2f}" if ages.size else "nan",
            "model_age_ms_max": f"{ages.max():.2f}" if ages.size else "nan",
            "render_state": self.renderer.state,
            "chatter_guard_engaged_total": str(self.renderer.counts_chatter),
            "force_source": self.p.force_source,
            "force_scale": f"{self.p.force_scale:g}",
            "force_clamp_n": f"{self.p.max_force_n:g}",
            "force_clamped_ticks_total": str(self.renderer.counts_clamped),
        }
        values.update({f"{k}_total": str(v) for k, v in c.items()})
        values.update({f"{k}_total": str(v) for k, v in self.renderer.counts.items() if k.startswith("fades_")})
        self._win = {"rendered": 0, "models": 0, "t_ns": now, "age_from": self._n_age, "period_max_ns": 0}
        st = DiagnosticStatus()
        st.name = f"{self.get_fully_qualified_name()}: device render"
        st.hardware_id = "skin_sim_bridge"
        st.level, st.message = DiagnosticStatus.OK, f"rendering ({self.renderer.state}, force x{self.p.force_scale:g})"
        st.values = [KeyValue(key=k, value=v) for k, v in values.items()]
        set_stamp(self._diag.header, ros_now_ns(self))
        self._diag.status = [st]
        publish_while_ok(self, self._diag_pub, self._diag)

    def stop(self) -> None:
        """Stop the servo thread, close the server link and log the bridge's counts."""
        self._servo_stop.set()
        try:
            self._servo_wake.trigger()
        except Exception:
            pass
        self._servo.join(timeout=LINK_JOIN_S)
        self.server.close()
        c = self.counts
        self.say(
            f"bridge stopping: {c['poses']} device poses, {c['twists']} twists, {c['models']} contact models "
            f"({c['models_rejected']} dropped), {c['rendered']} device ticks rendered ({c['rendered_fresh']} from a fresh "
            f"model, {c['rendered_no_model']} without one after the first model: {c['rendered_stale_model']} with it older than "
            f"its TTL, {c['rendered_outside_radius']} outside its radius), max model age {self.max_model_age_ms:.2f} ms, "
            f"{c['device_gaps_2ms']} device pose gaps > 2 ms, {c['wrenches']} wrenches ({c['forwarded']} forwarded), "
            f"{c['zeros']} watchdog zero commands, {c['non_finite_pose']} non-finite poses; force scale {self.p.force_scale:g}, "
            f"{self.renderer.counts_clamped} ticks clamped at {self.p.max_force_n:g} N"
        )
        if isinstance(self.server, LocalLink):
            longest = self.server.longest_ms
            self.say(
                f"node link (in this process): {self.server.forwarded} poses handed to the node "
                f"({self.server.served_here} without the link's thread); longest wait for the link's"
                f" thread {longest['pickup']:.1f} ms, for the node's answer {longest['answer']:.1f} ms on it and"
                f" {longest['here']:.1f} ms on the servo thread, for diagnostics {longest['periodic']:.1f} ms"
            )


def _needs_velocity(m: LocalModel) -> bool:
    """Whether rendering ``m`` needs the device's velocity: a ``D`` term, or the velocity friction law (a friction
    coefficient without the presliding stiffness). The default layered model's presliding friction needs none."""
    return bool(m.damping_n_s_per_m.any()) or (m.friction_coefficient > 0.0 and m.tangential_stiffness_n_per_m <= 0.0)


def _remember(memory: dict, stamp_ns: int, value) -> None:
    """Keep ``value`` under its stamp, the newest :data:`STAMP_MEMORY` only (a dict keeps insertion order)."""
    memory[stamp_ns] = value
    if len(memory) > STAMP_MEMORY:
        del memory[next(iter(memory))]


def main(argv=None) -> int:
    """``skin-sim bridge [options] [--ros-args ...]``."""
    return BridgeNode.main(argv)


if __name__ == "__main__":
    raise SystemExit(main())
