"""A simulated Phantom / Geomagic Touch, so the haptic loop closes headless.

The stylus is a point mass pulled by a hand impedance (spring + damper) towards a
scripted hand path (a :data:`skin_sim_node.device.mock_tool.TRAJECTORIES` entry), pushed by the
commanded device force (zero-order hold, applied one tick late, saturated at the
Touch's peak force) and slowed by a small device damping.

Device frame: the same axes as the tissue frame, origin at tissue ``(0, 0, +0.05)`` m,
i.e. ``p_tissue = p_device + (0, 0, 0.05)``; this is the default
:class:`skin_sim_node.device.bridge.DeviceMapping`, so the default bridge needs no options.
Positions are reported in the device frame (frame_id ``device_base``).

The pure part (:class:`SimulatedDevice`, :class:`DeviceParams`) imports no ROS code;
:class:`SimDeviceNode` is built on first access.
"""

from __future__ import annotations

import argparse
import math
from dataclasses import dataclass

from .bridge import TOUCH_PEAK_FORCE_N, DeviceMapping, clamp_magnitude
from .mock_tool import TRAJECTORIES, ScriptClock, Trajectory
from .passivity import PassivityController

Vec3 = tuple[float, float, float]
STABILISERS = ("none", "passivity")


@dataclass(frozen=True)
class DeviceParams:
    """Stylus and hand parameters (SI units).

    Attributes
    ----------
    mass_kg : float
        Apparent stylus mass at the tip: ~45 g on the Touch / Phantom Omni spec sheet
        ("inertia (apparent mass at tip) ~45 g").
    damping_n_s_per_m : float
        Device viscous damping. Small: 0.05 N*s/m resists a brisk 0.1 m/s hand with 5 mN,
        well under the Touch's specified backdrive friction (< 0.26 N), so it models only
        the viscous part of the gimbal and cable losses.
    hand_stiffness_n_per_m : float
        Hand impedance spring K_h. A pen grip is a few hundred N/m (fingertip impedance
        measurements, e.g. Hajian & Howe 1997, J Biomech Eng 119:109, report hundreds of N/m
        and a few N*s/m); 300 N/m stays below the Touch's own ~1 N/mm rendering stiffness.
    hand_damping_n_s_per_m : float
        Hand damper B_h. 3 N*s/m gives the stylus on the hand spring a damping ratio
        ``B_h / (2 sqrt(K_h m)) = 0.41`` at the defaults: a settled but not sluggish grip.
    max_force_n : float
        Saturation of the commanded force magnitude: the Touch's 3.3 N peak force.
    delay_ticks : int
        Ticks between a force command handed to :meth:`SimulatedDevice.step` and its first
        application (0 or 1; a real servo loop applies a command from its next tick).
    substep_s : float
        Longest integration step inside one tick (s); 0 integrates each tick in one step. The
        stability sweep (:mod:`skin_sim_node.stability.haptic_loop`) sets 50 us so that the stylus
        and hand behave as continuous-time physics and only the loop is sampled.
    stabiliser : str
        ``"none"`` or ``"passivity"``: the device-side passivity observer and controller of
        :class:`skin_sim_node.device.passivity.PassivityController`, run in the device tick.
    """

    mass_kg: float = 0.045
    damping_n_s_per_m: float = 0.05
    hand_stiffness_n_per_m: float = 300.0
    hand_damping_n_s_per_m: float = 3.0
    max_force_n: float = TOUCH_PEAK_FORCE_N
    delay_ticks: int = 1
    substep_s: float = 0.0
    stabiliser: str = "none"

    def __post_init__(self):
        if not self.mass_kg > 0:
            raise ValueError(f"mass_kg must be > 0, got {self.mass_kg}")
        for name in ("damping_n_s_per_m", "hand_stiffness_n_per_m", "hand_damping_n_s_per_m", "max_force_n"):
            v = getattr(self, name)
            if not (math.isfinite(v) and v >= 0):
                raise ValueError(f"{name} must be finite and >= 0, got {v}")
        if self.delay_ticks not in (0, 1):
            raise ValueError(f"delay_ticks must be 0 or 1, got {self.delay_ticks}")
        if not (math.isfinite(self.substep_s) and self.substep_s >= 0):
            raise ValueError(f"substep_s must be finite and >= 0, got {self.substep_s}")
        if self.stabiliser not in STABILISERS:
            raise ValueError(f"stabiliser must be one of {', '.join(STABILISERS)}, got {self.stabiliser!r}")

    def max_stable_dt_s(self, contact_stiffness_n_per_m: float = 0.0) -> float:
        """Largest step for which semi-implicit Euler stays stable on the linearised stylus.

        Semi-implicit (symplectic) Euler on ``m x'' = -K x - B x'`` is stable for
        ``dt < 2 / omega`` (``omega = sqrt(K / m)``) and ``dt < 2 m / B``; a one-tick force
        delay roughly halves the first bound, so ``dt < 1 / omega`` is required with
        ``K = K_h + contact stiffness``. At the defaults and 1 kHz, ``omega dt = 0.08`` on the
        hand spring and 0.47 against the stiffest default layer (epidermis, ~9.7 kN/m).
        """
        k = self.hand_stiffness_n_per_m + contact_stiffness_n_per_m
        b = self.hand_damping_n_s_per_m + self.damping_n_s_per_m
        limits = [1.0 / math.sqrt(k / self.mass_kg) if k > 0 else math.inf, 2.0 * self.mass_kg / b if b > 0 else math.inf]
        return min(limits)


class SimulatedDevice:
    """A Touch stylus held by a scripted hand, in the device frame.

    Parameters
    ----------
    hand_path : Trajectory or str
        The hand's path in the tissue frame (a trajectory or its name).
    params : DeviceParams
    mapping : DeviceMapping
        Device <-> tissue frame; the hand path is mapped into the device frame with it.
    start_delay_s, repeat, tail_s : float, int, float
        As :class:`skin_sim_node.device.mock_tool.ScriptClock`: hold the start pose first, run
        ``repeat`` times (``<= 0``: forever), hold the end pose ``tail_s`` before :attr:`done`.

    Notes
    -----
    Per :meth:`step`: ``F = K_h (x_h - x) + B_h (v_h - v) - b v + F_ext``, ``v += F dt / m``,
    ``x += v dt`` (semi-implicit Euler; see :meth:`DeviceParams.max_stable_dt_s`), in substeps of
    at most ``substep_s``. ``F_ext`` is the last force command, held, saturated to ``max_force_n``
    (direction kept; a non-finite command counts as zero), and applied ``delay_ticks`` late; with
    ``stabiliser="passivity"`` the device-side passivity controller adds its damping to it.
    """

    def __init__(
        self,
        hand_path: Trajectory | str = "press_hold_release",
        params: DeviceParams | None = None,
        mapping: DeviceMapping | None = None,
        start_delay_s: float = 0.0,
        repeat: int = 1,
        tail_s: float = 0.0,
    ):
        self.hand_path = TRAJECTORIES[hand_path] if isinstance(hand_path, str) else hand_path
        self.params = params or DeviceParams()
        self.mapping = mapping or DeviceMapping()
        self.script = ScriptClock(self.hand_path, start_delay_s, repeat, tail_s)
        self.reset()

    def reset(self) -> None:
        """Stylus at rest in the hand at the path's start; no force held; time 0."""
        self.t_s = 0.0
        self.pos, _ = self.hand()
        self.vel = (0.0, 0.0, 0.0)
        self._held = (0.0, 0.0, 0.0)
        self.applied_force_n = (0.0, 0.0, 0.0)
        self.passivity = PassivityController(self.params.mass_kg) if self.params.stabiliser == "passivity" else None

    def hand(self, t_s: float | None = None) -> tuple[Vec3, Vec3]:
        """Hand position (m) and velocity (m/s) in the device frame at ``t_s`` (default: now)."""
        p, v = self.hand_path.sample(self.script.trajectory_time(self.t_s if t_s is None else t_s))
        return self.mapping.to_device(p), self.mapping.velocity_to_device(v)

    @property
    def done(self) -> bool:
        return self.script.done(self.t_s)

    def step(self, force_xyz_n, dt: float) -> tuple[Vec3, Vec3]:
        """Advance by ``dt`` (s) with the force command ``force_xyz_n`` (N, device frame).

        Returns the new stylus position (m) and velocity (m/s) in the device frame.
        """
        p = self.params
        cmd = clamp_magnitude(tuple(float(c) for c in force_xyz_n), p.max_force_n)
        if p.delay_ticks == 0:
            self._held = cmd
        f_env = f_ext = self._held
        if self.passivity is not None:
            f_ext = clamp_magnitude(self.passivity.force(f_env, self.vel, dt), p.max_force_n)
        self.applied_force_n = f_ext
        x0 = x = self.pos
        v = self.vel
        k, b, bd, m = p.hand_stiffness_n_per_m, p.hand_damping_n_s_per_m, p.damping_n_s_per_m, p.mass_kg
        n_sub = max(1, math.ceil(dt / p.substep_s - 1e-9)) if p.substep_s > 0 else 1
        h = dt / n_sub
        for j in range(n_sub):
            xh, vh = self.hand(self.t_s + j * h)
            v = tuple(v[i] + h / m * (k * (xh[i] - x[i]) + b * (vh[i] - v[i]) - bd * v[i] + f_ext[i]) for i in range(3))
            x = tuple(x[i] + h * v[i] for i in range(3))
        if self.passivity is not None:
            self.passivity.observe(f_ext, f_env, tuple(x[i] - x0[i] for i in range(3)))
        self.pos, self.vel = x, v
        self.t_s += dt
        self._held = cmd
        return x, v

    @property
    def pos_tissue(self) -> Vec3:
        return self.mapping.to_tissue(self.pos)

    @property
    def vel_tissue(self) -> Vec3:
        return self.mapping.velocity_to_tissue(self.vel)


# --- ROS node ---------------------------------------------------------------------------
EXECUTOR = "events"  # run_nodes drives it with spin_once(timeout): far less CPU per callback
"""rclpy executor for :func:`run_nodes`. Not ``events``: with the rclpy 7.1.6 wheels its ``spin()``
ignores context shutdown (SIGINT, SIGTERM, exit-when-done never return) and, in a local test,
starved Python threads such as the device loop."""

DEFAULTS = {
    "hand_path": "press_hold_release",
    "rate_hz": 1000.0,  # a Touch's servo loop runs at 1 kHz (OpenHaptics scheduler)
    "convention": "crtk",
    "device_ns": "device",
    "frame_id": "device_base",
    "offset_m": list(DeviceMapping().offset_m),
    "start_delay_s": 1.0,  # DDS discovery on localhost typically completes well within 1 s
    "repeat": 1,
    "exit_when_done": True,
    "tail_s": 0.2,  # hand lifted after the last run, so the node sees the tool leave
    "mass_kg": DeviceParams.mass_kg,
    "damping_n_s_per_m": DeviceParams.damping_n_s_per_m,
    "hand_stiffness_n_per_m": DeviceParams.hand_stiffness_n_per_m,
    "hand_damping_n_s_per_m": DeviceParams.hand_damping_n_s_per_m,
    "max_force_n": DeviceParams.max_force_n,
    "substep_s": DeviceParams.substep_s,
    "stabiliser": DeviceParams.stabiliser,
}
MAX_DT_PERIODS = 2
"""A late tick integrates at most this many periods: keeps the integrator inside its stability
bound (see :meth:`DeviceParams.max_stable_dt_s`) after a scheduling hiccup; the hand path then
runs slightly behind wall time rather than the stylus blowing up."""


def _build_node_class():
    import rclpy
    from geometry_msgs.msg import PoseStamped, TwistStamped, WrenchStamped
    from rcl_interfaces.msg import FloatingPointRange, IntegerRange, ParameterDescriptor
    from rclpy.node import Node

    from msgs_schema.convert import fill_pose, fill_twist, read_wrench
    from msgs_schema.qos import PROFILES, publisher
    from msgs_schema.topics import TOPICS

    from ..ros_util import PeriodicLoop, ros_now_ns
    from .bridge import HOUSEKEEPING_PERIOD_S, publish_while_ok

    def frange(lo, hi):
        return [FloatingPointRange(from_value=float(lo), to_value=float(hi))]

    class SimDeviceNode(Node):
        """Publishes the simulated stylus like a device driver and takes force commands.

        ``crtk``: publishes ``<device_ns>/measured_cp`` and ``measured_cv``, subscribes
        ``servo_cf``. ``omni``: publishes ``<device_ns>/phantom/pose``, subscribes
        ``phantom/force_feedback``. The command subscription uses the reliable ``driver``
        QoS, like a real driver.

        Parameters
        ----------
        overrides : dict, optional
            Parameter defaults (e.g. from argparse); ``--ros-args -p`` still wins.
        """

        def __init__(self, overrides: dict | None = None, **kwargs):
            super().__init__("sim_device", **kwargs)
            d = {**DEFAULTS, **(overrides or {})}
            P = ParameterDescriptor
            ro = {"read_only": True}
            self.declare_parameter("hand_path", d["hand_path"], P(description=f"hand path: {', '.join(TRAJECTORIES)}", **ro))
            self.declare_parameter(
                "rate_hz", float(d["rate_hz"]), P(description="device rate (Hz)", floating_point_range=frange(10, 20000), **ro)
            )
            self.declare_parameter("convention", d["convention"], P(description="crtk | omni", **ro))
            self.declare_parameter("device_ns", d["device_ns"], P(description="namespace of the device topics (relative)", **ro))
            self.declare_parameter("frame_id", d["frame_id"], P(description="frame_id of the device pose", **ro))
            self.declare_parameter(
                "offset_m", [float(c) for c in d["offset_m"]], P(description="tissue position of the device origin (m)", **ro)
            )
            self.declare_parameter(
                "start_delay_s",
                float(d["start_delay_s"]),
                P(description="hold the start pose first (s), for DDS discovery", **ro),
            )
            self.declare_parameter(
                "repeat",
                int(d["repeat"]),
                P(
                    description="hand path runs; 0 loops forever",
                    integer_range=[IntegerRange(from_value=0, to_value=1_000_000)],
                    **ro,
                ),
            )
            self.declare_parameter(
                "exit_when_done", bool(d["exit_when_done"]), P(description="shut down after the last run and tail_s", **ro)
            )
            self.declare_parameter("tail_s", float(d["tail_s"]), P(description="lifted hand time after the last run (s)", **ro))
            for name, unit in (
                ("mass_kg", "kg"),
                ("damping_n_s_per_m", "N*s/m"),
                ("hand_stiffness_n_per_m", "N/m"),
                ("hand_damping_n_s_per_m", "N*s/m"),
                ("max_force_n", "N"),
            ):
                self.declare_parameter(name, float(d[name]), P(description=f"{name} ({unit}), see DeviceParams", **ro))
            self.declare_parameter(
                "substep_s", float(d["substep_s"]), P(description="longest integration substep (s); 0: one per tick", **ro)
            )
            self.declare_parameter("stabiliser", d["stabiliser"], P(description=f"{' | '.join(STABILISERS)}", **ro))
            gp = self.get_parameter
            conv = gp("convention").value
            if conv not in ("crtk", "omni"):
                raise ValueError(f"convention {conv!r}: choose crtk or omni")
            path = gp("hand_path").value
            if path not in TRAJECTORIES:
                raise ValueError(f"unknown hand path {path!r}; choose one of {', '.join(TRAJECTORIES)}")
            params = DeviceParams(
                gp("mass_kg").value, gp("damping_n_s_per_m").value, gp("hand_stiffness_n_per_m").value,
                gp("hand_damping_n_s_per_m").value, gp("max_force_n").value,
                substep_s=gp("substep_s").value, stabiliser=gp("stabiliser").value,
            )  # fmt: skip
            self.device = SimulatedDevice(
                path, params, DeviceMapping(offset_m=tuple(gp("offset_m").value)),
                gp("start_delay_s").value, gp("repeat").value, gp("tail_s").value,
            )  # fmt: skip
            self.exit_when_done = gp("exit_when_done").value
            self.frame = gp("frame_id").value
            ns = gp("device_ns").value.strip("/")

            def dev(key):
                return f"{ns}/{TOPICS[key].name}" if ns else TOPICS[key].name

            pose_key, twist_key, cmd_key = (
                ("crtk_measured_cp", "crtk_measured_cv", "crtk_servo_cf") if conv == "crtk" else ("omni_pose", None, "omni_force")
            )
            self._pose_pub = publisher(self, pose_key, name=dev(pose_key))
            self._twist_pub = publisher(self, twist_key, name=dev(twist_key)) if twist_key else None
            self.create_subscription(WrenchStamped, dev(cmd_key), self._on_command, PROFILES["driver"])
            self._pose, self._twist = PoseStamped(), TwistStamped()
            self._cmd = (0.0, 0.0, 0.0)
            self.commands = 0
            self._finished = False
            period_ns = int(1e9 / gp("rate_hz").value)
            self._period_ns = period_ns
            self.get_logger().info(
                f"simulated Touch ({conv}) on {dev(pose_key)}, hand path {path}, {gp('rate_hz').value} Hz, "
                f"origin at tissue {self.device.mapping.offset_m} m, stabiliser {params.stabiliser}"
            )
            self._loop = PeriodicLoop(period_ns, self._tick, name="sim-device")
            self.create_timer(HOUSEKEEPING_PERIOD_S, self._housekeeping)
            self._loop.start()

        def _housekeeping(self) -> None:
            if self._finished:
                rclpy.try_shutdown(context=self.context)

        def _on_command(self, msg) -> None:
            self._cmd = read_wrench(msg)[2]
            self.commands += 1

        def _tick(self, now_ns: int, elapsed_ns: int) -> None:
            if self._finished:
                return
            dt = min(max(elapsed_ns, 0), MAX_DT_PERIODS * self._period_ns) * 1e-9
            pos, vel = self.device.step(self._cmd, dt)
            stamp = ros_now_ns(self)
            # twist first: a receiver that ticks on the pose then finds the twist of the same stamp
            if self._twist_pub is not None:
                publish_while_ok(self, self._twist_pub, fill_twist(self._twist, stamp, self.frame, vel))
            if not publish_while_ok(self, self._pose_pub, fill_pose(self._pose, stamp, self.frame, pos)):
                return
            if self.exit_when_done and self.device.done:
                self._finished = True
                self.get_logger().info(f"hand path done ({self.commands} force commands received): shutting down")
                self._loop.stop()  # from inside the loop thread: sets the flag, no join

        def stop(self) -> None:
            self._loop.stop()
            pc = self.device.passivity
            pc_text = f"; passivity controller active {pc.active_ticks} ticks, dissipated {pc.dissipated_j:.3g} J" if pc else ""
            self.get_logger().info(
                f"sim device stopping: {self._loop.ticks} ticks, {self._loop.overruns} overruns, "
                f"{self.commands} force commands received{pc_text}"
            )

    return SimDeviceNode


def __getattr__(name: str):
    if name == "SimDeviceNode":
        cls = _build_node_class()
        globals()["SimDeviceNode"] = cls
        return cls
    raise AttributeError(f"module {__name__!r} has no attribute {name!r}")


def main(argv=None) -> int:
    """``sim_device [--hand-path NAME] [--rate-hz HZ] [--convention crtk|omni] [--loop] [--ros-args ...]``."""
    ap = argparse.ArgumentParser(prog="sim_device", description=__doc__.splitlines()[0])
    ap.add_argument("--hand-path", choices=sorted(TRAJECTORIES))
    ap.add_argument("--rate-hz", type=float)
    ap.add_argument("--convention", choices=("crtk", "omni"))
    ap.add_argument("--device-ns", help="namespace of the device topics (default 'device'; '' for none)")
    g = ap.add_mutually_exclusive_group()
    g.add_argument("--repeat", type=int, help="number of hand path runs")
    g.add_argument("--loop", action="store_true", help="loop the hand path forever")
    ap.add_argument("--start-delay-s", type=float)
    ap.add_argument("--stabiliser", choices=STABILISERS, help="device-side stabiliser (default none)")
    ap.add_argument("--substep-s", type=float, help="longest stylus integration substep (s); 0: one per tick")
    ap.add_argument("--no-exit", action="store_true", help="keep holding the end pose instead of exiting")
    opts, rest = ap.parse_known_args(argv)
    overrides = {
        k: v
        for k, v in {
            "hand_path": opts.hand_path,
            "rate_hz": opts.rate_hz,
            "convention": opts.convention,
            "device_ns": opts.device_ns,
            "repeat": 0 if opts.loop else opts.repeat,
            "start_delay_s": opts.start_delay_s,
            "exit_when_done": False if opts.no_exit else None,
            "stabiliser": opts.stabiliser,
            "substep_s": opts.substep_s,
        }.items()
        if v is not None
    }
    from ..ros_util import run_nodes

    cls = _build_node_class()
    return run_nodes([lambda: cls(overrides)], args=rest, executor=EXECUTOR)


if __name__ == "__main__":
    raise SystemExit(main())
