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
"""

from __future__ import annotations

import math
import os
import sys
import threading
import time
from collections.abc import Callable

import numpy as np
import rclpy
from diagnostic_msgs.msg import DiagnosticArray, DiagnosticStatus, KeyValue
from geometry_msgs.msg import PoseStamped, TwistStamped, WrenchStamped

from msgs_schema.contact_model import LocalModel, read_contact_model
from msgs_schema.convert import fill_pose, fill_twist, fill_wrench, read_pose, read_twist, read_wrench, set_stamp, stamp_ns
from msgs_schema.qos import PROFILES, publisher, subscription
from msgs_schema.topics import FRAMES, TOPICS

from ..ros_util import localhost_udp_env, make_executor, ros_now_ns, set_pid_realtime, set_realtime, spin_context
from .base import DeviceNode, Param, publish_while_ok
from .mapping import (
    CONVENTIONS,
    DEFAULTS,
    DEVICE_PRESETS,
    MEASURED_FORCE,
    TOUCH_MAX_DAMPING_N_S_PER_M,
    TOUCH_MAX_STIFFNESS_N_PER_M,
    DeviceMapping,
    axes_matrix,
    force_to_tissue,
    normalize_namespace,
    without_namespace_remap,
)
from .render import FADE_S, SERVO_PERIOD_S, ContactRenderer, stable_damping_n_s_per_m
from .stylus import DeviceParams

SOURCES = ("model", "wrench")
STABILISERS = ("none", "passivity")
FRICTION_RENDERS = ("law", "linear")
TWIST_MAX_SKEW_NS = 5_000_000  # a device twist this close to the pose's stamp is the pose's velocity (as the node's 5 ms)
HOLD_RADIUS_M = 1.0  # wrench source: a held force does not depend on the pose (any pose on a Touch's workspace)
AGE_RING = 4096  # model ages kept for the diagnostics window (4 s at 1 kHz)
DEVICE_QUEUE_DEPTH = 10
"""History depth of the device pose, twist and measured-force subscriptions: device poses that arrive while the
servo thread is busy (a burst after a scheduling hiccup) are each answered, in order, with their own stamp, instead
of all but the newest being overwritten (issue 19: depth 1 answered 85 % of the poses). 10 ms at 1 kHz."""
RT_PRIORITY = 80
"""SCHED_FIFO priority of the device path (the executor thread that renders each device pose and the device-side
DDS threads); the node link's threads run one below. 80 sits above the kernel's threaded IRQs (50 on PREEMPT_RT),
as the node's ``rt_priority`` documents for servo loops."""
SWITCH_INTERVAL_S = 2e-4
"""``sys.setswitchinterval`` of the bridge (Python's default 5 ms): a servo thread waiting for the GIL gets it
within 0.2 ms of the link thread holding it (the node uses the same)."""


NO_NODE_HINT_NS = 3_000_000_000
"""Device poses without a contact model (or wrench) from the node for this long (3 s; DDS discovery on localhost
takes well under 2 s): the bridge says once that the node seems missing."""

LINK_JOIN_S = 2.0
"""How long the bridge waits at shutdown for each of its node-link threads (they poll every 50 ms)."""


class ServerLink:
    """The bridge's side towards the node, on its own DDS participant (an rclpy context) and threads.

    Measured (tests/test_force_path_ros.py): a node killed with SIGKILL while writing into a participant's
    shared-memory port stalls that port for 1000 ms (Fast DDS's health-check timeout). With one participant the
    device's poses then stopped reaching the bridge: no tick to render on, the force held, then a watchdog step.
    Here the node writes only into this participant's port, the device only into the bridge's own, and the tool
    pose goes out from this link's thread (a latest-value hand-off), so a dead node cannot stall the servo path.
    """

    def __init__(
        self,
        bridge: BridgeNode,
        ros_args: list[str],
        on_model,
        twist: bool,
        node_ns: str = "",
        rt_priority: int = 0,
        periodic: tuple[float, Callable[[], None]] | None = None,
    ):
        self._periodic = periodic
        self._periodic_failed = False
        self.ctx = rclpy.Context()
        rclpy.init(args=without_namespace_remap(ros_args) if node_ns else ros_args, context=self.ctx)
        self.node = rclpy.create_node(f"{bridge.get_name()}_server", context=self.ctx, namespace=node_ns or None)
        self.rt_priority = rt_priority
        self.frame = bridge.tissue_frame
        self._pose_pub = publisher(self.node, "tool_pose")
        self._twist_pub = publisher(self.node, "tool_twist") if twist else None
        self._pose, self._twist = PoseStamped(), TwistStamped()
        key = "contact_model" if bridge.model_source else "tool_wrench"
        subscription(self.node, key, on_model)
        self._latest: dict[str, tuple] = {}
        self._lock = threading.Lock()
        self._wake = threading.Event()
        self._stop = threading.Event()
        self._executor = make_executor("events", self.ctx)
        self._executor.add_node(self.node)
        self._threads = [
            threading.Thread(target=self._spin, name="server-spin", daemon=True),
            threading.Thread(target=self._publish_loop, name="server-publish", daemon=True),
        ]
        for t in self._threads:
            t.start()

    def send(self, kind: str, values: tuple) -> None:
        """Hand the newest ``pose`` (stamp, xyz, quat) or ``twist`` (stamp, linear) to the publishing thread."""
        with self._lock:
            self._latest[kind] = values
        self._wake.set()

    def _realtime(self) -> None:
        """This link thread one priority below the device path: a link thread holding the GIL is not preempted by
        the node or other processes while the servo thread waits for it (no priority inversion through the GIL)."""
        if self.rt_priority > 1:
            set_realtime(self.rt_priority - 1)

    def _spin(self) -> None:
        self._realtime()
        spin_context(self._executor, self.ctx, self._stop)

    def _publish_loop(self) -> None:
        """Publish the newest pose and twist; between them, the ``periodic`` call (the bridge's diagnostics) when due."""
        self._realtime()
        period_ns = int(self._periodic[0] * 1e9) if self._periodic is not None else 0
        next_ns = time.monotonic_ns() + period_ns  # the first after one period: the bridge finishes its start first
        while not self._stop.is_set():
            if self._periodic is not None and time.monotonic_ns() >= next_ns:
                next_ns = time.monotonic_ns() + period_ns
                try:
                    self._periodic[1]()
                except Exception as exc:  # never let it stop the tool pose going to the node
                    if not self._periodic_failed:
                        self._periodic_failed = True
                        print(f"skin-sim bridge: diagnostics failed: {exc!r} (reported once)", flush=True)
            if not self._wake.wait(0.05):
                continue
            self._wake.clear()
            with self._lock:
                latest, self._latest = self._latest, {}
            tw = latest.get("twist")
            if tw is not None and self._twist_pub is not None:  # twist first, as the device publishes them
                publish_while_ok(self.node, self._twist_pub, fill_twist(self._twist, tw[0], self.frame, tw[1]))
            ps = latest.get("pose")
            if ps is not None:
                publish_while_ok(self.node, self._pose_pub, fill_pose(self._pose, ps[0], self.frame, ps[1], ps[2]))

    def close(self) -> None:
        """Stop the link's threads, then destroy its node and context, never under a thread still inside them.

        A thread still running after :data:`LINK_JOIN_S` (starved on a loaded machine) keeps the node and the
        context alive until the process exits: destroying them under its ``spin_once`` corrupted the heap at exit
        (``malloc_consolidate(): unaligned fastbin chunk``, exit -6, once in 15 shutdowns beside four busy processes).
        """
        self._stop.set()
        self._wake.set()
        for t in self._threads:
            t.join(timeout=LINK_JOIN_S)
        if any(t.is_alive() for t in self._threads):
            return
        try:
            self._executor.shutdown(timeout_sec=LINK_JOIN_S)
            self.node.destroy_node()
        except Exception:
            pass
        rclpy.try_shutdown(context=self.ctx)


class BridgeNode(DeviceNode):
    """Device driver topics <-> node topics; renders the local contact model every device tick."""

    NODE_NAME = "skin_sim_bridge"
    PROG = "skin-sim bridge"
    DESCRIPTION = (
        "Device bridge: device pose -> tool/pose; tool/contact_model rendered at the device's rate -> force "
        "command (CRTK servo_cf or omni force_feedback). Start it after skin-sim node, before the device."
    )
    PARAMS = (
        Param(
            "device",
            "sim",
            "device preset: sim (skin-sim device, axes xyz) or touch (a Touch under sawSensablePhantom: "
            "convention crtk, axes x-zy); options given explicitly win",
            choices=tuple(DEVICE_PRESETS),
            presets=DEVICE_PRESETS,
        ),
        Param("convention", DEFAULTS["convention"], "device driver topic convention", choices=tuple(CONVENTIONS)),
        Param("device_ns", DEFAULTS["device_ns"], "namespace of the device topics (relative; '' for none)"),
        Param("offset_m", DEFAULTS["offset_m"], "tissue-frame position of the device origin (m)"),
        Param("scale", DEFAULTS["scale"], "motion scale: tissue m per device m", 1e-3, 1e3),
        Param("axes", DEFAULTS["axes"], "tissue x, y, z as signed device axes, e.g. xyz, or x-zy for a Touch base frame"),
        Param(
            "force_scale",
            DEFAULTS["force_scale"],
            "force scale: F_device = force_scale * R^T F_tissue, before the clamp (a needle's puncture peak above the "
            "clamp is flattened at scale 1; e.g. 0.6 keeps an 18 G peak, 2.7 N, under sawSensablePhantom's 2 N)",
            0.0,
            100.0,
        ),
        Param("max_force_n", DEFAULTS["max_force_n"], "device force clamp (N); Touch peak 3.3 N", 0.0, 100.0),
        Param(
            "max_stiffness_n_per_m",
            TOUCH_MAX_STIFFNESS_N_PER_M,
            "cap of the rendered stiffness at the device (N/m); Touch spec >= 1.02 N/mm on its weakest axis",
            0.0,
            1e6,
        ),
        Param(
            "max_damping_n_s_per_m",
            TOUCH_MAX_DAMPING_N_S_PER_M,
            "cap of the rendered damping at the device (N*s/m); sawSensablePhantom's largest servo damping on a Touch",
            0.0,
            1e4,
        ),
        Param(
            "friction_render",
            "law",
            "law: evaluate the contact model's friction law at the device's velocity (CRTK measured_cv) every tick; "
            "linear: f0 + K dx + D dv (D capped), as a consumer without the law",
            choices=FRICTION_RENDERS,
        ),
        Param(
            "max_friction_slope_n_s_per_m",
            0.0,
            "cap of the rendered friction law's slope at zero slip, mu F_n / v_r (N*s/m); 0: the model's own law. "
            "0.6 m / T (27 N*s/m for a 45 g stylus at 1 kHz) ends the stick chatter of a light stylus, at a render error",
            0.0,
            1e6,
        ),
        Param(
            "chatter_guard",
            "on",
            "on: while the device's tangential velocity reverses twice within 10 ms (stick on a light stylus, or "
            "velocity noise), cap the friction law's slope at the device's stable damping, 2 sin(pi/10) device_mass_kg / 1 ms",
            choices=("on", "off"),
        ),
        Param(
            "slip_speed_floor_m_s",
            0.0,
            "least regularisation speed of the rendered friction law, in the device's velocity (m/s): raise it to the "
            "noise of the driver's measured_cv near rest; 0: the model's own v_s",
            0.0,
            1.0,
        ),
        Param(
            "node_ns",
            DEFAULTS["node_ns"],
            "namespace of the node's topics (tool/pose, tool/twist, tool/contact_model, tool/wrench), e.g. /skin1; "
            "'' : the process's. Unlike -r __ns:=, it leaves the device topics where they are",
        ),
        Param(
            "rt_priority",
            RT_PRIORITY,
            "SCHED_FIFO priority of the device path, 1-99 (0: normal scheduling); refused without root/CAP_SYS_NICE",
            0,
            99,
        ),
        Param(
            "force_source",
            "model",
            "model: render tool/contact_model per device tick; wrench: forward tool/wrench",
            choices=SOURCES,
        ),
        Param("fade_s", FADE_S, "fade to zero when the model goes stale or the tool leaves it (s)", 1e-3, 1.0),
        Param(
            "stabiliser",
            "passivity",
            "passivity: time-domain passivity controller on the rendered force; none",
            choices=STABILISERS,
        ),
        Param("device_mass_kg", DeviceParams.mass_kg, "apparent stylus mass for the passivity controller (kg)", 1e-3, 10.0),
        Param(
            "watchdog_s",
            DEFAULTS["watchdog_s"],
            "device pose age (s) after which one zero force is sent (wrench source: also the node's wrench age)",
            1e-3,
            10.0,
        ),
        Param("watchdog_rate_hz", DEFAULTS["watchdog_rate_hz"], "watchdog check rate (Hz)", 1.0, 1e4),
        Param("device_frame", DEFAULTS["device_frame"], "frame_id of force commands; empty: the device pose's frame_id"),
        Param("restamp", DEFAULTS["restamp"], "stamp tool poses with the bridge clock instead of the driver's", cli=""),
        Param("diagnostics_period_s", 1.0, "period of the bridge's diagnostics (s)", 0.05, 60.0),
    )

    TRANSPORT_NOTE = ""  # what localhost_udp_env decided before rclpy started (logged at start)

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
        updates, cls.TRANSPORT_NOTE = localhost_udp_env(os.environ, keep_shm=opts.localhost_shm)
        os.environ.update(updates)  # before rclpy creates a participant: both of the bridge's participants
        return None

    def __init__(self, overrides: dict | None = None, **kwargs):
        super().__init__(overrides, **kwargs)
        p = self.p
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

        self._force_out = WrenchStamped()
        self._render_lock = threading.Lock()  # the renderer: models from the server link's thread, ticks from this one
        self._force_pub = self.create_publisher(WrenchStamped, dev(force_key), PROFILES["driver"])
        self._diag_pub = publisher(self, "diagnostics")
        self._diag = DiagnosticArray()
        depth = DEVICE_QUEUE_DEPTH
        subscription(self, pose_key, self._on_device_pose, name=dev(pose_key), depth=depth)
        if twist_key:
            subscription(self, twist_key, self._on_device_twist, name=dev(twist_key), depth=depth)
        cf_key = MEASURED_FORCE[p.convention]
        if cf_key:
            subscription(self, cf_key, self._on_device_force, name=dev(cf_key), depth=depth)
        self.rt_message = self._device_path_realtime(p.rt_priority)
        self._cf_tissue: np.ndarray | None = None
        self._cf_stamp_ns = -1
        self.node_ns = normalize_namespace(p.node_ns)
        self._ages_ms = np.zeros(AGE_RING)
        self._n_age = 0
        self._win = {"rendered": 0, "models": 0, "t_ns": time.monotonic_ns(), "age_from": 0, "period_max_ns": 0}
        # the diagnostics (percentiles, ~20 key-values, a publish: about a millisecond once a second) run on the node
        # link's publishing thread, not on the servo executor: no device pose waits for them (issue 19, gaps)
        self.server = ServerLink(
            self,
            self.ROS_ARGS,
            self._on_model if self.model_source else self._on_wrench,
            bool(twist_key),
            self.node_ns,
            p.rt_priority if not self.rt_message.startswith("SCHED_FIFO refused") else 0,
            periodic=(p.diagnostics_period_s, self._publish_diagnostics),
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
        self.max_model_age_ms = 0.0
        self._rejected_logged: set[str] = set()
        self.create_timer(1.0 / p.watchdog_rate_hz, self._watchdog)
        src = self.server.node.resolve_topic_name(TOPICS["contact_model" if self.model_source else "tool_wrench"].name)
        src = f"{src} rendered per device tick" if self.model_source else src
        tool_pose = self.server.node.resolve_topic_name(TOPICS["tool_pose"].name)
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

    def _device_path_realtime(self, priority: int) -> str:
        """SCHED_FIFO for every thread that exists now: the executor thread (it renders each device pose) and the
        device-side participant's DDS threads. With SCHED_RESET_ON_FORK, the node link's threads, started after this,
        do not inherit it (they set one priority less themselves). Returns the message to log."""
        if priority <= 0:
            return "device path at normal priority (rt_priority 0)"
        sys.setswitchinterval(SWITCH_INTERVAL_S)
        why = set_pid_realtime(os.getpid(), priority)
        if why is None:
            return f"device path at SCHED_FIFO {priority} (servo executor, device-side DDS threads; node link {priority - 1})"
        return (
            f"SCHED_FIFO refused for the device path ({why}): it shares the CPU with the node, the display and joining "
            "readers at normal priority; run as root, or grant CAP_SYS_NICE or an rtprio limit, or pass --rt-priority 0"
        )

    # --- device side --------------------------------------------------------------------
    def _stamp(self, msg) -> int:
        s = stamp_ns(msg.header)
        return ros_now_ns(self) if self.p.restamp or s == 0 else s

    def _on_device_twist(self, msg) -> None:
        t_ns, _, v = read_twist(msg)
        if not all(math.isfinite(c) for c in v):
            return
        vt = self.mapping.velocity_to_tissue(v)
        self._v_tissue, self._v_stamp_ns = np.array(vt), t_ns
        self.server.send("twist", (self._stamp(msg), vt))
        self.counts["twists"] += 1

    def _on_device_force(self, msg) -> None:
        t_ns, _, f = read_wrench(msg)
        self._cf_tissue, self._cf_stamp_ns = np.array(force_to_tissue(self.mapping, f)), t_ns

    def _on_device_pose(self, msg) -> None:
        t_ns, frame, pos = read_pose(msg)
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
        o = msg.pose.orientation
        q = self.mapping.orientation_to_tissue((o.x, o.y, o.z, o.w))
        x = self.mapping.to_tissue(pos)
        stamp = self._stamp(msg)
        self.counts["poses"] += 1
        # the servo tick: render at this pose and command at once (wrench source: the last force, held)
        v = self._v_tissue if self._v_tissue is not None and abs(self._v_stamp_ns - t_ns) <= TWIST_MAX_SKEW_NS else None
        cf = self._cf_tissue if self._cf_stamp_ns == t_ns else None  # applied over the tick that ended here
        n_radius = self.renderer.counts["fades_radius"]
        with self._render_lock:  # on the device's clock: the pose's stamp
            f = self.renderer.render(stamp * 1e-9, x, v, cf)
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
        self.server.send("pose", (stamp, x, q))

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
    def _on_model(self, msg) -> None:
        m = read_contact_model(msg)
        why: str | None
        if m.frame_id != self.tissue_frame:
            why = f"frame '{m.frame_id}', expected '{self.tissue_frame}'"
        else:
            with self._render_lock:
                why = self.renderer.set_model(m)  # at the latest device tick: the renderer's clock is the device's
        if why is None:
            self._check_needle_peak(m)
            self.counts["models"] += 1
            self._win["models"] += 1
            self._first_model = True
            return
        self.counts["models_rejected"] += 1
        kind = why.split(" ")[0]
        if kind not in self._rejected_logged:
            self._rejected_logged.add(kind)
            self.get_logger().warning(f"contact model dropped: {why} (logged once per kind)")

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

    def _on_wrench(self, msg) -> None:
        """Wrench source: the node's force as a model with no stiffness (held until the next, faded after watchdog_s)."""
        self.counts["wrenches"] += 1
        t_ns, _, f = read_wrench(msg)
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
        publish_while_ok(self, self._force_pub, fill_wrench(self._force_out, t_ns, self.device_frame or "device_base", f))

    def _watchdog(self) -> None:
        now = time.monotonic_ns()
        # a stale node is the renderer's business (it fades); a silent device has no tick to render on
        stale = self.last_pose_rx_ns is None or now - self.last_pose_rx_ns > self.watchdog_ns
        if stale and not self.stale:
            f = self._force_out.wrench.force
            held = math.sqrt(f.x * f.x + f.y * f.y + f.z * f.z)
            self._publish_force(ros_now_ns(self), (0.0, 0.0, 0.0))
            self.counts["zeros"] += 1
            if self.counts["poses"]:  # a device that stopped while pushing is a warning; one that ended lifted is not
                text = f"no device pose for {self.watchdog_ns * 1e-6:.0f} ms: device force set to zero (was {held:.3f} N)"
                if held > 0.0:  # rclpy: one severity per call site
                    self.get_logger().warning(text)
                else:
                    self.get_logger().info(text)
        self.stale = stale
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
        """Close the server link and log the bridge's counts."""
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


def main(argv=None) -> int:
    """``skin-sim bridge [options] [--ros-args ...]``."""
    return BridgeNode.main(argv)


if __name__ == "__main__":
    raise SystemExit(main())
