"""``skin-sim bench``: skin_sim_node's latency, rate and jitter against bare rclpy baselines.

All cases run in one invocation on this machine, each as separate processes over DDS:

1. ``echo``   a bare rclpy node that answers each pose with a zero wrench (latency baseline);
2. ``node``   skin_sim_node in ``input`` mode answering the same poses;
3. ``ticker`` a bare 1 kHz publishing thread (period-jitter baseline);
4. ``node-timer`` skin_sim_node in ``timer`` mode at ``--rate-hz`` with the tool held pressed.

The pose source and the observer live in this process: poses at ``--rate-hz`` follow a
1 Hz press 0-3 mm deep, stamped with the send time; latency = wrench arrival - stamp.
"""

from __future__ import annotations

import argparse
import math
import os
import tempfile
import time
from pathlib import Path

import numpy as np

from .scenes import Scene


def _pcts(a):
    a = np.asarray(a, dtype=float)
    if a.size == 0:
        return (float("nan"),) * 3
    return float(np.percentile(a, 50)), float(np.percentile(a, 99)), float(a.max())


def run_case(kind: str, duration_s: float, rate_hz: float, log_dir: Path, node_args: tuple[str, ...] = ()) -> dict:
    from geometry_msgs.msg import PoseStamped, TwistStamped

    from msgs_schema import convert as cv

    from .monitor import Monitor
    from .ros_util import PeriodicLoop

    with Scene(log_dir / kind) as scene:
        os.environ["ROS_DOMAIN_ID"] = scene.env["ROS_DOMAIN_ID"]
        os.environ["ROS_AUTOMATIC_DISCOVERY_RANGE"] = scene.env["ROS_AUTOMATIC_DISCOVERY_RANGE"]
        if kind == "echo":
            proc = scene.start("echo", "echo")
        elif kind == "ticker":
            proc = scene.start("ticker", "echo", "--ticker-hz", str(rate_hz))
        else:
            mode = "timer" if kind == "node-timer" else "input"
            proc = scene.node("-p", f"loop_mode:={mode}", "-p", f"rate_hz:={rate_hz}", *node_args)
        scene.wait_for_log(proc, "live:", timeout_s=120)
        mon = Monitor(name=f"bench_{kind.replace('-', '_')}", images=False, record_depth=1)  # newest sample
        pose_pub = mon.publisher("tool_pose")
        twist_pub = mon.publisher("tool_twist")
        pose, twist = PoseStamped(), TwistStamped()
        sent: list[int] = []
        publishing = kind != "ticker"
        hold = kind == "node-timer"
        t_start = [0]

        def tick(now_ns, _elapsed):
            t = (now_ns - t_start[0]) * 1e-9
            z = -1.5e-3 * (1 - math.cos(2 * math.pi * t)) if not hold else -2e-3
            vz = -1.5e-3 * 2 * math.pi * math.sin(2 * math.pi * t) if not hold else 0.0
            stamp = mon.now_ns()
            twist_pub.publish(cv.fill_twist(twist, stamp, "tissue", (0.0, 0.0, vz)))  # twist first: see docs/ros.md
            pose_pub.publish(cv.fill_pose(pose, stamp, "tissue", (0.0, 0.0, z)))
            sent.append(stamp)

        if publishing:
            end = time.monotonic() + 15
            while pose_pub.get_subscription_count() == 0 and time.monotonic() < end:
                time.sleep(0.05)
        mon.wait_for(lambda: publishing or len(mon.wrench) > 10, 15, "ticker wrenches")
        loop = PeriodicLoop(int(1e9 / rate_hz), tick, name="bench-source")
        t_start[0] = time.perf_counter_ns()
        if publishing:
            loop.start()
        time.sleep(1.0)  # warm-up: discovery settles, caches fill
        mon.wrench.clear()
        mon.diagnostics.clear()
        sent.clear()
        time.sleep(duration_s)
        loop.stop()
        time.sleep(0.2)
        records = list(mon.wrench)
        f = mon.forces()
        diags = [d for _, d, _, _ in mon.diagnostics]
        mon.close()
    out = {"case": kind, "sent": len(sent), "wrenches": len(f)}
    rx = np.sort(f[:, 0]) if len(f) else np.zeros(0)
    periods_ms = np.diff(rx) * 1e-6
    out["obs_period_ms"] = _pcts(periods_ms)
    out["obs_missed_pct"] = float(np.mean(periods_ms > 1.5e3 / rate_hz) * 100) if periods_ms.size else float("nan")
    out["obs_rate_hz"] = (len(rx) - 1) / ((rx[-1] - rx[0]) * 1e-9) if len(rx) > 1 else float("nan")
    if publishing and len(f):
        sent_set = set(sent)
        answered = np.array([r - s for r, s, _ in records if s in sent_set], dtype=np.int64)
        out["answered_pct"] = 100.0 * len(answered) / max(len(sent), 1)
        out["latency_ms"] = _pcts(answered * 1e-6)
    if diags:
        out["node_rate_hz"] = float(np.median([float(d["achieved_rate_hz"]) for d in diags]))
        out["node_period_us_p99"] = float(np.median([float(d["period_us_p99"]) for d in diags]))
        out["node_kernel_us_p99"] = float(np.median([float(d["kernel_us_p99"]) for d in diags]))
        out["node_late_ticks"] = int(sum(int(d["late_ticks_window"]) for d in diags))
    return out


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(prog="skin-sim bench", description=__doc__.splitlines()[0])
    ap.add_argument("--duration-s", type=float, default=30.0, help="measured seconds per case (default 30)")
    ap.add_argument("--rate-hz", type=float, default=1000.0)
    ap.add_argument("--cases", default="echo,node,ticker,node-timer")
    ap.add_argument("--node-param", action="append", default=[], help="extra node parameter NAME:=VALUE (repeatable)")
    args = ap.parse_args(argv)
    node_args = tuple(a for p in args.node_param for a in ("-p", p))
    log_dir = Path(tempfile.mkdtemp(prefix="skin_sim_bench_"))
    print(f"skin-sim bench: {args.duration_s:.0f} s per case at {args.rate_hz:.0f} Hz, {os.cpu_count()} cores; logs {log_dir}")
    rows = {c: run_case(c, args.duration_s, args.rate_hz, log_dir, node_args) for c in args.cases.split(",")}
    for r in rows.values():
        line = f"{r['case']:>10}: wrenches {r['wrenches']:6d} at observer {r['obs_rate_hz']:7.1f} Hz"
        p = r["obs_period_ms"]
        line += f" | period p50 {p[0]:.3f} p99 {p[1]:.3f} max {p[2]:.2f} ms, missed(>1.5T) {r['obs_missed_pct']:.2f} %"
        if "latency_ms" in r:
            lat = r["latency_ms"]
            line += f" | answered {r['answered_pct']:.1f} % latency p50 {lat[0]:.3f} p99 {lat[1]:.3f} max {lat[2]:.2f} ms"
        if "node_rate_hz" in r:
            line += (
                f" | node diag: rate {r['node_rate_hz']:.0f} Hz, period p99 {r['node_period_us_p99']:.0f} us, "
                f"tick p99 {r['node_kernel_us_p99']:.0f} us, late ticks {r['node_late_ticks']}"
            )
        print(line, flush=True)
    if "echo" in rows and "node" in rows and "latency_ms" in rows["node"]:
        e, n = rows["echo"]["latency_ms"], rows["node"]["latency_ms"]
        print(f"latency ratio node/echo: p50 {n[0] / e[0]:.2f}x, p99 {n[1] / e[1]:.2f}x")
    if "ticker" in rows and "node-timer" in rows:
        t, n = rows["ticker"]["obs_period_ms"], rows["node-timer"]["obs_period_ms"]
        print(
            f"period p99 ratio node-timer/ticker: {n[1] / t[1]:.2f}x; missed ticks node-timer "
            f"{rows['node-timer']['obs_missed_pct']:.2f} % vs ticker {rows['ticker']['obs_missed_pct']:.2f} %"
        )
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
