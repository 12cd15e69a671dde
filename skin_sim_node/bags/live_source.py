"""Live replay publisher: a process of its own that publishes the inputs at recorded timing.

Started by :mod:`skin_sim_node.bags.live`. It publishes only (no executor, no subscriptions),
so no other Python thread competes for its GIL: in one process with the recorder, the
publishing thread was late by up to 50 ms, and the node's keep-last-1 pose reader then keeps
one pose of each late burst. Protocol: it publishes lifted handshake poses every 10 ms until
a line arrives on stdin (the parent saw the node answer one), waits past the node's watchdog,
streams, and prints one JSON line with the stream's wall time and publish lateness.

A node with hands (issue 32): the events file names the hands (``hand_names``, each event's ``hands`` index), each
hand's inputs go to ``<hand>/tool/pose`` and ``<hand>/tool/twist`` in the file's one merged order
(:func:`skin_sim_node.bags.offline.merged_events`), and every hand gets its own lifted handshake pose each period (the
parent waits for every hand's answer). Without them the file is one hand's, on the contract's names.
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
from msgs_schema.topics import hand_topic

HANDSHAKE_PERIOD_S = 0.01
WATCHDOG_WAIT_S = 0.1  # > the node's 50 ms watchdog


def stream(pose_pubs, twist_pubs, stamps, ranks, frames, xyz, speed: float, quat=None, hands=None) -> tuple[float, np.ndarray]:
    """Publish every input at its recorded time / speed to its hand's publishers (``hands[i]`` indexes ``pose_pubs``
    and ``twist_pubs``; None: all the first's); returns wall time (s) and pose lateness (s)."""
    from geometry_msgs.msg import PoseStamped, TwistStamped

    pose, twist = PoseStamped(), TwistStamped()
    late = []
    first = int(stamps[0])
    t0 = time.perf_counter_ns()
    quats = quat.tolist() if quat is not None else [(0.0, 0.0, 0.0, 1.0)] * len(stamps)
    hand_ix = hands.tolist() if hands is not None else [0] * len(stamps)
    for stamp, rank, frame, p, q, h in zip(stamps.tolist(), ranks.tolist(), frames, xyz.tolist(), quats, hand_ix):
        due = t0 + int((stamp - first) / speed)
        rem = due - time.perf_counter_ns()
        if rem > 200_000:
            time.sleep(rem * 1e-9)
        if rank:
            late.append(time.perf_counter_ns() - due)
            pose_pubs[h].publish(cv.fill_pose(pose, stamp, frame, p, q))
        else:
            twist_pubs[h].publish(cv.fill_twist(twist, stamp, frame, p))
    return (time.perf_counter_ns() - t0) * 1e-9, np.array(late) * 1e-9


def main(argv=None) -> int:
    """Publish a lifted pose until ``go`` on stdin (the live replay's handshake), then stream the events; print timing JSON."""
    ap = argparse.ArgumentParser(prog="skin_sim_node.bags.live_source", description=__doc__.splitlines()[0])
    ap.add_argument("events", help=".npz with stamps, ranks (1 pose, 0 twist), frame_ids, frames, xyz[, hands, hand_names]")
    ap.add_argument("--speed", type=float, default=1.0)
    ap.add_argument("--handshake-base-ns", type=int, required=True)
    args = ap.parse_args(argv)
    d = np.load(args.events)
    names = [str(s) for s in d["frame_names"]]
    frames = [names[i] for i in d["frame_ids"]]
    stamps, ranks, xyz = d["stamps"], d["ranks"], d["xyz"]
    hand_names = [str(s) for s in d["hand_names"]] if "hand_names" in d else [""]
    hands = d["hands"] if "hands" in d else np.zeros(len(stamps), dtype=np.int8)
    import rclpy
    from geometry_msgs.msg import PoseStamped

    from msgs_schema.qos import publisher

    rclpy.init()
    node = rclpy.create_node("skin_sim_live_source")
    pose_pubs = [publisher(node, "tool_pose", hand_topic("tool_pose", ns)) for ns in hand_names]
    twist_pubs = [publisher(node, "tool_twist", hand_topic("tool_twist", ns)) for ns in hand_names]
    lifts = []  # each hand's handshake: its first pose's x, y, lifted to z >= 5 mm, and orientation
    for h in range(len(hand_names)):
        i0 = int(np.argmax((ranks == 1) & (hands == h)))
        x, y, z = xyz[i0]
        q0 = tuple(float(c) for c in d["quat"][i0]) if "quat" in d else (0.0, 0.0, 0.0, 1.0)
        lifts.append((pose_pubs[h], frames[i0], (float(x), float(y), max(float(z), 0.005)), q0))
    msg = PoseStamped()
    i = 0
    while not select.select([sys.stdin], [], [], HANDSHAKE_PERIOD_S)[0]:
        for pub, frame, lifted, q0 in lifts:
            pub.publish(cv.fill_pose(msg, args.handshake_base_ns + i * 1_000_000, frame, lifted, q0))
        i += 1
    if not sys.stdin.readline().startswith("go"):
        return 1
    time.sleep(WATCHDOG_WAIT_S)
    gc.collect()
    gc.disable()
    sys.setswitchinterval(2e-4)
    wall, late = stream(pose_pubs, twist_pubs, stamps, ranks, frames, xyz, args.speed, d["quat"] if "quat" in d else None, hands)
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
