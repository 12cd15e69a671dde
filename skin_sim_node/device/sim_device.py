"""``skin-sim device``: a simulated Geomagic Touch published like a device driver, so the loop closes headless.

The stylus (:class:`skin_sim_node.device.stylus.SimulatedDevice`) follows a scripted hand path at the
device rate and applies the force commands it receives (zero-order hold, one tick late, saturated at
the Touch's peak force). It only applies: the bridge renders the force for every device tick from the
node's contact model, and runs the passivity controller, as it would for a real Touch.

``crtk``: publishes ``<device_ns>/measured_cp``, ``measured_cv`` and ``measured_cf`` (the force it applied
over the tick), subscribes ``servo_cf``. ``omni``:
publishes ``<device_ns>/phantom/pose``, subscribes ``phantom/force_feedback``. Device frame: the tissue
axes, origin at tissue ``(0, 0, +0.05)`` m (the bridge's default mapping). Run alone it receives no
force commands; it says so (start ``skin-sim node`` and ``skin-sim bridge`` first, docs/devices.md).
"""

from __future__ import annotations

import math
import os

from geometry_msgs.msg import PoseStamped, TwistStamped, WrenchStamped

from msgs_schema.convert import fill_pose, fill_twist, fill_wrench, read_wrench
from msgs_schema.qos import PROFILES, publisher
from msgs_schema.topics import TOPICS

from ..ros_util import localhost_udp_env, ros_now_ns
from .base import Param, ScriptedNode, publish_while_ok
from .mapping import CONVENTIONS, MEASURED_FORCE, DeviceMapping
from .stylus import DeviceParams, SimulatedDevice
from .trajectories import TRAJECTORIES

MAX_DT_PERIODS = 2
"""A late tick integrates at most this many periods: keeps the integrator inside its stability
bound (see :meth:`DeviceParams.max_stable_dt_s`) after a scheduling hiccup; the hand path then
runs slightly behind wall time rather than the stylus blowing up."""

NO_COMMAND_HINT_S = 3.0
"""Seconds of hand path without a single force command before the device prints how to connect it
(DDS discovery of node and bridge on localhost takes well under 2 s)."""

HINT = (
    "no force commands received: is the bridge running? Start, in separate terminals with the same "
    "ROS_DOMAIN_ID: 1) skin-sim node, 2) skin-sim bridge, 3) skin-sim device (docs/devices.md, 'three terminals')"
)

NONZERO_FORCE_N = 1e-3
"""A force command above 1 mN counts as a force: far below what a hand feels through a Touch, far above the rounding
of a zero command, so any contact the node answered is counted."""
ZERO_FORCES_HINT = (
    "every force command was zero: the bridge runs, but the tool never touched the tissue or no node answered "
    "(is skin-sim node running on this ROS_DOMAIN_ID, with the tissue under the hand path? docs/devices.md)"
)


class SimDeviceNode(ScriptedNode):
    """Publishes the simulated stylus like a device driver and applies the force commands it receives."""

    NODE_NAME = "sim_device"
    PROG = "skin-sim device"
    DESCRIPTION = "Simulated Geomagic Touch following a scripted hand path; applies the bridge's force commands."
    PARAMS = (
        Param("hand_path", "press_hold_release", "scripted hand path", choices=tuple(sorted(TRAJECTORIES))),
        Param("rate_hz", 1000.0, "device servo rate (Hz); a Touch's OpenHaptics servo loop runs at 1 kHz", 10.0, 20000.0),
        Param("convention", "crtk", "driver topic convention", choices=tuple(CONVENTIONS)),
        Param("device_ns", "device", "namespace of the device topics (relative; '' for none)"),
        Param("frame_id", "device_base", "frame_id of the device pose", cli=""),
        Param("offset_m", list(DeviceMapping().offset_m), "tissue position of the device origin (m), as the bridge's", cli=""),
        Param("path_offset_m", [0.0, 0.0, 0.0], "the hand path shifted in the tissue frame (m): a second hand beside the first"),
        Param("start_delay_s", 1.0, "hold the start pose this long first (s), for DDS discovery", 0.0, 600.0),
        Param("repeat", 1, "hand path runs; 0 loops forever", 0, 1_000_000),
        Param("exit_when_done", True, "shut down after the last run and tail_s", cli=""),
        Param("tail_s", 0.2, "lifted-hand time after the last run (s), so the node sees the tool leave", cli=""),
        Param("mass_kg", DeviceParams.mass_kg, "apparent stylus mass (kg), see DeviceParams", cli=""),
        Param("damping_n_s_per_m", DeviceParams.damping_n_s_per_m, "device viscous damping (N*s/m)", cli=""),
        Param("hand_stiffness_n_per_m", DeviceParams.hand_stiffness_n_per_m, "hand spring (N/m)", cli=""),
        Param("hand_damping_n_s_per_m", DeviceParams.hand_damping_n_s_per_m, "hand damper (N*s/m)", cli=""),
        Param("max_force_n", DeviceParams.max_force_n, "force saturation (N): Touch peak 3.3 N", cli=""),
        Param("substep_s", DeviceParams.substep_s, "longest stylus integration substep (s); 0: one per tick"),
        Param(
            "rt_priority",
            90,
            "SCHED_FIFO priority of the simulated Touch's servo loop, 1-99 (0: normal scheduling): a driver's servo "
            "thread runs real-time (OpenHaptics' scheduler, sawSensablePhantom), above the bridge's 80; refused "
            "without root/CAP_SYS_NICE (one warning, then normal priority)",
            0,
            99,
        ),
    )

    TRANSPORT_NOTE = ""

    @classmethod
    def before_start(cls, opts) -> int | None:
        """A driver on the device path: off shared memory under LOCALHOST, as the bridge (docs/devices.md)."""
        updates, cls.TRANSPORT_NOTE = localhost_udp_env(os.environ)
        os.environ.update(updates)
        return None

    def __init__(self, overrides: dict | None = None, **kwargs):
        super().__init__(overrides, **kwargs)
        p = self.p
        params = DeviceParams(
            p.mass_kg,
            p.damping_n_s_per_m,
            p.hand_stiffness_n_per_m,
            p.hand_damping_n_s_per_m,
            p.max_force_n,
            substep_s=p.substep_s,
        )
        self.device = SimulatedDevice(
            p.hand_path,
            params,
            DeviceMapping(offset_m=tuple(p.offset_m)),
            p.start_delay_s,
            p.repeat,
            p.tail_s,
            path_offset_m=tuple(p.path_offset_m),
        )
        ns = p.device_ns.strip("/")

        def dev(key):
            return f"{ns}/{TOPICS[key].name}" if ns else TOPICS[key].name

        pose_key, twist_key, cmd_key = CONVENTIONS[p.convention]
        self._pose_pub = publisher(self, pose_key, name=dev(pose_key))
        self._twist_pub = publisher(self, twist_key, name=dev(twist_key)) if twist_key else None
        cf_key = MEASURED_FORCE[p.convention]
        self._cf_pub = publisher(self, cf_key, name=dev(cf_key)) if cf_key else None
        self._cf = WrenchStamped()
        self.create_subscription(WrenchStamped, dev(cmd_key), self._on_command, PROFILES["driver"])
        self._pose, self._twist = PoseStamped(), TwistStamped()
        self._cmd = (0.0, 0.0, 0.0)
        self.commands = 0
        self.nonzero_commands = 0
        self.peak_command_n = 0.0
        self._hinted = False
        self._period_ns = int(1e9 / p.rate_hz)
        self.get_logger().info(
            f"simulated Touch ({p.convention}) on {dev(pose_key)}, hand path {p.hand_path}, {p.rate_hz} Hz, "
            f"origin at tissue {self.device.mapping.offset_m} m; applies the force commands on {dev(cmd_key)}"
        )
        if self.TRANSPORT_NOTE:
            self.get_logger().info(f"transports: {self.TRANSPORT_NOTE}")
        self.start_loop(self._period_ns, self._tick, name="sim-device", rt_priority=self.p.rt_priority)

    def housekeeping(self) -> None:
        """Timer callback: warn once when no force command has arrived well after the start delay."""
        if not self._hinted and self.commands == 0 and self.device.t_s > self.p.start_delay_s + NO_COMMAND_HINT_S:
            self._hinted = True
            self.get_logger().warning(HINT)

    def _on_command(self, msg) -> None:
        self._cmd = read_wrench(msg)[2]
        self.commands += 1
        f_n = math.sqrt(sum(c * c for c in self._cmd))
        if f_n > NONZERO_FORCE_N:
            self.nonzero_commands += 1
            self.peak_command_n = max(self.peak_command_n, f_n)

    def received(self) -> str:
        """What the force commands were: how many, how many non-zero, the peak; a hint when all were zero."""
        text = (
            f"{self.commands} force commands received, {self.nonzero_commands} of them non-zero "
            f"(> {NONZERO_FORCE_N * 1e3:g} mN), peak {self.peak_command_n:.3f} N"
        )
        if self.commands == 0:
            return f"{text}; {HINT}"
        if self.nonzero_commands == 0:
            return f"{text}; {ZERO_FORCES_HINT}"
        return text

    def _tick(self, now_ns: int, elapsed_ns: int) -> None:
        if self.finished:
            return
        dt = min(max(elapsed_ns, 0), MAX_DT_PERIODS * self._period_ns) * 1e-9
        pos, vel = self.device.step(self._cmd, dt)
        stamp = ros_now_ns(self)
        # twist and applied force first: a receiver that ticks on the pose then finds those of the same stamp
        if self._twist_pub is not None:
            publish_while_ok(self, self._twist_pub, fill_twist(self._twist, stamp, self.p.frame_id, vel))
        if self._cf_pub is not None:
            publish_while_ok(self, self._cf_pub, fill_wrench(self._cf, stamp, self.p.frame_id, self.device.applied_force_n))
        if not publish_while_ok(
            self, self._pose_pub, fill_pose(self._pose, stamp, self.p.frame_id, pos, self.device.orientation)
        ):
            return
        if self.p.exit_when_done and self.device.done:
            self.finish(f"hand path done ({self.received()}): shutting down")

    def stop(self) -> None:
        """Stop the servo loop and log its ticks, overruns and the force commands received."""
        self._loop.stop()
        self.say(f"sim device stopping: {self._loop.ticks} ticks, {self._loop.overruns} overruns, {self.received()}")


def main(argv=None) -> int:
    """``skin-sim device [options] [--ros-args ...]``."""
    return SimDeviceNode.main(argv)


if __name__ == "__main__":
    raise SystemExit(main())
