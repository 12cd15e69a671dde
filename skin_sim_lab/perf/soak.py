"""``skin-sim soak``: hours-long behaviour in minutes: memory and force-stream gaps at 1 kHz.

Scene: skin_sim_node + device bridge + simulated Touch looping the ``drag`` hand path (press
1.5 mm, drag 40 mm across the sheet, lift, again), all 1 kHz, each its own process over DDS.
This process observes ``tool/wrench`` with a deep reader (observer stalls lose no sample) and
samples the resident memory of the node and its display worker with psutil once a second.

Aims (issue 7): resident memory grows by at most 1 % after warm-up; no gap in the force stream longer than 5
ms. Aims at the device (issue 12): every device tick the bridge renders gets its force from a contact model no
older than its time-to-live, with zero exceptions, in three phases of equal length: steady (node at 1 kHz,
input mode), joining readers (a new DDS participant subscribes to ``tool/wrench`` every ``JOIN_EVERY_S``, for
``JOIN_HOLD_S`` each) and throttled (the node set live to ``loop_mode:=timer``, ``rate_hz:=250``). The
bridge's own counters (its ``diagnostics``) give the figures; the device's and the bridge's tick counts give
the poses lost between them. Gaps are measured on the wrench stamps (in ``input`` mode the device's pose stamp
each force answers: the stream as the node produced it) and, for reference, on the arrival times at this
observer (which add this process's own scheduling). It ends with one line, ``soak PASS: ...`` or
``soak FAIL: ...``, naming each aim missed and met; exit 1 when an aim is missed (``--no-check``: always 0).
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

from skin_sim_node.scenes import Scene
from skin_sim_node.verdicts import exit_code, verdict_line

from .bench_node import SETTLE_S, cpu_steal_ms

GAP_LIMIT_MS = 5.0  # issue 7
PHASES = ("steady", "joining readers", "throttled 250 Hz")
JOIN_EVERY_S = 10.0  # a new tool/wrench reader every 10 s: several joins in any phase of >= 30 s
JOIN_HOLD_S = 5.0  # each stays 5 s: past the ~2-3 s after which the join stall was measured (bench_node.SETTLE_S)
THROTTLE = (("loop_mode", "timer"), ("rate_hz", 250.0))  # the server rate lever at the 250 Hz
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
    from skin_sim_node.bags.monitor import StreamObserver
    from skin_sim_node.ros_util import set_pid_realtime

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
            peers = [scene.start("bridge", "bridge", "--diagnostics-period-s", "0.25")]
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
            phases = PhaseTracker(mon, node_name="skin_sim_node")
            t0 = time.monotonic()
            steal0 = cpu_steal_ms()
            next_sample = t0
            while (now := time.monotonic()) < t0 + duration_s:
                phases.update(now - t0, duration_s)
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
                    print(
                        f"  t {now - t0:6.0f} s: node rss {main_rss / 2**20:.1f} MiB, display {kid_rss / 2**20:.1f} MiB, "
                        f"forces {n_force}, max stamp gap {stamp_gaps.max_ns * 1e-6:.2f} ms",
                        flush=True,
                    )
                next_sample += SAMPLE_PERIOD_S
                time.sleep(max(0.0, next_sample - time.monotonic()))
            steal_ms = cpu_steal_ms() - steal0
            phases.finish()
        finally:
            mon.close()
        scene.stop_all()
        device_ticks = _stopping_count(peers[1].log(), r"sim device stopping: (\d+) ticks")
        bridge_rendered = _stopping_count(peers[0].log(), r"(\d+) device ticks rendered")
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
        "device_phases": phases.summary(),
        "device_ticks": device_ticks,
        "bridge_rendered": bridge_rendered,
    }
    device_ok = all(p["stale_model"] == 0 and p["rendered"] > 0 for p in out["device_phases"].values())
    out["device_aim_met"] = device_ok
    out["aims_met"] = bool(
        out["node_rss_growth_pct"] <= RSS_GROWTH_LIMIT_PCT and out["stamp_gaps"]["gaps_over_limit"] == 0 and device_ok
    )
    return out


def _stopping_count(log: str, pattern: str) -> int | None:
    import re

    m = re.search(pattern, log)
    return int(m.group(1)) if m else None


class PhaseTracker:
    """The soak's three phases (:data:`PHASES`): joins readers, throttles the node, and books the bridge's counters.

    Reads the bridge's ``diagnostics`` (totals every 0.25 s) from the observer ``mon``; each phase gets the
    difference of the totals over it, the worst model age and the lowest render rate of its windows, and the
    node's median achieved rate.
    """

    def __init__(self, mon, node_name: str):
        self.mon = mon
        self.node_name = node_name
        self.phase = -1
        self.readers: list = []
        self.next_join = 0.0
        self.start_totals: dict | None = None
        self.diag_from = 0
        self.results: dict[str, dict] = {}
        self.joins = 0

    def _latest_bridge(self) -> dict | None:
        for _, d, _, _ in reversed(self.mon.diagnostics):
            if "render_rate_hz" in d:
                return d
        return None

    def update(self, t_s: float, duration_s: float) -> None:
        phase = min(int(3 * t_s / duration_s), 2)
        if phase != self.phase:
            self._close_phase()
            self.phase = phase
            self.start_totals = self._latest_bridge()
            self.diag_from = len(self.mon.diagnostics)
            print(f"  soak phase: {PHASES[phase]} from t {t_s:.0f} s", flush=True)
            if phase == 2:
                self._throttle()
        if phase == 1 and t_s >= self.next_join:
            self.next_join = t_s + JOIN_EVERY_S
            self.readers.append((t_s, _JoiningReader()))
            self.joins += 1
        while self.readers and (t_s - self.readers[0][0] >= JOIN_HOLD_S or phase != 1):
            self.readers.pop(0)[1].close()

    def _throttle(self) -> None:
        from rclpy.parameter import Parameter
        from rclpy.parameter_client import AsyncParameterClient

        client = AsyncParameterClient(self.mon.node, self.node_name)
        client.wait_for_services(timeout_sec=10.0)
        fut = client.set_parameters([Parameter(k, value=v) for k, v in THROTTLE])
        t_end = time.monotonic() + 10.0
        while not fut.done() and time.monotonic() < t_end:
            time.sleep(0.05)
        res = fut.result() if fut.done() else None
        ok = res is not None and all(r.successful for r in res.results)
        print(
            f"  node throttled ({', '.join(f'{k}:={v}' for k, v in THROTTLE)}): {'applied' if ok else 'NOT applied'}", flush=True
        )

    def _close_phase(self) -> None:
        if self.phase < 0:
            return
        time.sleep(0.3)  # one more bridge diagnostics window
        end = self._latest_bridge() or {}
        start = self.start_totals or {}
        window = [d for _, d, _, _ in self.mon.diagnostics[self.diag_from :]]
        bridge = [d for d in window if "render_rate_hz" in d]
        node = [float(d["achieved_rate_hz"]) for d in window if d.get("achieved_rate_hz") not in (None, "nan")]

        def delta(key):
            return int(end.get(key, 0)) - int(start.get(key, 0))

        ages = [float(d["model_age_ms_max"]) for d in bridge if d["model_age_ms_max"] != "nan"]
        rates = [float(d["render_rate_hz"]) for d in bridge[1:] if d["render_rate_hz"] != "nan"]
        self.results[PHASES[self.phase]] = {
            "rendered": delta("rendered_total"),
            "from_fresh_model": delta("rendered_fresh_total"),
            "without_fresh_model": delta("rendered_no_model_total"),
            "stale_model": delta("rendered_stale_model_total"),
            "outside_radius": delta("rendered_outside_radius_total"),
            "device_pose_gaps_over_2ms": delta("device_gaps_2ms_total"),
            "models": delta("models_total"),
            "fades_ttl": delta("fades_ttl_total"),
            "fades_radius": delta("fades_radius_total"),
            "model_age_ms_max": max(ages) if ages else float("nan"),
            "render_rate_hz_min": min(rates) if rates else float("nan"),
            "render_rate_hz_median": float(np.median(rates)) if rates else float("nan"),
            "node_rate_hz_median": float(np.median(node)) if node else float("nan"),
            "readers_joined": self.joins if self.phase == 1 else 0,
        }

    def finish(self) -> None:
        while self.readers:
            self.readers.pop(0)[1].close()
        self._close_phase()
        self.phase = -1

    def summary(self) -> dict:
        return self.results


class _JoiningReader:
    """A new DDS participant (its own rclpy context) with a ``tool/wrench`` reader: what ``ros2 topic echo`` does.

    Parameters
    ----------
    topic : str or None
        The topic read (a hand's ``right/tool/wrench``); None: the contract's ``tool/wrench``.
    """

    def __init__(self, topic: str | None = None):
        import rclpy

        from msgs_schema.qos import subscription

        self.ctx = rclpy.Context()
        rclpy.init(context=self.ctx)
        self.node = rclpy.create_node(f"soak_joiner_{os.getpid()}_{time.monotonic_ns()}", context=self.ctx)
        subscription(self.node, "tool_wrench", lambda _m: None, name=topic)

    def close(self) -> None:
        import rclpy

        self.node.destroy_node()
        rclpy.try_shutdown(context=self.ctx)


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
        f"hypervisor steal during the run: {r['steal_ms']:.0f} ms (both vCPUs)",
        flush=True,
    )
    print(f"device side (bridge counters; device ticks {r['device_ticks']}, bridge rendered {r['bridge_rendered']}):")
    print(
        "  phase             | ticks rendered (bridge renders/s: median, min) | from a valid model | model older than "
        "TTL | outside radius | max model age ms | device pose gaps > 2 ms | node ticks/s median"
    )
    for name, p in r["device_phases"].items():
        print(
            f"  {name:17s} | {p['rendered']:8d} ({p['render_rate_hz_median']:6.1f}, {p['render_rate_hz_min']:6.1f})"
            f"                 | {p['from_fresh_model']:8d}           | {p['stale_model']:20d} | {p['outside_radius']:14d} | "
            f"{p['model_age_ms_max']:16.2f} | {p['device_pose_gaps_over_2ms']:23d} | {p['node_rate_hz_median']:7.1f}"
            + f"  (fades: {p['fades_ttl']} stale model, {p['fades_radius']} left radius)"
            + (f"  ({p['readers_joined']} readers joined)" if p["readers_joined"] else "")
        )
    checks = soak_checks(r)
    print(f"aims met: {r['aims_met']} (device: {r['device_aim_met']})")
    print(verdict_line("soak", checks) + (" (--no-check: exit 0)" if args.no_check else ""), flush=True)
    if args.json:
        args.json.write_text(json.dumps(r, indent=1))
    return 0 if args.no_check else exit_code(checks)


def soak_checks(r: dict) -> list[tuple[bool, str]]:
    """The soak's aims as ``(met, what)``: memory growth, force-stream gaps, and each phase at the device.

    ``r``: the figures of :func:`run_soak`. Each description says what was measured against what aim.
    """
    growth = r["node_rss_growth_pct"]
    gaps = r["stamp_gaps"]
    checks = [
        (growth <= RSS_GROWTH_LIMIT_PCT, f"node memory growth {growth:+.3f} % (aim <= {RSS_GROWTH_LIMIT_PCT} %)"),
        (
            gaps["gaps_over_limit"] == 0,
            f"{gaps['gaps_over_limit']} force-stream gaps over {GAP_LIMIT_MS} ms "
            f"(longest {gaps['max_gap_ms']:.2f} ms; aim: none)",
        ),
    ]
    for name, p in r["device_phases"].items():
        ok = p["stale_model"] == 0 and p["rendered"] > 0
        what = f"device, {name}: {p['stale_model']} of {p['rendered']} ticks rendered from a model older than its TTL"
        checks.append((ok, what + ("" if p["rendered"] else " (no tick rendered)") + " (aim: none, and some rendered)"))
    if not r["device_phases"]:
        checks.append((False, "device: no phase measured"))
    return checks


if __name__ == "__main__":
    raise SystemExit(main())
