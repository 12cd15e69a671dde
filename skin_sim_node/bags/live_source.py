"""Live replay publisher: a process of its own that publishes the inputs at recorded timing.

Started by :mod:`skin_sim_node.bags.live`. It publishes only (no executor, no subscriptions),
so no other Python thread competes for its GIL: in one process with the recorder, the
publishing thread was late by up to 50 ms, and the node's keep-last-1 pose reader then keeps
one pose of each late burst. Protocol: it publishes lifted handshake poses every 10 ms until
a line arrives on stdin (the parent saw the node answer one), waits past the node's watchdog,
streams, and prints one JSON line with the stream's wall time and publish lateness.
"""

from __future__ import annotations

import argparse
import gc
import json
import select
import sys
import time

import numpy as np

from msgs_schema import convert as cv

HANDSHAKE_PERIOD_S = 0.01
WATCHDOG_WAIT_S = 0.1  # > the node's 50 ms watchdog


def stream(pose_pub, twist_pub, stamps, ranks, frames, xyz, speed: float, quat=None) -> tuple[float, np.ndarray]:
    """Publish every input at its recorded time / speed; returns wall time (s) and pose lateness (s)."""
    from geometry_msgs.msg import PoseStamped, TwistStamped

    pose, twist = PoseStamped(), TwistStamped()
    late = []
    first = int(stamps[0])
    t0 = time.perf_counter_ns()
    quats = quat.tolist() if quat is not None else [(0.0, 0.0, 0.0, 1.0)] * len(stamps)
    for stamp, rank, frame, p, q in zip(stamps.tolist(), ranks.tolist(), frames, xyz.tolist(), quats):
        due = t0 + int((stamp - first) / speed)
        rem = due - time.perf_counter_ns()
        if rem > 200_000:
            time.sleep(rem * 1e-9)
        if rank:
            late.append(time.perf_counter_ns() - due)
            pose_pub.publish(cv.fill_pose(pose, stamp, frame, p, q))
        else:
            twist_pub.publish(cv.fill_twist(twist, stamp, frame, p))
    return (time.perf_counter_ns() - t0) * 1e-9, np.array(late) * 1e-9


def main(argv=None) -> int:
    """Publish a lifted pose until ``go`` on stdin (the live replay's handshake), then stream the events; print timing JSON."""
    ap = argparse.ArgumentParser(prog="skin_sim_node.bags.live_source", description=__doc__.splitlines()[0])
    ap.add_argument("events", help=".npz with stamps, ranks (1 pose, 0 twist), frame_ids, frames, xyz")
    ap.add_argument("--speed", type=float, default=1.0)
    ap.add_argument("--handshake-base-ns", type=int, required=True)
    args = ap.parse_args(argv)
    d = np.load(args.events)
    names = [str(s) for s in d["frame_names"]]
    frames = [names[i] for i in d["frame_ids"]]
    stamps, ranks, xyz = d["stamps"], d["ranks"], d["xyz"]
    import rclpy
    from geometry_msgs.msg import PoseStamped

    from msgs_schema.qos import publisher

    rclpy.init()
    node = rclpy.create_node("skin_sim_live_source")
    pose_pub, twist_pub = publisher(node, "tool_pose"), publisher(node, "tool_twist")
    i0 = int(np.argmax(ranks == 1))
    x, y, z = xyz[i0]
    lifted = (float(x), float(y), max(float(z), 0.005))
    msg = PoseStamped()
    i = 0
    while not select.select([sys.stdin], [], [], HANDSHAKE_PERIOD_S)[0]:
        q0 = tuple(float(c) for c in d["quat"][i0]) if "quat" in d else (0.0, 0.0, 0.0, 1.0)
        pose_pub.publish(cv.fill_pose(msg, args.handshake_base_ns + i * 1_000_000, frames[i0], lifted, q0))
        i += 1
    if not sys.stdin.readline().startswith("go"):
        return 1
    time.sleep(WATCHDOG_WAIT_S)
    gc.collect()
    gc.disable()
    sys.setswitchinterval(2e-4)
    wall, late = stream(pose_pub, twist_pub, stamps, ranks, frames, xyz, args.speed, d["quat"] if "quat" in d else None)
    print(
        json.dumps(
            {
                "stream_wall_s": wall,
                "handshake_poses": i,
                **{f"publish_late_ms_p{q}": float(np.percentile(late, q) * 1e3) for q in (50, 99)},
                "publish_late_ms_max": float(late.max() * 1e3),
            }
        ),
        flush=True,
    )
    node.destroy_node()
    rclpy.try_shutdown()
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
