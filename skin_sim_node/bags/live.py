"""Live replay: publish a bag's tool inputs to a running node at recorded timing and compare.

The recorded stamps are kept, so the node's wrench stamps equal the pose stamps and match
the offline replay's one for one. The node must not reject old stamps: a node started here
gets ``-p max_stamp_age_s:=0.0``; an ``--attach``-ed node must have been started with it.

Before the first recorded pose a discovery handshake publishes lifted poses (at the first
pose's x, y, stamped seconds before the bag) until the node answers one, then waits past
the watchdog so the node has released the tissue: a lifted tool leaves the model at rest,
the state the offline replay starts from. Within one stamp the twist is published first,
so the node's tick uses it, as the offline tick does.
"""

from __future__ import annotations

import gc
import json
import sys
import time
from pathlib import Path

import numpy as np

from msgs_schema import convert as cv
from msgs_schema.topics import TOPICS

from ..mock_tool import LIFT_Z_M
from .inputs import POSE, Inputs
from .io import BagWriter, deserialize, qos_profiles
from .offline import ReplayResult, bag_topic

HANDSHAKE_LEAD_NS = 5_000_000_000
WATCHDOG_WAIT_S = 0.1  # > the node's 50 ms watchdog


def _handshake(rec, pose_pub, msg, inputs: Inputs, timeout_s: float) -> int:
    """Publish lifted poses until the node answers one; returns how many were sent."""
    first = next(e for e in inputs.events if e[1] == POSE)
    x, y, z = first[3]
    xyz = (x, y, max(z, LIFT_Z_M))
    base = first[0] - HANDSHAKE_LEAD_NS
    end = time.monotonic() + timeout_s
    sent = set()
    i = 0
    while time.monotonic() < end:
        stamp = base + i * 1_000_000
        i += 1
        sent.add(stamp)
        pose_pub.publish(cv.fill_pose(msg, stamp, first[2], xyz))
        time.sleep(0.01)
        if sent & set(live_forces(rec.records[-20:])):
            time.sleep(WATCHDOG_WAIT_S)
            return i
    raise TimeoutError(
        "the node never answered a handshake pose: is it running on this ROS_DOMAIN_ID, with max_stamp_age_s:=0.0?"
    )


def _stream(pose_pub, twist_pub, inputs: Inputs, speed: float) -> tuple[float, np.ndarray]:
    """Publish every input at its recorded time (scaled by 1/speed).

    Returns the wall time taken (s) and each pose's publish lateness (s).
    """
    from geometry_msgs.msg import PoseStamped, TwistStamped

    pose, twist = PoseStamped(), TwistStamped()
    first = inputs.events[0][0]
    late = []
    t0 = time.perf_counter_ns()
    for stamp, rank, frame, xyz in inputs.events:
        due = t0 + int((stamp - first) / speed)
        rem = due - time.perf_counter_ns()
        if rem > 200_000:
            time.sleep(rem * 1e-9)
        if rank == POSE:
            late.append(time.perf_counter_ns() - due)
            pose_pub.publish(cv.fill_pose(pose, stamp, frame, xyz))
        else:
            twist_pub.publish(cv.fill_twist(twist, stamp, frame, xyz))
    return (time.perf_counter_ns() - t0) * 1e-9, np.array(late) * 1e-9


def live_forces(records) -> dict[int, float]:
    out = {}
    for _, key, raw in records:
        if key == "tool_wrench":
            stamp, _, f = cv.read_wrench(deserialize(raw, "geometry_msgs/msg/WrenchStamped"))
            out[stamp] = f[2]
    return out


def agreement(offline: ReplayResult, live: dict[int, float]) -> dict:
    """Max and RMS force difference at matched stamps and the fraction of poses answered."""
    off = dict(zip(offline.stamps_ns.tolist(), offline.force_n.tolist()))
    common = sorted(set(off) & set(live))
    d = np.array([live[s] - off[s] for s in common]) if common else np.zeros(0)
    peak = offline.peak_force_n
    return {
        "offline_answered": len(off),
        "live_answered": len(common),
        "fraction_answered": len(common) / max(len(off), 1),
        "max_df_n": float(np.max(np.abs(d))) if d.size else float("nan"),
        "rms_df_n": float(np.sqrt(np.mean(d**2))) if d.size else float("nan"),
        "peak_force_n": peak,
        "max_df_frac_of_peak": float(np.max(np.abs(d)) / peak) if d.size and peak > 0 else float("nan"),
    }


def run_live(inputs: Inputs, offline: ReplayResult, args, out: Path) -> int:
    """Start (or attach to) a node, stream the inputs, record its outputs to ``out/live``, compare."""
    from ..scenes import Scene
    from .recorder import Recorder, use_scene_env

    scene = None if args.attach else Scene(out / "live_logs")
    if scene is not None:
        use_scene_env(scene.env)
    keys = (
        ["tool_wrench", "diagnostics"]
        + (["contact"] if args.contact else [])
        + (["height_map", "layer_heights"] if args.images else [])
    )
    # kept in memory while streaming and written afterwards: no disk work competes with the node for the 2 cores
    rec = Recorder(keys, None, name="skin_sim_live_replay", keep=True, executor="single")
    gc.collect()
    switch = sys.getswitchinterval()
    sys.setswitchinterval(2e-4)  # as the node: the publishing thread gets the GIL back within 0.2 ms
    gc.disable()  # a full collection over the growing record list would stall the stream by milliseconds
    try:
        if scene is not None:
            extra = ["-p", "max_stamp_age_s:=0.0"]
            if not args.images:  # the display worker competes for the 2 cores; the comparison needs no grids
                extra += ["-p", "display_rate_hz:=0.0", "-p", "publish_mesh:=false"]
            node = scene.node(*extra, params=args.params)
            scene.wait_for_log(node, "live:", timeout_s=args.timeout_s)
        pose_pub, twist_pub = rec.publisher("tool_pose"), rec.publisher("tool_twist")
        from geometry_msgs.msg import PoseStamped

        t0 = time.perf_counter()
        _handshake(rec, pose_pub, PoseStamped(), inputs, timeout_s=30.0)
        t_handshake = time.perf_counter() - t0
        t_stream, late_s = _stream(pose_pub, twist_pub, inputs, args.speed)
        time.sleep(0.3)  # answers in flight
    finally:
        gc.enable()
        sys.setswitchinterval(switch)
        rec.close()
        if scene is not None:
            scene.stop_all()
    with BagWriter(out / "live", args.storage, custom_data={"skin_sim.source": inputs.bag.name}, overwrite=True) as w:
        for rx, key, raw in rec.records:
            w.write_raw(bag_topic(key), TOPICS[key].type, rx, raw, qos_profiles(key))
    stats = agreement(offline, live_forces([r for r in rec.records if r[1] == "tool_wrench"]))
    span = (inputs.events[-1][0] - inputs.events[0][0]) * 1e-9
    stats.update({"speed": args.speed, "recorded_span_s": span, "stream_wall_s": t_stream, "handshake_s": t_handshake})
    for q in (50, 99):
        stats[f"publish_late_ms_p{q}"] = float(np.percentile(late_s, q) * 1e3)
    stats["publish_late_ms_max"] = float(late_s.max() * 1e3)
    ok = stats["max_df_n"] <= args.force_tol_frac * offline.peak_force_n and stats["fraction_answered"] >= args.min_answered
    stats["pass"] = bool(ok)
    (out / "live_summary.json").write_text(json.dumps(stats, indent=2) + "\n")
    print(
        f"live replay: streamed {span:.3f} s of inputs in {t_stream:.3f} s (speed {args.speed:g}; handshake {t_handshake:.2f} s) "
        f"-> {out / 'live'}\n"
        f"node answered {stats['live_answered']} of {stats['offline_answered']} poses ({stats['fraction_answered']:.2%}); "
        f"at matched stamps max |dF| = {stats['max_df_n']:.3e} N ({stats['max_df_frac_of_peak']:.3%} of peak "
        f"{offline.peak_force_n:.4f} N), RMS dF = {stats['rms_df_n']:.3e} N\n"
        f"publish lateness p50 {stats['publish_late_ms_p50']:.3f} ms, p99 {stats['publish_late_ms_p99']:.3f} ms, "
        f"max {stats['publish_late_ms_max']:.3f} ms\n"
        f"{'PASS' if ok else 'FAIL'} (limits: max |dF| <= {args.force_tol_frac:.1%} of peak, answered >= {args.min_answered:.0%})"
    )
    return 0 if ok else 1
