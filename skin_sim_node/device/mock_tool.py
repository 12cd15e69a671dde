"""``skin-sim mock-tool``: publishes a scripted trajectory on ``tool/pose`` and ``tool/twist`` (tissue frame).

The trajectories are :data:`skin_sim_node.device.trajectories.TRAJECTORIES` (``--list`` prints them).
No device and no bridge: the node's answers go nowhere but to observers.
"""

from __future__ import annotations

from geometry_msgs.msg import PoseStamped, TwistStamped

from msgs_schema.convert import fill_pose, fill_twist
from msgs_schema.qos import publisher
from msgs_schema.topics import FRAMES

from ..ros_util import ros_now_ns
from .base import Param, ScriptedNode, publish_while_ok
from .trajectories import TRAJECTORIES, ScriptClock


class MockToolNode(ScriptedNode):
    """Publishes a scripted trajectory on ``tool/pose`` (and ``tool/twist``) in the tissue frame."""

    NODE_NAME = "mock_tool"
    PROG = "skin-sim mock-tool"
    DESCRIPTION = "Scripted tool pose/twist publisher (tissue frame), in place of a device and bridge."
    PARAMS = (
        Param("trajectory", "press_hold_release", "trajectory name", choices=tuple(sorted(TRAJECTORIES))),
        Param("rate_hz", 1000.0, "publish rate (Hz); the haptics norm (Phantom servo loop)", 1.0, 2e4),
        Param("publish_twist", True, "also publish tool/twist", cli=""),
        Param("repeat", 1, "number of runs; 0 loops forever", 0, 1_000_000),
        Param("start_delay_s", 1.0, "hold the start pose this long first (s), for DDS discovery", 0.0, 600.0),
        Param("exit_when_done", True, "after the last run and tail_s of lifted pose, shut down (exit 0)", cli=""),
        Param("tail_s", 0.2, "lifted pose time after the last run (s), so the node sees the tool leave", cli=""),
        Param("offset_x_m", 0.0, "the trajectory shifted along x (m): a second hand beside the first (issue 32)", -0.06, 0.06),
        Param("offset_y_m", 0.0, "the trajectory shifted along y (m)", -0.06, 0.06),
    )

    @classmethod
    def add_arguments(cls, ap) -> None:
        """The scripted node's options plus ``--list`` (print the trajectories) and ``--no-twist``."""
        super().add_arguments(ap)
        ap.add_argument("--list", action="store_true", help="list the trajectories and exit")
        ap.add_argument("--no-twist", action="store_true", help="do not publish tool/twist")

    @classmethod
    def overrides_from(cls, opts) -> dict:
        """``--no-twist`` as ``publish_twist = False`` on top of the scripted node's overrides."""
        o = super().overrides_from(opts)
        if opts.no_twist:
            o["publish_twist"] = False
        return o

    @classmethod
    def before_start(cls, opts) -> int | None:
        """``--list``: print the trajectories and exit 0; else None (start the node)."""
        if opts.list:
            for t in TRAJECTORIES.values():
                print(f"{t.name:20s} {t.duration_s:6.3f} s  {t.description}")
            return 0
        return None

    def __init__(self, overrides: dict | None = None, **kwargs):
        super().__init__(overrides, **kwargs)
        p = self.p
        self.traj = TRAJECTORIES[p.trajectory]
        self.clock = ScriptClock(self.traj, p.start_delay_s, p.repeat, p.tail_s)
        self.frame = FRAMES["tissue"]
        self._pose_pub = publisher(self, "tool_pose")
        self._twist_pub = publisher(self, "tool_twist") if p.publish_twist else None
        self._pose, self._twist = PoseStamped(), TwistStamped()
        self._t0_ns: int | None = None
        self.get_logger().info(
            f"trajectory {p.trajectory} ({self.traj.duration_s:.3f} s) x {self.clock.repeat or 'inf'} at {p.rate_hz} Hz"
        )
        self.start_loop(int(1e9 / p.rate_hz), self._tick, name="mock-tool")

    def _tick(self, now_ns: int, elapsed_ns: int) -> None:
        if self.finished:
            return
        if self._t0_ns is None:
            self._t0_ns = now_ns
        t = (now_ns - self._t0_ns) * 1e-9
        pos, vel = self.traj.sample(self.clock.trajectory_time(t))
        if self.p.offset_x_m or self.p.offset_y_m:
            pos = (pos[0] + self.p.offset_x_m, pos[1] + self.p.offset_y_m, pos[2])
        stamp = ros_now_ns(self)
        # twist first: a receiver that ticks on the pose then finds the twist of the same stamp
        if self._twist_pub is not None:
            publish_while_ok(self, self._twist_pub, fill_twist(self._twist, stamp, self.frame, vel))
        if not publish_while_ok(self, self._pose_pub, fill_pose(self._pose, stamp, self.frame, pos, self.traj.orientation)):
            return
        if self.p.exit_when_done and self.clock.done(t):
            self.finish("trajectory done: shutting down")


def main(argv=None) -> int:
    """``skin-sim mock-tool [options] [--ros-args ...]``."""
    return MockToolNode.main(argv)


if __name__ == "__main__":
    raise SystemExit(main())
