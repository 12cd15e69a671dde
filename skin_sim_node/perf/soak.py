"""``skin-sim soak``: hours-long behaviour in minutes: memory and force-stream gaps at 1 kHz.

Scene: skin_sim_node + device bridge + simulated Touch looping the ``drag`` hand path (press
1.5 mm, drag 40 mm across the sheet, lift, again), all 1 kHz, each its own process over DDS.
This process observes ``tool/wrench`` with a deep reader (observer stalls lose no sample) and
samples the resident memory of the node and its display worker with psutil once a second.

Aims (issue 7): resident memory grows by at most 1 % after warm-up; no gap in the force stream
longer than 5 ms. Gaps are measured on the wrench stamps (in ``input`` mode the device's pose
stamp each force answers: the stream as the node produced it) and, for reference, on the
arrival times at this observer (which add this process's own scheduling). Exit 1 when an aim
is missed (``--no-check``: always 0).
"""

from __future__ import annotations

import argparse
import json
import os
import tempfile
import time
from pathlib import Path

import numpy as np
import psutil

from ..scenes import Scene
from .bench_node import SETTLE_S, cpu_steal_ms

GAP_LIMIT_MS = 5.0  # issue 7
RSS_GROWTH_LIMIT_PCT = 1.0  # issue 7
SAMPLE_PERIOD_S = 1.0


def rss_bytes(pid: int) -> tuple[int, int]:
    """Resident set size (bytes) of ``pid`` and the sum over its child processes."""
    p = psutil.Process(pid)
    kids = 0
    for c in p.children(recursive=True):
        try:
            kids += c.memory_info().rss
        except psutil.NoSuchProcess:
            pass
    return p.memory_info().rss, kids


def growth_pct(samples: np.ndarray, warmup_n: int) -> float:
    """Growth (%) of the median of the last 10 % of samples over the first 10 % after warm-up."""
    s = np.asarray(samples, dtype=float)[warmup_n:]
    if s.size < 2:
        return float("nan")
    k = max(1, s.size // 10)
    return float(100.0 * (np.median(s[-k:]) - np.median(s[:k])) / np.median(s[:k]))


class GapCounter:
    """Incremental gap statistics of a time series (ns): count over a limit, max, histogram-free."""

    def __init__(self, limit_ns: float):
        self.limit_ns = limit_ns
        self.last: int | None = None
        self.n = 0
        self.over = 0
        self.max_ns = 0
        self.p99_parts: list[np.ndarray] = []

    def add(self, t_ns: np.ndarray) -> None:
        t = np.sort(np.asarray(t_ns, dtype=np.int64))
        if t.size == 0:
            return
        if self.last is not None:
            t = np.concatenate(([self.last], t))
        d = np.diff(t)
        self.last = int(t[-1])
        if d.size:
            self.n += d.size
            self.over += int(np.sum(d > self.limit_ns))
            self.max_ns = max(self.max_ns, int(d.max()))
            self.p99_parts.append(np.float32(d * 1e-6))

    def summary(self) -> dict:
        d = np.concatenate(self.p99_parts) if self.p99_parts else np.zeros(0)
        return {
            "periods": self.n,
            "gaps_over_limit": self.over,
            "max_gap_ms": self.max_ns * 1e-6,
            "p50_ms": float(np.percentile(d, 50)) if d.size else float("nan"),
            "p99_ms": float(np.percentile(d, 99)) if d.size else float("nan"),
        }


def run_soak(
    duration_s: float, warmup_s: float, log_dir: Path, node_args: tuple[str, ...] = (), quiet: bool = False, rt_priority: int = 0
) -> dict:
    """Run the soak scene; returns the figures (see the module docstring).

    ``rt_priority`` > 0: the node runs its haptic threads SCHED_FIFO at it (``rt_priority``
    parameter), the bridge, the simulated device and this observer run SCHED_FIFO one below
    (a device's servo loop and its driver would).
    """
    from ..ros_util import set_pid_realtime
    from .bench_node import StreamObserver

    if rt_priority > 0:
        node_args = (*node_args, "-p", f"rt_priority:={rt_priority}")

    with Scene(log_dir) as scene:
        os.environ["ROS_DOMAIN_ID"] = scene.env["ROS_DOMAIN_ID"]
        os.environ["ROS_AUTOMATIC_DISCOVERY_RANGE"] = scene.env["ROS_AUTOMATIC_DISCOVERY_RANGE"]
        node = scene.node(*node_args)
        scene.wait_for_log(node, "live:", timeout_s=180)
        mon = StreamObserver("soak_observer", record_depth=1000)
        joined = time.monotonic()
        try:
            peers = [scene.start("bridge", "bridge")]
            peers.append(scene.start("device", "device", "--hand-path", "drag", "--loop", "--start-delay-s", "1.0"))
            if rt_priority > 0:
                time.sleep(0.5)  # their threads exist
                for p in [*peers, None]:
                    problem = set_pid_realtime(p.popen.pid if p else os.getpid(), max(rt_priority - 1, 1))
                    if problem:
                        print(f"soak: {problem}", flush=True)
            mon.wait_for(lambda: any(abs(f) > 0 for _, _, f in mon.wrench[-2000:]), 60, "a pressing force")
            time.sleep(max(0.0, joined + SETTLE_S - time.monotonic()))  # a joining reader's stall: see SETTLE_S
            del mon.wrench[:]
            stamp_gaps, rx_gaps = GapCounter(GAP_LIMIT_MS * 1e6), GapCounter(GAP_LIMIT_MS * 1e6)
            t_rss, rss, rss_kids = [], [], []
            n_force = n_pressing = 0
            t0 = time.monotonic()
            steal0 = cpu_steal_ms()
            next_sample = t0
            while (now := time.monotonic()) < t0 + duration_s:
                if node.popen.poll() is not None:
                    raise RuntimeError(f"node exited with {node.popen.returncode}:\n{node.log()[-3000:]}")
                main_rss, kid_rss = rss_bytes(node.popen.pid)
                t_rss.append(now - t0)
                rss.append(main_rss)
                rss_kids.append(kid_rss)
                n = len(mon.wrench)
                batch = np.array(mon.wrench[:n], dtype=np.float64).reshape(-1, 3)
                del mon.wrench[:n]
                rx_gaps.add(batch[:, 0].astype(np.int64))
                stamp_gaps.add(batch[:, 1].astype(np.int64))
                n_force += len(batch)
                n_pressing += int(np.sum(np.abs(batch[:, 2]) > 0))
                if not quiet and len(rss) % 30 == 0:
                    print(f"  t {now - t0:6.0f} s: node rss {main_rss / 2**20:.1f} MiB, display {kid_rss / 2**20:.1f} MiB, "
                          f"forces {n_force}, max stamp gap {stamp_gaps.max_ns * 1e-6:.2f} ms", flush=True)  # fmt: skip
                next_sample += SAMPLE_PERIOD_S
                time.sleep(max(0.0, next_sample - time.monotonic()))
            steal_ms = cpu_steal_ms() - steal0
        finally:
            mon.close()
    warm_n = int(np.searchsorted(np.asarray(t_rss), warmup_s))
    out = {
        "duration_s": duration_s,
        "warmup_s": warmup_s,
        "forces": n_force,
        "force_rate_hz": n_force / duration_s,
        "pressing_pct": 100.0 * n_pressing / max(n_force, 1),
        "rss_samples": len(rss),
        "node_rss_mib": (rss[warm_n] / 2**20 if warm_n < len(rss) else float("nan"), rss[-1] / 2**20 if rss else float("nan")),
        "node_rss_growth_pct": growth_pct(rss, warm_n),
        "display_rss_growth_pct": growth_pct(rss_kids, warm_n),
        "steal_ms": steal_ms,
        "stamp_gaps": stamp_gaps.summary(),
        "arrival_gaps": rx_gaps.summary(),
    }
    out["aims_met"] = bool(out["node_rss_growth_pct"] <= RSS_GROWTH_LIMIT_PCT and out["stamp_gaps"]["gaps_over_limit"] == 0)
    return out


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(prog="skin-sim soak", description=__doc__.splitlines()[0])
    ap.add_argument("--duration-s", type=float, default=600.0, help="measured seconds (default 600)")
    ap.add_argument(
        "--warmup-s", type=float, default=None, help="memory warm-up excluded from the growth (default 10 %%, >= 5 s)"
    )
    ap.add_argument("--node-param", action="append", default=[], help="node parameter NAME:=VALUE (repeatable)")
    ap.add_argument("--rt-priority", type=int, default=0, help="SCHED_FIFO: node at this, device side one below (0: off)")
    ap.add_argument("--json", type=Path, help="also write the figures to this JSON file")
    ap.add_argument("--no-check", action="store_true", help="exit 0 even when an aim is missed")
    args = ap.parse_args(argv)
    warmup = args.warmup_s if args.warmup_s is not None else max(5.0, 0.1 * args.duration_s)
    node_args = tuple(a for p in args.node_param for a in ("-p", p))
    log_dir = Path(tempfile.mkdtemp(prefix="skin_sim_soak_"))
    print(
        f"skin-sim soak: {args.duration_s:.0f} s, warm-up {warmup:.0f} s, rt priority {args.rt_priority}, "
        f"load {os.getloadavg()[0]:.2f}; logs {log_dir}",
        flush=True,
    )
    r = run_soak(args.duration_s, warmup, log_dir, node_args, rt_priority=args.rt_priority)
    sg, ag = r["stamp_gaps"], r["arrival_gaps"]
    print(
        f"forces {r['forces']} ({r['force_rate_hz']:.1f} Hz, {r['pressing_pct']:.0f} % pressing)\n"
        f"node rss {r['node_rss_mib'][0]:.1f} -> {r['node_rss_mib'][1]:.1f} MiB after warm-up: growth "
        f"{r['node_rss_growth_pct']:+.3f} % (aim <= {RSS_GROWTH_LIMIT_PCT} %); "
        f"display worker {r['display_rss_growth_pct']:+.3f} %\n"
        f"force stream gaps (stamps):  p50 {sg['p50_ms']:.3f} p99 {sg['p99_ms']:.3f} max {sg['max_gap_ms']:.2f} ms, "
        f"{sg['gaps_over_limit']} over {GAP_LIMIT_MS} ms of {sg['periods']} (aim: none)\n"
        f"force stream gaps (arrival): p50 {ag['p50_ms']:.3f} p99 {ag['p99_ms']:.3f} max {ag['max_gap_ms']:.2f} ms, "
        f"{ag['gaps_over_limit']} over {GAP_LIMIT_MS} ms\n"
        f"hypervisor steal during the run: {r['steal_ms']:.0f} ms (both vCPUs)\n"
        f"aims met: {r['aims_met']}",
        flush=True,
    )
    if args.json:
        args.json.write_text(json.dumps(r, indent=1))
    return 0 if r["aims_met"] or args.no_check else 1


if __name__ == "__main__":
    raise SystemExit(main())
