"""``skin-sim echo``: the bare rclpy baseline: pose in, wrench out (same stamp), no model.

Same topics, QoS, executor and process set-up as skin_sim_node, so a latency ratio
against it isolates what the node adds.
"""

from __future__ import annotations

import argparse
import sys

from geometry_msgs.msg import WrenchStamped
from rclpy.node import Node

from msgs_schema import convert as cv
from msgs_schema.qos import publisher, subscription
from skin_sim_node.device.base import publish_while_ok
from skin_sim_node.ros_util import PeriodicLoop, run_nodes


class EchoNode(Node):
    """Echo each pose as a zero wrench; with ``ticker_hz`` > 0, instead publish a wrench at that
    rate (the period-jitter baseline) from a bare rclpy timer (``ticker_kind="timer"``) or from
    the same thread loop as skin_sim_node (``"thread"``)."""

    def __init__(self, ticker_hz: float = 0.0, ticker_kind: str = "timer"):
        super().__init__("skin_sim_echo")
        self._msg = WrenchStamped()
        self._pub = publisher(self, "tool_wrench")
        self._loop = None
        if ticker_hz > 0 and ticker_kind == "thread":
            self._loop = PeriodicLoop(int(1e9 / ticker_hz), self._on_tick)
            self._loop.start()
        elif ticker_hz > 0:
            self.create_timer(1.0 / ticker_hz, lambda: self._on_tick(0, 0))
        else:
            subscription(self, "tool_pose", self._on_pose)
        self.get_logger().info("live: echo" + (f" {ticker_kind} ticker at {ticker_hz} Hz" if ticker_hz else ""))

    def stop(self) -> None:
        """Stop the ticker thread, if one runs."""
        if self._loop:
            self._loop.stop()

    def _on_tick(self, _now, _elapsed) -> None:
        if not self.context.ok():  # Ctrl-C/SIGTERM: the timer or loop may fire once more; publish nothing
            return
        msg = cv.fill_wrench(self._msg, self.get_clock().now().nanoseconds, "tissue", (0.0, 0.0, 0.0))
        publish_while_ok(self, self._pub, msg)

    def _on_pose(self, msg) -> None:
        stamp, frame, _ = cv.read_pose(msg)
        publish_while_ok(self, self._pub, cv.fill_wrench(self._msg, stamp, frame, (0.0, 0.0, 0.0)))


def main(argv=None) -> int:
    """``skin-sim echo``: run the bare echo (or ticker) node until interrupted."""
    ap = argparse.ArgumentParser(prog="skin-sim echo", description=__doc__.splitlines()[0])
    ap.add_argument("--executor", choices=("events", "single"), default="events")
    ap.add_argument("--switch-interval-s", type=float, default=2e-4)
    ap.add_argument("--ticker-hz", type=float, default=0.0, help="publish at this rate instead of echoing")
    ap.add_argument("--ticker-kind", choices=("timer", "thread"), default="timer", help="rclpy timer or a PeriodicLoop thread")
    args, rest = ap.parse_known_args(argv)
    sys.setswitchinterval(args.switch_interval_s)
    return run_nodes([lambda: EchoNode(args.ticker_hz, args.ticker_kind)], args=rest, executor=args.executor)


if __name__ == "__main__":
    raise SystemExit(main())
