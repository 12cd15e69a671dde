"""Scripted, deterministic tool trajectories and a node that publishes them.

The pure part (:data:`TRAJECTORIES`, :class:`Trajectory`) imports no ROS code; the
simulated device uses the same paths as its hand path. :class:`MockToolNode` is built
on first access (PEP 562 module ``__getattr__``), so ``from skin_sim_node.device.mock_tool
import TRAJECTORIES`` works without rclpy.

Every trajectory is a chain of cosine ramps ``p(s) = a + (b - a) (1 - cos(pi s)) / 2``
(``s = t / T``) with the exact velocity ``(b - a) pi / (2 T) sin(pi s)``: position and
velocity are continuous, and every segment starts and ends at rest. All positions are
in the tissue frame (sheet centred on the origin, z up, rest surface z = 0; the tool
presses for z < 0). Each starts and ends lifted at ``z = LIFT_Z_M``.
"""

from __future__ import annotations

import argparse
import bisect
import math
from dataclasses import dataclass, field

LIFT_Z_M = 0.005
"""Lifted tool height (m): 5 mm clears the rest surface by far more than any relaxing bulge."""

Vec3 = tuple[float, float, float]


@dataclass(frozen=True)
class Trajectory:
    """A piecewise cosine-ramp path.

    Parameters
    ----------
    name : str
    start_m : tuple of float
        Start position (m, tissue frame).
    segments : tuple of (duration_s, target_m)
        Each segment ramps from the previous point to ``target_m`` in ``duration_s``;
        ``target_m`` equal to the previous point is a hold.
    description : str
    """

    name: str
    start_m: Vec3
    segments: tuple[tuple[float, Vec3], ...]
    description: str = ""
    _t0: tuple[float, ...] = field(init=False, repr=False, compare=False)
    _p0: tuple[Vec3, ...] = field(init=False, repr=False, compare=False)

    def __post_init__(self):
        t0, p0, t, p = [], [], 0.0, tuple(float(c) for c in self.start_m)
        for dur, target in self.segments:
            if not dur > 0:
                raise ValueError(f"{self.name}: segment durations must be > 0, got {dur}")
            t0.append(t)
            p0.append(p)
            t += float(dur)
            p = tuple(float(c) for c in target)
        object.__setattr__(self, "_t0", tuple(t0))
        object.__setattr__(self, "_p0", tuple(p0))

    @property
    def duration_s(self) -> float:
        """Total duration (s)."""
        return sum(d for d, _ in self.segments)

    @property
    def end_m(self) -> Vec3:
        return tuple(float(c) for c in self.segments[-1][1]) if self.segments else tuple(self.start_m)

    def sample(self, t: float) -> tuple[Vec3, Vec3]:
        """Position (m) and exact velocity (m/s) at time ``t`` (s); held at the ends outside ``[0, duration_s]``."""
        if t <= 0.0 or not self.segments:
            return tuple(float(c) for c in self.start_m), (0.0, 0.0, 0.0)
        if t >= self.duration_s:
            return self.end_m, (0.0, 0.0, 0.0)
        i = bisect.bisect_right(self._t0, t) - 1
        dur, b = self.segments[i]
        a = self._p0[i]
        s = (t - self._t0[i]) / dur
        w = 0.5 * (1.0 - math.cos(math.pi * s))
        dw = 0.5 * math.pi / dur * math.sin(math.pi * s)
        pos = tuple(ai + (bi - ai) * w for ai, bi in zip(a, b))
        vel = tuple((bi - ai) * dw for ai, bi in zip(a, b))
        return pos, vel


def _press(name: str, x_m: float, depth_m: float, press_s: float, hold_s: float, release_s: float, lifted_s: float, desc: str):
    up = (x_m, 0.0, LIFT_Z_M)
    down = (x_m, 0.0, -depth_m)
    return Trajectory(name, up, ((press_s, down), (hold_s, down), (release_s, up), (lifted_s, up)), desc)


def _build() -> dict[str, Trajectory]:
    lift = LIFT_Z_M
    trajs = [
        _press(
            "press_hold_release", 0.0, 2.5e-3, 0.5, 1.0, 0.3, 0.5,
            "centre: press to 2.5 mm over 0.5 s, hold 1 s, release over 0.3 s, stay lifted 0.5 s",
        ),
        _press(
            "light_touch", 0.0, 20e-6, 0.5, 1.0, 0.3, 0.5,
            "centre: press to 20 um (epidermis only: the epidermis/dermis interface peaks at 35 um), hold 1 s, "
            "release over 0.3 s, stay lifted 0.5 s",
        ),
        _press(
            "press_all_layers", 0.0, 4.0e-3, 0.8, 1.0, 0.5, 0.5,
            "centre: press to 4.0 mm (below the dermis/fat interface, 1.275 +- 0.5 mm: all three layers)",
        ),
        Trajectory(
            "drag",
            (-0.02, 0.0, lift),
            (
                (0.5, (-0.02, 0.0, -1.5e-3)),
                (0.2, (-0.02, 0.0, -1.5e-3)),
                (2.0, (0.02, 0.0, -1.5e-3)),
                (0.2, (0.02, 0.0, -1.5e-3)),
                (0.3, (0.02, 0.0, lift)),
                (0.3, (0.02, 0.0, lift)),
            ),
            "press to 1.5 mm at x = -20 mm, drag along x to +20 mm over 2 s across the egg-carton "
            "peaks (x = 0, +-5 mm, ...) and valleys (x = +-2.5 mm, ...) of the dermis/fat interface, lift",
        ),
        _press(
            "edge_press", 0.05, 2.0e-3, 0.5, 1.0, 0.3, 0.5,
            "press to 2 mm at x = 50 mm, 10 mm from the +x sheet edge",
        ),
        Trajectory(
            "fast_stab",
            (0.0, 0.0, lift),
            (
                (0.3, (0.0, 0.0, 0.0)),
                (0.1, (0.0, 0.0, 0.0)),
                (0.02, (0.0, 0.0, -3.0e-3)),
                (0.02, (0.0, 0.0, 0.0)),
                (0.2, (0.0, 0.0, lift)),
                (0.3, (0.0, 0.0, lift)),
            ),
            "approach the surface, stab from the surface to 3 mm in 20 ms and out in 20 ms, lift",
        ),
        Trajectory(
            "lift_during_relax",
            (0.0, 0.0, lift),
            (
                (0.5, (0.0, 0.0, -3.0e-3)),
                (0.3, (0.0, 0.0, -3.0e-3)),
                (0.015, (0.0, 0.0, 0.5e-3)),
                (0.015, (0.0, 0.0, -1.0e-3)),
                (0.3, (0.0, 0.0, -1.0e-3)),
                (0.3, (0.0, 0.0, lift)),
                (0.3, (0.0, 0.0, lift)),
            ),
            "press 3 mm, release to +0.5 mm in 15 ms, come back down to 1 mm 30 ms after the release "
            "started (the tissue is still relaxing: fat release time constant is tens of ms), hold, lift",
        ),
    ]  # fmt: skip
    return {t.name: t for t in trajs}


TRAJECTORIES: dict[str, Trajectory] = _build()
"""The scripted trajectories by name."""


# --- ROS node ---------------------------------------------------------------------------
class ScriptClock:
    """Maps loop time to trajectory time: start delay, repeats, then a lifted tail.

    Parameters
    ----------
    traj : Trajectory
    start_delay_s : float
        Time holding the start pose before the first run (lets DDS discovery finish).
    repeat : int
        Number of runs; ``<= 0`` loops forever.
    tail_s : float
        Time holding the end pose after the last run before :attr:`done`.
    """

    def __init__(self, traj: Trajectory, start_delay_s: float, repeat: int, tail_s: float):
        self.traj, self.start_delay_s, self.repeat, self.tail_s = traj, start_delay_s, repeat, tail_s

    def trajectory_time(self, t_s: float) -> float:
        """Trajectory time (s) at loop time ``t_s``."""
        t = t_s - self.start_delay_s
        d = self.traj.duration_s
        if t <= 0.0:
            return 0.0
        if self.repeat <= 0:
            return math.fmod(t, d)
        return t - d * (self.repeat - 1) if t >= d * self.repeat else math.fmod(t, d)

    def done(self, t_s: float) -> bool:
        return self.repeat > 0 and t_s >= self.start_delay_s + self.traj.duration_s * self.repeat + self.tail_s


DEFAULTS = {
    "trajectory": "press_hold_release",
    "rate_hz": 1000.0,  # the haptics norm (Phantom servo loop), the node's default rate
    "publish_twist": True,
    "repeat": 1,
    "start_delay_s": 1.0,  # DDS discovery on localhost typically completes well within 1 s
    "exit_when_done": True,
    "tail_s": 0.2,  # lifted pose after the last run, so the node sees the tool leave
}


EXECUTOR = "events"  # run_nodes drives it with spin_once(timeout): far less CPU per callback
"""rclpy executor for :func:`run_nodes`. Not ``events``: with the rclpy 7.1.6 wheels its ``spin()``
ignores context shutdown (SIGINT, SIGTERM, exit-when-done never return) and starved Python threads
in a local test; this node publishes from its own loop thread, so the executor has nothing at 1 kHz."""


def _build_node_class():
    import rclpy
    from geometry_msgs.msg import PoseStamped, TwistStamped
    from rcl_interfaces.msg import FloatingPointRange, IntegerRange, ParameterDescriptor
    from rclpy.node import Node

    from msgs_schema.convert import fill_pose, fill_twist
    from msgs_schema.qos import publisher
    from msgs_schema.topics import FRAMES

    from ..ros_util import PeriodicLoop, ros_now_ns
    from .bridge import HOUSEKEEPING_PERIOD_S, publish_while_ok

    class MockToolNode(Node):
        """Publishes a scripted trajectory on ``tool/pose`` (and ``tool/twist``) in the tissue frame.

        Parameters
        ----------
        overrides : dict, optional
            Parameter defaults (e.g. from argparse); ``--ros-args -p`` still wins.
        """

        def __init__(self, overrides: dict | None = None, **kwargs):
            super().__init__("mock_tool", **kwargs)
            d = {**DEFAULTS, **(overrides or {})}

            def desc(**kw):  # all read once at start: read-only, so a live change cannot silently do nothing
                return ParameterDescriptor(read_only=True, **kw)

            self.declare_parameter("trajectory", d["trajectory"], desc(description=f"trajectory name: {', '.join(TRAJECTORIES)}"))
            self.declare_parameter(
                "rate_hz", float(d["rate_hz"]),
                desc(description="publish rate (Hz)", floating_point_range=[FloatingPointRange(from_value=1.0, to_value=2e4)]),
            )  # fmt: skip
            self.declare_parameter("publish_twist", bool(d["publish_twist"]), desc(description="also publish tool/twist"))
            self.declare_parameter(
                "repeat", int(d["repeat"]),
                desc(description="number of runs; 0 loops forever", integer_range=[IntegerRange(from_value=0, to_value=10**6)]),
            )  # fmt: skip
            self.declare_parameter(
                "start_delay_s", float(d["start_delay_s"]),
                desc(description="hold the start pose this long first (s), for DDS discovery"),
            )  # fmt: skip
            self.declare_parameter(
                "exit_when_done", bool(d["exit_when_done"]),
                desc(description="after the last run and tail_s of lifted pose, shut down rclpy (exit 0)"),
            )  # fmt: skip
            self.declare_parameter("tail_s", float(d["tail_s"]), desc(description="lifted pose time after the last run (s)"))
            gp = self.get_parameter
            name = gp("trajectory").value
            if name not in TRAJECTORIES:
                raise ValueError(f"unknown trajectory {name!r}; choose one of {', '.join(TRAJECTORIES)}")
            self.traj = TRAJECTORIES[name]
            self.clock = ScriptClock(self.traj, gp("start_delay_s").value, gp("repeat").value, gp("tail_s").value)
            self.exit_when_done = gp("exit_when_done").value
            self.frame = FRAMES["tissue"]
            self._pose_pub = publisher(self, "tool_pose")
            self._twist_pub = publisher(self, "tool_twist") if gp("publish_twist").value else None
            self._pose, self._twist = PoseStamped(), TwistStamped()
            self._t0_ns: int | None = None
            self._finished = False
            self.get_logger().info(
                f"trajectory {name} ({self.traj.duration_s:.3f} s) x {self.clock.repeat or 'inf'} at {gp('rate_hz').value} Hz"
            )
            self._loop = PeriodicLoop(int(1e9 / gp("rate_hz").value), self._tick, name="mock-tool")
            self.create_timer(HOUSEKEEPING_PERIOD_S, self._housekeeping)
            self._loop.start()

        def _housekeeping(self) -> None:
            if self._finished:
                rclpy.try_shutdown(context=self.context)

        def _tick(self, now_ns: int, elapsed_ns: int) -> None:
            if self._finished:
                return
            if self._t0_ns is None:
                self._t0_ns = now_ns
            t = (now_ns - self._t0_ns) * 1e-9
            pos, vel = self.traj.sample(self.clock.trajectory_time(t))
            stamp = ros_now_ns(self)
            # twist first: a receiver that ticks on the pose then finds the twist of the same stamp
            if self._twist_pub is not None:
                publish_while_ok(self, self._twist_pub, fill_twist(self._twist, stamp, self.frame, vel))
            if not publish_while_ok(self, self._pose_pub, fill_pose(self._pose, stamp, self.frame, pos)):
                return
            if self.exit_when_done and self.clock.done(t):
                self._finished = True
                self.get_logger().info("trajectory done: shutting down")
                self._loop.stop()  # from inside the loop thread: sets the flag, no join

        def stop(self) -> None:
            self._loop.stop()

    return MockToolNode


def __getattr__(name: str):
    if name == "MockToolNode":
        cls = _build_node_class()
        globals()["MockToolNode"] = cls
        return cls
    raise AttributeError(f"module {__name__!r} has no attribute {name!r}")


def main(argv=None) -> int:
    """``mock_tool [--trajectory NAME] [--rate-hz HZ] [--repeat N | --loop] [--list] [--ros-args ...]``."""
    ap = argparse.ArgumentParser(prog="mock_tool", description=__doc__.splitlines()[0])
    ap.add_argument("--trajectory", choices=sorted(TRAJECTORIES), help="trajectory name")
    ap.add_argument("--list", action="store_true", help="list the trajectories and exit")
    ap.add_argument("--rate-hz", type=float)
    ap.add_argument("--no-twist", action="store_true", help="do not publish tool/twist")
    g = ap.add_mutually_exclusive_group()
    g.add_argument("--repeat", type=int, help="number of runs")
    g.add_argument("--loop", action="store_true", help="loop forever")
    ap.add_argument("--start-delay-s", type=float)
    ap.add_argument("--no-exit", action="store_true", help="keep publishing the lifted end pose instead of exiting")
    opts, rest = ap.parse_known_args(argv)
    if opts.list:
        for t in TRAJECTORIES.values():
            print(f"{t.name:20s} {t.duration_s:6.3f} s  {t.description}")
        return 0
    overrides = {
        k: v
        for k, v in {
            "trajectory": opts.trajectory,
            "rate_hz": opts.rate_hz,
            "publish_twist": False if opts.no_twist else None,
            "repeat": 0 if opts.loop else opts.repeat,
            "start_delay_s": opts.start_delay_s,
            "exit_when_done": False if opts.no_exit else None,
        }.items()
        if v is not None
    }
    from ..ros_util import run_nodes

    cls = _build_node_class()
    return run_nodes([lambda: cls(overrides)], args=rest, executor=EXECUTOR)


if __name__ == "__main__":
    raise SystemExit(main())
