"""``skin-sim bench``: skin_sim_node's latency, rate, jitter and start-up against bare rclpy baselines.

Every figure is printed as median, p99 and max next to a baseline measured in the same run,
each case in its own processes over DDS (the pose source and the observer live in this process):

- ``latency``: pose-to-force latency across processes. Baseline: ``skin-sim echo``, a bare
  rclpy node answering each pose with a zero wrench; then the node in ``input`` mode. Poses at
  1 kHz follow a 1 Hz press 0-3 mm deep, stamped at send; latency = wrench arrival - stamp,
  observed with reader depth 1 (as a device sees it).
- ``jitter``: force period at each ``--rates`` rate. Baseline: a bare rclpy timer publishing a
  wrench (``skin-sim echo --ticker-hz R``); then the node in ``timer`` mode at the same rate
  with the tool held 2 mm deep (poses at ``--pose-rate-hz``). Periods come from the wrench
  stamps (the publisher's clock at publish), recorded with a deep reader so observer stalls
  lose nothing. The first rate runs ``--duration-s`` (60 s: the missed-tick figure), the others
  ``--jitter-s``. Missed ticks = slots of the nominal grid that got no force sample
  (``sum(round(period / T) - 1)`` over the expected count); late = periods over 1.5 T.
- ``levers``: the node in ``timer`` mode at the first rate with each ``--lever`` parameter set.
- ``startup``: time from process start to the first force at the observer, the node with a
  cold numba cache (a fresh ``NUMBA_CACHE_DIR``) then warm (the same directory again).
  Baseline: the bare rclpy timer (no numba at all).
"""

from __future__ import annotations

import argparse
import json
import math
import os
import signal
import subprocess
import sys
import tempfile
import threading
import time
from pathlib import Path

import numpy as np

from skin_sim_node.bags.monitor import StreamObserver
from skin_sim_node.scenes import Scene, pick_domain_id

SECTIONS = ("floor", "tickcost", "latency", "jitter", "levers", "startup", "joinstall")
DEFAULT_SECTIONS = SECTIONS[:-1]  # joinstall is opt-in: its trials measure a rare event
LEVER_PRESETS = {
    # name: node parameters (NAME:=VALUE) on top of timer mode; "off" is the loop before issue 7
    "off": ("precise_sleep:=false",),
    "abs-sleep": ("precise_sleep:=true",),
    "spin-100us": ("precise_sleep:=true", "spin_tail_us:=100.0"),
    "affinity-cpu1": ("precise_sleep:=true", "haptic_cpu:=1"),
    "rt-haptic": ("precise_sleep:=true", "rt_priority:=80", "rt_scope:=haptic"),
    "rt-process": ("precise_sleep:=true", "rt_priority:=80", "rt_scope:=process"),
    "rt-process-cpu1": ("precise_sleep:=true", "rt_priority:=80", "rt_scope:=process", "haptic_cpu:=1"),
    "rt-process-spin": ("precise_sleep:=true", "rt_priority:=80", "rt_scope:=process", "spin_tail_us:=100.0"),
    # GIL switch interval of the node process (its --switch-interval-s; default 0.2 ms)
    "rt-process-switch50us": ("precise_sleep:=true", "rt_priority:=80", "rt_scope:=process", "switch_interval_s:=5e-5"),
    # no tool input at all (pose_rate_hz is the bench's, not a node parameter): what the pose callbacks cost the clock
    "off-no-poses": ("precise_sleep:=false", "pose_rate_hz:=0"),
}
SETTLE_S = 5.0
"""Seconds between the observer joining and the measurement. Measured (Fast DDS 2.14, the wheel): when a
participant joins, opening its shared-memory port froze the node's receive path for ~335 ms in 8 of 23
trials (eProsima/Fast-DDS#6535); skin-sim's processes use UDPv4 only (``ros_util.HAPTIC_TRANSPORTS``), but
under ``LOCALHOST`` discovery, which the scenes default to, rmw_fastrtps adds shared memory back. The figures
are steady state; docs/performance_rate.md reports the join stall."""
BENCH_ONLY = ("pose_rate_hz:=", "switch_interval_s:=")  # lever entries that are not node parameters
CASE_OVERHEAD_S = 8.0
"""Wall time of a case beyond its measured seconds and :data:`SETTLE_S`, for the estimates printed at
start: node start-up with a warm numba cache (2-4 s here), discovery, shutdown."""


class Progress:
    """Stage-by-stage progress of a long benchmark: a tqdm bar in estimated seconds and one line per stage.

    ``stage(name, est_s)`` opens a stage (a line with the elapsed and the estimated remaining time);
    the bar advances by each finished stage's estimate, so it reaches its total at the end.
    """

    def __init__(self, stages_est_s: list[float], desc: str):
        from tqdm import tqdm

        self.total = float(sum(stages_est_s))
        self.n = len(stages_est_s)
        self.i = 0
        self.t0 = time.monotonic()
        self._open = 0.0
        self.bar = tqdm(
            total=round(self.total),
            unit="s",
            desc=desc,
            mininterval=1.0,
            leave=False,
            bar_format="{desc}: {percentage:3.0f}%|{bar:20}| {n:.0f}/{total:.0f} s est. [{elapsed}]",
        )

    def stage(self, name: str, est_s: float) -> None:
        """Start stage ``name`` expected to take ``est_s``: print its line with the elapsed and remaining time."""
        self._close()
        self.i += 1
        self._open = est_s
        left = max(self.total - self.bar.n, 0.0)
        el = time.monotonic() - self.t0
        self.bar.write(f"[{self.i}/{self.n}, {el / 60:.1f} min elapsed, ~{left / 60:.1f} min left] {name} (~{est_s:.0f} s)")

    def _close(self) -> None:
        if self._open:
            self.bar.update(round(self._open))
            self._open = 0.0

    def close(self) -> None:
        """Finish the current stage and the bar."""
        self._close()
        self.bar.close()


def case_estimate_s(duration_s: float) -> float:
    """Estimated wall time of one :func:`run_case`."""
    return duration_s + SETTLE_S + CASE_OVERHEAD_S


def _pcts(a) -> tuple[float, float, float]:
    a = np.asarray(a, dtype=float)
    if a.size == 0:
        return (float("nan"),) * 3
    return float(np.percentile(a, 50)), float(np.percentile(a, 99)), float(a.max())


def period_stats(stamps_ns, rate_hz: float) -> dict:
    """Period figures of a force stream from its stamps (ns): median/p99/max period (ms),
    missed ticks (% of the nominal slots without a sample), late periods (> 1.5 T, %)."""
    s = np.sort(np.unique(np.asarray(stamps_ns, dtype=np.int64)))
    period_ns = 1e9 / rate_hz
    d = np.diff(s).astype(float)
    if d.size == 0:
        return {"period_ms": (float("nan"),) * 3, "missed_pct": float("nan"), "late_pct": float("nan"), "samples": int(s.size)}
    slots = np.maximum(np.rint(d / period_ns) - 1, 0)
    expected = d.sum() / period_ns
    return {
        "period_ms": _pcts(d * 1e-6),
        "missed_pct": float(100.0 * slots.sum() / expected),
        "late_pct": float(100.0 * np.mean(d > 1.5 * period_ns)),
        "samples": int(s.size),
        "achieved_hz": float((s.size - 1) / (d.sum() * 1e-9)),
    }


def cpu_steal_ms() -> float:
    """Hypervisor steal time so far, summed over CPUs (ms; /proc/stat, USER_HZ ticks). On a VM,
    time a vCPU was runnable but the host ran something else: no priority inside the guest helps."""
    try:
        with open("/proc/stat") as fh:
            fields = fh.readline().split()
        return float(fields[8]) * 1000.0 / os.sysconf("SC_CLK_TCK")
    except (OSError, IndexError, ValueError):
        return float("nan")


def diag_counts(diags: list[dict]) -> dict:
    """The node's own tick counts from its 1 Hz diagnostics (windows after the first, which began
    before the measurement): ticks, missed slots (% of ticks + missed), late periods (% of ticks)."""
    if len(diags) < 2:
        return {"node_windows": len(diags)}
    ticks = int(diags[-1]["ticks_total"]) - int(diags[0]["ticks_total"])
    rest = diags[1:]
    missed = sum(int(d.get("missed_slots_window", 0)) for d in rest)
    late = sum(int(d["late_ticks_window"]) for d in rest)
    return {
        "node_windows": len(rest),
        "node_ticks": ticks,
        "node_missed_pct": 100.0 * missed / max(ticks + missed, 1),
        "node_late_ticks": late,
        "node_late_pct": 100.0 * late / max(ticks, 1),
        "node_rate_hz": float(np.median([float(d["achieved_rate_hz"]) for d in rest])),
        "node_period_us_p99": float(np.median([float(d["period_us_p99"]) for d in rest])),
        "node_tick_us_p99": float(np.median([float(d["kernel_us_p99"]) for d in rest])),
    }


def start_case(scene: Scene, kind: str, rate_hz: float, node_args: tuple[str, ...] = ()):
    """Start the process(es) of one case in ``scene``; returns the process that publishes forces."""
    if kind == "echo":
        return scene.start("echo", "echo")
    if kind in ("timer", "ticker"):
        return scene.start(kind, "echo", "--ticker-hz", str(rate_hz), "--ticker-kind", "timer" if kind == "timer" else "thread")
    mode = "timer" if kind == "node-timer" else "input"
    return scene.node("-p", f"loop_mode:={mode}", "-p", f"rate_hz:={rate_hz}", *node_args)


def run_case(
    kind: str,
    duration_s: float,
    rate_hz: float,
    log_dir: Path,
    node_args: tuple[str, ...] = (),
    pose_rate_hz: float = 1000.0,
    settle_s: float | None = None,
    env: dict[str, str] | None = None,
    keep_stamps: bool = False,
) -> dict:
    """Run one case for ``duration_s`` measured seconds, from ``settle_s`` (default :data:`SETTLE_S`)
    after the observer joined; returns its figures (see the module doc), and with ``keep_stamps`` the wrench
    stamps they were computed from (``stamps_ns``) and the node's diagnostics (``diagnostics``)."""
    settle_s = SETTLE_S if settle_s is None else settle_s
    from geometry_msgs.msg import PoseStamped, TwistStamped

    from msgs_schema import convert as cv
    from skin_sim_node.ros_util import PeriodicLoop

    latency_case = kind in ("echo", "node")
    with Scene(log_dir) as scene:
        os.environ["ROS_DOMAIN_ID"] = scene.env["ROS_DOMAIN_ID"]
        os.environ["ROS_AUTOMATIC_DISCOVERY_RANGE"] = scene.env["ROS_AUTOMATIC_DISCOVERY_RANGE"]
        scene.env.update(env or {})  # the case's processes only (e.g. RMW_FASTRTPS_PUBLICATION_MODE)
        proc = start_case(scene, kind, rate_hz, node_args)
        scene.wait_for_log(proc, "live:", timeout_s=180)
        # latency: depth 1 (arrival as a device sees it); periods: deep, so observer stalls lose no stamp
        mon = StreamObserver(f"bench_{kind.replace('-', '_')}", record_depth=1 if latency_case else 1000)
        joined = time.monotonic()
        pose_pub, twist_pub = mon.publisher("tool_pose"), mon.publisher("tool_twist")
        pose, twist = PoseStamped(), TwistStamped()
        sent: list[int] = []
        hold = not latency_case
        t_start = [0]

        def tick(now_ns, _elapsed):
            t = (now_ns - t_start[0]) * 1e-9
            z = -2e-3 if hold else -1.5e-3 * (1 - math.cos(2 * math.pi * t))
            vz = 0.0 if hold else -1.5e-3 * 2 * math.pi * math.sin(2 * math.pi * t)
            stamp = mon.now_ns()
            twist_pub.publish(cv.fill_twist(twist, stamp, "tissue", (0.0, 0.0, vz)))  # twist first: see docs/ros.md
            pose_pub.publish(cv.fill_pose(pose, stamp, "tissue", (0.0, 0.0, z)))
            sent.append(stamp)

        if kind not in ("timer", "ticker") and (latency_case or pose_rate_hz > 0):
            end = time.monotonic() + 15
            while pose_pub.get_subscription_count() == 0 and time.monotonic() < end:
                time.sleep(0.05)
        source_hz = 1000.0 if latency_case else pose_rate_hz
        loop = PeriodicLoop(int(1e9 / max(source_hz, 1.0)), tick, name="bench-source")
        t_start[0] = time.perf_counter_ns()
        if source_hz > 0:
            loop.start()
        mon.wait_for(lambda: len(mon.wrench) > 10, 30, f"{kind} wrenches")
        time.sleep(max(0.0, joined + settle_s - time.monotonic()))  # see SETTLE_S
        mon.wrench.clear()
        mon.diagnostics.clear()
        sent.clear()
        steal0 = cpu_steal_ms()
        time.sleep(duration_s)
        steal_ms = cpu_steal_ms() - steal0
        loop.stop()
        time.sleep(0.2)
        records = list(mon.wrench)
        diags = [d for _, d, _, _ in mon.diagnostics]
        mon.close()
    out = {"case": kind, "rate_hz": rate_hz, "duration_s": duration_s, "node_args": list(node_args), "wrenches": len(records)}
    out["steal_ms"] = steal_ms
    if latency_case:
        sent_set = set(sent)
        lat = np.array([r - s for r, s, _ in records if s in sent_set], dtype=np.int64)
        out["answered_pct"] = 100.0 * lat.size / max(len(sent), 1)
        out["latency_ms"] = _pcts(lat * 1e-6)
    else:
        out.update(period_stats([s for _, s, _ in records], rate_hz))
    out.update(diag_counts(diags))
    if keep_stamps:
        out["stamps_ns"] = [s for _, s, _ in records]
        out["diagnostics"] = diags
    return out


def run_interleaved(cases: list[tuple], total_s: float, slot_s: float, log_dir: Path) -> list[dict]:
    """Latency of several cases under the same machine load: all run at once, each in its own DDS domain,
    and one 1 kHz pose source feeds them in turn, ``slot_s`` each, for ``total_s`` each in all.

    ``cases``: ``(label, node args, node environment[, companions])`` (see :func:`latency_variant`); label
    ``echo`` is the bare rclpy echo. The first
    100 ms of each slot are not counted (the process resumes after a pause; the node's watchdog has
    released the tissue). Figures as :func:`run_case`'s latency case, plus ``slots``.
    """
    from contextlib import ExitStack

    from geometry_msgs.msg import PoseStamped, TwistStamped

    from msgs_schema import convert as cv
    from skin_sim_node.ros_util import PeriodicLoop

    skip_ns = 100_000_000
    with ExitStack() as stack:
        targets = []
        domains: set[int] = set()
        for label, args, env, *more in cases:
            while (domain := pick_domain_id()) in domains:  # one domain each: a shared one would cross-answer poses
                pass
            domains.add(domain)
            scene = stack.enter_context(Scene(log_dir / label, domain_id=domain))
            scene.env.update(env)
            proc = scene.start("echo", "echo") if label == "echo" else scene.node(*args)
            for name in more[0] if more else ():
                scene.start(name, *COMPANIONS[name])
            targets.append((label, scene, proc))
        for _, scene, proc in targets:
            scene.wait_for_log(proc, "live:", timeout_s=180)
        state = []
        for label, scene, _ in targets:
            os.environ["ROS_DOMAIN_ID"] = scene.env["ROS_DOMAIN_ID"]  # the observer's context joins this domain
            os.environ["ROS_AUTOMATIC_DISCOVERY_RANGE"] = scene.env["ROS_AUTOMATIC_DISCOVERY_RANGE"]
            mon = StreamObserver(f"bench_ab_{len(state)}", record_depth=1)
            stack.callback(mon.close)
            state.append(
                {
                    "label": label,
                    "mon": mon,
                    "pose": mon.publisher("tool_pose"),
                    "twist": mon.publisher("tool_twist"),
                    "sent": [],
                    "counted": set(),
                }
            )
        for st in state:
            end = time.monotonic() + 15
            while st["pose"].get_subscription_count() == 0 and time.monotonic() < end:
                time.sleep(0.05)
        pose, twist = PoseStamped(), TwistStamped()
        active = [0]
        slot_start = [0]
        t0 = time.perf_counter_ns()

        def tick(now_ns, _elapsed):
            t = (now_ns - t0) * 1e-9
            z = -1.5e-3 * (1 - math.cos(2 * math.pi * t))
            vz = -1.5e-3 * 2 * math.pi * math.sin(2 * math.pi * t)
            st = state[active[0]]
            stamp = st["mon"].now_ns()
            st["twist"].publish(cv.fill_twist(twist, stamp, "tissue", (0.0, 0.0, vz)))
            st["pose"].publish(cv.fill_pose(pose, stamp, "tissue", (0.0, 0.0, z)))
            if now_ns - slot_start[0] >= skip_ns:
                st["counted"].add(stamp)

        loop = PeriodicLoop(1_000_000, tick, name="bench-source")
        loop.start()
        time.sleep(SETTLE_S)  # every observer's join stall passes (see SETTLE_S); nothing counted yet
        for st in state:
            st["counted"].clear()
            st["mon"].wrench.clear()
        steal0 = cpu_steal_ms()
        n_slots = max(1, round(total_s / slot_s))
        for _ in range(n_slots):
            for i in range(len(state)):
                active[0], slot_start[0] = i, time.perf_counter_ns()
                time.sleep(slot_s)
        loop.stop()
        time.sleep(0.2)
        steal_ms = cpu_steal_ms() - steal0
        out = []
        for st in state:
            counted = st["counted"]
            lat = np.array([r - s for r, s, _ in list(st["mon"].wrench) if s in counted], dtype=np.int64)
            out.append(
                {
                    "case": "echo" if st["label"] == "echo" else "node",
                    "label": st["label"],
                    "slots": n_slots,
                    "answered_pct": 100.0 * lat.size / max(len(counted), 1),
                    "latency_ms": _pcts(lat * 1e-6),
                    "steal_ms": steal_ms,
                    "duration_s": n_slots * slot_s,
                }
            )
    return out


def run_startup(kind: str, log_dir: Path, cache_dir: Path | None, rate_hz: float = 1000.0) -> dict:
    """Seconds from starting the process to the first wrench at the observer (and the node's numba warm-up)."""
    from skin_sim_node.bags.monitor import Monitor

    with Scene(log_dir) as scene:
        os.environ["ROS_DOMAIN_ID"] = scene.env["ROS_DOMAIN_ID"]
        os.environ["ROS_AUTOMATIC_DISCOVERY_RANGE"] = scene.env["ROS_AUTOMATIC_DISCOVERY_RANGE"]
        if cache_dir is not None:
            scene.env["NUMBA_CACHE_DIR"] = str(cache_dir)
        mon = Monitor(name=f"bench_start_{kind.replace('-', '_')}", images=False)
        try:
            t0 = time.monotonic()
            proc = start_case(scene, kind, rate_hz)
            mon.wait_for(lambda: len(mon.wrench) > 0, 300, f"{kind} first force")
            first_s = time.monotonic() - t0
            scene.wait_for_log(proc, "live:", timeout_s=60)
        finally:
            mon.close()
        log = proc.log()
    out = {"case": kind, "first_force_s": first_s}
    if "numba warm-up" in log:
        out["numba_warmup_s"] = float(log.split("numba warm-up ")[1].split(" s")[0])
    return out


def tick_cost(n: int = 5000) -> dict:
    """In-process cost (us, p50/p99/max) of each step of the node's pose-to-force path, one thread, no load.

    Shows how long each tick holds the GIL: everything except the numba model step (``nogil``).
    A 1 Hz press 0-3 mm deep at 1 kHz stamps; publishers on an rclpy node with no subscriber. The pose is read
    and the wrench written serialized, as the node does; the contact message is timed although the node
    publishes it only while it has a reader.
    """
    import rclpy
    from geometry_msgs.msg import PoseStamped
    from rclpy.serialization import serialize_message
    from sensor_msgs.msg import JointState

    from msgs_schema import convert as cv
    from msgs_schema.qos import publisher
    from skin_sim_node.model import preset
    from skin_sim_node.session import HapticSession, SessionParams
    from skin_sim_node.tools import make_tool, warm_up

    cfg = preset("default")
    warm_up(cfg)
    tool = make_tool(cfg)
    model = tool.tissue  # its step is wrapped below to time the nogil kernel alone
    ctx = rclpy.Context()
    rclpy.init(context=ctx)
    node = rclpy.create_node("bench_tick_cost", context=ctx)
    pub_w, pub_c = publisher(node, "tool_wrench"), publisher(node, "contact")
    pose, wrench_cdr, contact = PoseStamped(), cv.WrenchCdr("tissue"), JointState()
    keys = (
        "read_pose (CDR)",
        "on_pose",
        "tick (session + model)",
        "model step (nogil)",
        "publish wrench (CDR)",
        "publish contact (only while read)",
    )
    t = {k: np.zeros(n) for k in keys}
    step = model.step
    step_ns = [0]

    def timed_step(*a, **k):
        t0 = time.perf_counter_ns()
        r = step(*a, **k)
        step_ns[0] = time.perf_counter_ns() - t0
        return r

    model.step = timed_step
    session = HapticSession(tool, SessionParams(max_stamp_age_s=0.0))
    clock = time.perf_counter_ns
    base = time.time_ns()
    try:
        for i in range(n):
            stamp = base + i * 1_000_000
            z = -1.5e-3 * (1 - math.cos(2 * math.pi * i / 1000))
            data = serialize_message(cv.fill_pose(pose, stamp, "tissue", (0.0, 0.0, z)))  # as the node receives it
            t0 = clock()
            st, frame, xyz = cv.read_stamped_vec3_cdr(data)
            t1 = clock()
            session.on_pose(st, frame, xyz, now_ns=stamp, rx_ns=t1)
            t2 = clock()
            r = session.tick(t2, 1_000_000)
            t3 = clock()
            pub_w.publish(wrench_cdr.fill_from_tick(r, st))
            t4 = clock()
            pub_c.publish(cv.fill_contact_from_tick(contact, r, st, "tissue"))
            t5 = clock()
            for k, dt in zip(keys, (t1 - t0, t2 - t1, t3 - t2, step_ns[0], t4 - t3, t5 - t4)):
                t[k][i] = dt * 1e-3
    finally:
        node.destroy_node()
        rclpy.try_shutdown(context=ctx)
    warm = n // 10
    return {k: _pcts(v[warm:]) for k, v in t.items()}


JOIN_TRANSPORTS = ("DEFAULT", "UDPv4")
"""``FASTDDS_BUILTIN_TRANSPORTS`` of the node and observer A in the join trials: Fast DDS's default (shared memory
and UDPv4) against skin-sim's default (:data:`skin_sim_node.ros_util.HAPTIC_TRANSPORTS`). The joiner keeps the
default, as ``ros2 topic echo`` would. Under ``LOCALHOST`` discovery rmw_fastrtps sets its own transports and
both rows run the same: run with ``ROS_AUTOMATIC_DISCOVERY_RANGE=SUBNET``."""
JOINER = """
import rclpy
from msgs_schema.qos import subscription
rclpy.init()
node = rclpy.create_node("bench_join_b")
n = [0]
subscription(node, "tool_wrench", lambda m: n.__setitem__(0, n[0] + 1))
try:
    rclpy.spin(node)
except (KeyboardInterrupt, rclpy.executors.ExternalShutdownException):
    pass
print(n[0], flush=True)
"""
JOIN_TRIAL_EST_S = 25.0
JOIN_WATCH_S = 6.0
"""Seconds watched after a reader joins: the stall came 2-3 s after the join (see :data:`SETTLE_S`)."""


def join_stall(transports: str, log_dir: Path, node_args: tuple[str, ...] = (), before_s: float = 4.0) -> dict:
    """The joining-reader stall with ``FASTDDS_BUILTIN_TRANSPORTS=transports`` for the node and observer A.

    The node answers 1 kHz poses (input mode, defaults, display on) to observer A; after ``before_s`` a
    second reader of ``tool/wrench`` joins (its own rclpy context). Figures: the longest gap between
    wrench arrivals at A in the ``before_s`` before the join and in the :data:`JOIN_WATCH_S` after it,
    and the poses answered in each window.
    """
    from geometry_msgs.msg import PoseStamped, TwistStamped

    from msgs_schema import convert as cv
    from skin_sim_node.ros_util import PeriodicLoop

    with Scene(log_dir) as scene:
        os.environ["ROS_DOMAIN_ID"] = scene.env["ROS_DOMAIN_ID"]
        os.environ["ROS_AUTOMATIC_DISCOVERY_RANGE"] = scene.env["ROS_AUTOMATIC_DISCOVERY_RANGE"]
        joiner_env = dict(scene.env)
        joiner_env.pop("FASTDDS_BUILTIN_TRANSPORTS", None)  # the joiner keeps Fast DDS's default, as ros2 topic echo
        scene.env["FASTDDS_BUILTIN_TRANSPORTS"] = transports
        proc = scene.node(*node_args)
        scene.wait_for_log(proc, "live:", timeout_s=180)
        own = os.environ.get("FASTDDS_BUILTIN_TRANSPORTS")
        os.environ["FASTDDS_BUILTIN_TRANSPORTS"] = transports  # observer A's participant is created now
        try:
            mon = StreamObserver("bench_join_a", record_depth=1)
        finally:
            if own is None:
                os.environ.pop("FASTDDS_BUILTIN_TRANSPORTS")
            else:
                os.environ["FASTDDS_BUILTIN_TRANSPORTS"] = own
        pose_pub, twist_pub = mon.publisher("tool_pose"), mon.publisher("tool_twist")
        pose, twist = PoseStamped(), TwistStamped()
        sent: list[int] = []

        def tick(_now_ns, _elapsed):
            stamp = mon.now_ns()
            twist_pub.publish(cv.fill_twist(twist, stamp, "tissue", (0.0, 0.0, 0.0)))
            pose_pub.publish(cv.fill_pose(pose, stamp, "tissue", (0.0, 0.0, -1.0e-3)))
            sent.append(stamp)

        end = time.monotonic() + 15
        while pose_pub.get_subscription_count() == 0 and time.monotonic() < end:
            time.sleep(0.05)
        loop = PeriodicLoop(1_000_000, tick, name="bench-source")
        loop.start()
        mon.wait_for(lambda: len(mon.wrench) > 10, 30, "wrenches")
        time.sleep(SETTLE_S)  # A's own join stall, if any, passes first
        t_before = mon.now_ns()
        time.sleep(before_s)
        t_join = mon.now_ns()
        # the joining reader is a process of its own, so its start-up takes no GIL from observer A
        joiner = subprocess.Popen([sys.executable, "-c", JOINER], env=joiner_env, stdout=subprocess.PIPE, text=True)
        time.sleep(JOIN_WATCH_S)
        t_end = mon.now_ns()
        loop.stop()
        joiner.send_signal(signal.SIGINT)
        out, _ = joiner.communicate(timeout=10)
        joined_got = int(out.split()[-1]) if out.split() else 0
        records = list(mon.wrench)
        mon.close()

    def window(t0, t1):
        rx = np.array([r for r, _, _ in records if t0 <= r < t1], dtype=np.int64)
        got = {s for r, s, _ in records if t0 <= r < t1}
        n_sent = sum(1 for s in sent if t0 <= s < t1 - 20_000_000)
        gap = float(np.diff(np.r_[t0, rx, t1]).max() * 1e-6) if rx.size else (t1 - t0) * 1e-6
        return gap, 100.0 * len(got & set(sent)) / max(n_sent, 1)

    gap_b, ans_b = window(t_before, t_join)
    gap_a, ans_a = window(t_join, t_end)
    return {
        "transports": transports,
        "max_gap_before_ms": gap_b,
        "max_gap_after_ms": gap_a,
        "answered_before_pct": ans_b,
        "answered_after_pct": ans_a,
        "joiner_wrenches": joined_got,
    }


def print_join_stall(rows: list[dict]) -> None:
    """Print the joining-reader stall rows: the longest wrench gap before and after a second reader joins."""
    print(
        f"\njoining-reader stall: a second tool/wrench reader joins; longest gap between wrench arrivals at the first "
        f"reader, ms, {JOIN_WATCH_S:.0f} s after the join vs the seconds before it (answered %)"
    )
    if os.environ.get("ROS_AUTOMATIC_DISCOVERY_RANGE", "LOCALHOST") == "LOCALHOST":
        print("  note: LOCALHOST discovery: rmw_fastrtps sets its own transports, so both rows ran with shared memory")
    for r in rows:
        print(
            f"  {r['transports']:>12}: before {r['max_gap_before_ms']:7.1f} ({r['answered_before_pct']:5.1f} %) | after join "
            f"{r['max_gap_after_ms']:7.1f} ({r['answered_after_pct']:5.1f} %) | joiner got {r['joiner_wrenches']}"
        )
    for mode in JOIN_TRANSPORTS:
        g = [r["max_gap_after_ms"] for r in rows if r["transports"] == mode]
        if g:
            print(
                f"  {mode:>12}: after-join max gap median {np.median(g):.1f} ms, worst {max(g):.1f} ms, "
                f"trials over 100 ms {sum(x > 100 for x in g)}/{len(g)}"
            )


def wake_floor(rt_priority: int, duration_s: float, rate_hz: float = 1000.0) -> dict:
    """The platform's floor: a bare Python thread (no ROS, no other thread) sleeping to each
    deadline with :func:`ros_util.sleep_until_ns`; wake latency = wake - deadline (us), and the
    share of wakes later than half a period (what would make a 1.5 T period)."""
    from skin_sim_node.ros_util import set_realtime, sleep_until_ns

    out: dict = {}

    def run():
        if rt_priority > 0:
            out["problem"] = set_realtime(rt_priority)
        period = int(1e9 / rate_hz)
        n = int(duration_s * rate_hz)
        lat = np.zeros(n)
        clock = time.perf_counter_ns
        nxt = clock() + period
        for i in range(n):
            while clock() < nxt:
                sleep_until_ns(nxt)
            lat[i] = (clock() - nxt) * 1e-3
            nxt += period
        out["wake_us"] = _pcts(lat)
        out["over_half_period_pct"] = float(100.0 * np.mean(lat > 0.5e6 / rate_hz))

    t = threading.Thread(target=run, name="wake-floor")
    t.start()
    t.join()
    return out


def _fmt3(p) -> str:
    return f"{p[0]:7.3f} {p[1]:7.3f} {p[2]:7.2f}"


def _ratio(a, b) -> str:
    return f"{a[0] / b[0]:.2f}x / {a[1] / b[1]:.2f}x / {a[2] / b[2]:.2f}x"


COMPANIONS = {"view": ("view", "--port", "0")}
"""Processes a latency case may start beside its node (``with.NAME``): ``view`` is ``skin-sim view`` with no page
open; it reads ``tissue/layer_heights`` (so the display worker builds the grid at display rate), ``tissue/contact``,
``tool/pose``, ``tool/wrench`` and the diagnostics. No reader of ``tissue/height_map`` or the mesh."""


def latency_variant(spec: str, node_args: tuple[str, ...]) -> tuple[str, tuple[str, ...], dict[str, str], tuple[str, ...]]:
    """``NAME=P:=V,env.VAR:=VALUE,with.view,...`` -> (name, node arguments, node environment, companions)."""
    name, _, params = spec.partition("=")
    items = [p for p in params.split(",") if p]
    env = dict(p[4:].split(":=", 1) for p in items if p.startswith("env."))
    companions = tuple(p[5:] for p in items if p.startswith("with."))
    unknown = [c for c in companions if c not in COMPANIONS]
    if unknown:
        raise SystemExit(f"latency variant {name}: unknown with.{unknown[0]} (choose {', '.join(COMPANIONS)})")
    args = tuple(a for p in items if not p.startswith(("env.", "with.")) for a in ("-p", p))
    return name, node_args + args, env, companions


def print_latency(echo: dict, nodes: list[dict]) -> None:
    """Print pose-to-force latency (p50, p99, max) of the echo baseline and each node case, with ratios to the echo."""
    print("\npose-to-force latency across processes, ms (p50 p99 max); answered = wrenches / poses sent")
    for r in (echo, *nodes):
        line = f"  {r.get('label', r['case']):>16}: {_fmt3(r['latency_ms'])} | answered {r['answered_pct']:5.1f} %"
        line += f" | steal {r['steal_ms']:.0f} ms"
        if r is not echo:
            line += f" | ratio to echo (p50 / p99 / max) {_ratio(r['latency_ms'], echo['latency_ms'])}"
        print(line)


def print_periods(title: str, pairs: list[tuple[dict, dict]]) -> None:
    """Print the force periods seen by the observer for each (baseline, node) pair: p50, p99, max, missed and late."""
    print(
        f"\n{title}: force period from the stamps seen by the observer (p50 p99 max, ms); missed = empty slots, "
        "late = periods > 1.5 T; the node's own count covers its ticks only (no transport)"
    )
    shown = set()
    for base, node in pairs:
        for r in (base, node):
            if id(r) in shown:
                continue
            shown.add(id(r))
            label = r.get("label", r["case"])
            line = (
                f"  {r['rate_hz']:6.0f} Hz {r['duration_s']:4.0f} s {label:>16}: {_fmt3(r['period_ms'])} | "
                f"missed {r['missed_pct']:6.3f} % late {r['late_pct']:6.3f} % | {r['samples']} samples, "
                f"steal {r['steal_ms']:.0f} ms"
            )
            if "node_ticks" in r:
                line += (
                    f" | node's own count: missed {r['node_missed_pct']:.3f} % late {r['node_late_pct']:.3f} %, "
                    f"tick p99 {r['node_tick_us_p99']:.0f} us"
                )
            print(line)
        print(
            f"  {'':>14} ratio {node.get('label', node['case'])}/{base['case']} p99 period: "
            f"{node['period_ms'][1] / base['period_ms'][1]:.2f}x"
        )


def main(argv=None) -> int:
    """``skin-sim bench``: the node benchmark sections (tick cost, latency, rates, start-up, join stall) against bare rclpy."""
    ap = argparse.ArgumentParser(
        prog="skin-sim bench",
        description=__doc__.splitlines()[0],
        epilog="Duration: about 14 min with the defaults (all sections; ~1.5 min per latency case pair with "
        "--latency-s 30); the estimate for the chosen sections is printed at start, then one line per case. "
        "Short: --sections tickcost,latency --latency-s 15 (~1.5 min).",
    )
    ap.add_argument(
        "--sections",
        default=",".join(DEFAULT_SECTIONS),
        help=f"comma list of {', '.join(SECTIONS)} (default all but joinstall)",
    )
    ap.add_argument(
        "--interleave-s",
        type=float,
        default=0.0,
        help="latency: run echo and node cases at once and switch the pose stream between them every this many "
        "seconds (the same machine load for all; 0: one case after the other)",
    )
    ap.add_argument(
        "--join-trials",
        type=int,
        default=4,
        help="joinstall: trials per transport setting (~25 s each; run with ROS_AUTOMATIC_DISCOVERY_RANGE=SUBNET)",
    )
    ap.add_argument("--duration-s", type=float, default=60.0, help="seconds of the first-rate jitter case (missed ticks)")
    ap.add_argument("--jitter-s", type=float, default=20.0, help="seconds of the other rates' jitter cases")
    ap.add_argument("--latency-s", type=float, default=30.0, help="seconds of each latency case")
    ap.add_argument("--floor-s", type=float, default=10.0, help="seconds of each platform-floor case")
    ap.add_argument("--lever-s", type=float, default=20.0, help="seconds of each lever case")
    ap.add_argument("--rates", default="1000,2000,4000", help="force rates of the jitter cases (Hz)")
    ap.add_argument("--lever-rate-hz", type=float, default=None, help="force rate of the lever cases (default: the first rate)")
    ap.add_argument("--pose-rate-hz", type=float, default=1000.0, help="held-pose rate fed to timer-mode cases")
    ap.add_argument("--node-param", action="append", default=[], help="node parameter NAME:=VALUE for all node cases")
    ap.add_argument(
        "--lever",
        action="append",
        default=[],
        help=f"levers case NAME or NAME=P:=V,P:=V (repeatable; presets: {', '.join(LEVER_PRESETS)}; default all presets)",
    )
    ap.add_argument(
        "--latency-variant",
        action="append",
        default=[],
        help="latency node case NAME=P:=V,P:=V (repeatable; default one case 'node' with --node-param only); "
        "an item env.VAR:=VALUE sets the node's environment, e.g. env.RMW_FASTRTPS_PUBLICATION_MODE:=ASYNCHRONOUS; "
        "with.view also runs skin-sim view on that node (a display reader)",
    )
    ap.add_argument(
        "--observer-rt",
        type=int,
        default=0,
        help="SCHED_FIFO priority of this process (pose source and observer, as a device's servo loop would run); "
        "0: normal. The processes it starts run normally (SCHED_RESET_ON_FORK)",
    )
    ap.add_argument("--json", type=Path, help="also write all figures to this JSON file")
    args = ap.parse_args(argv)
    if args.observer_rt > 0:  # before any thread or DDS participant exists: they all inherit it
        from skin_sim_node.ros_util import set_process_realtime

        problem = set_process_realtime(args.observer_rt)
        print(f"observer: {problem or f'SCHED_FIFO {args.observer_rt}'}", flush=True)
    sections = [s for s in args.sections.split(",") if s]
    rates = [float(r) for r in args.rates.split(",")]
    node_args = tuple(a for p in args.node_param for a in ("-p", p))
    log_dir = Path(tempfile.mkdtemp(prefix="skin_sim_bench_"))
    levers = args.lever or list(LEVER_PRESETS)
    variants = args.latency_variant or ["node="]
    est = {
        "tickcost": [10.0],
        "floor": [args.floor_s] * 2,
        "latency": [case_estimate_s((1 + len(variants)) * args.latency_s)]
        if args.interleave_s > 0
        else [case_estimate_s(args.latency_s)] * (1 + len(variants)),
        "jitter": [case_estimate_s(args.duration_s if i == 0 else args.jitter_s) for i in range(len(rates)) for _ in (0, 1)],
        "levers": [case_estimate_s(args.lever_s)] * (1 + len(levers)),
        "startup": [10.0, 60.0, 15.0],  # bare timer; node with a cold numba cache (compiles), then warm
        "joinstall": [JOIN_TRIAL_EST_S] * (2 * args.join_trials),
    }
    plan = [e for sec in sections for e in est.get(sec, [])]
    print(
        f"skin-sim bench: sections {','.join(sections)}; {len(plan)} stages, about {sum(plan) / 60:.1f} min; "
        f"{os.cpu_count()} cores, load {os.getloadavg()[0]:.2f}; node params {list(args.node_param)}; logs {log_dir}",
        flush=True,
    )
    progress = Progress(plan, "skin-sim bench")
    try:
        results = _run_sections(args, sections, rates, node_args, log_dir, levers, variants, est, progress)
    finally:
        progress.close()
    if args.json:
        args.json.write_text(json.dumps(results, indent=1))
    return 0


def _run_sections(args, sections, rates, node_args, log_dir, levers, variants, est, progress: Progress) -> dict:
    results: dict = {}
    if "tickcost" in sections:
        progress.stage("tick cost in one thread", est["tickcost"][0])
        cost = tick_cost()
        results["tickcost"] = cost
        print("\nper-tick cost of the pose-to-force path in one thread, us (p50 p99 max); all but the model step hold the GIL")
        for k, v in cost.items():
            print(f"  {k:>33}: {v[0]:7.1f} {v[1]:7.1f} {v[2]:8.1f}")
    if "floor" in sections:
        rows = {}
        for prio in (0, 80):
            progress.stage(f"platform floor, {'SCHED_FIFO 80' if prio else 'normal'}", args.floor_s)
            rows[prio] = wake_floor(prio, args.floor_s)
        results["floor"] = rows
        print(f"\nplatform floor: a bare Python thread sleeping to 1 kHz deadlines, {args.floor_s:.0f} s; wake latency, us")
        for prio, r in rows.items():
            w = r["wake_us"]
            name = f"SCHED_FIFO {prio}" if prio else "normal"
            note = f" ({r['problem']})" if r.get("problem") else ""
            late = r["over_half_period_pct"]
            print(f"  {name:>14}: p50 {w[0]:6.0f} p99 {w[1]:6.0f} max {w[2]:7.0f} | later than T/2: {late:.3f} %{note}")
    if "latency" in sections and args.interleave_s > 0:
        progress.stage(
            f"latency, interleaved {args.interleave_s:g} s slots: echo and {len(variants)} node case(s)", est["latency"][0]
        )
        cases = [("echo", (), {}, ()), *(latency_variant(spec, node_args) for spec in variants)]
        rows = run_interleaved(cases, args.latency_s, args.interleave_s, log_dir / "latency_interleaved")
        results["latency"] = rows
        print(
            f"\n(interleaved: all cases running, one pose stream switched between them every {args.interleave_s:g} s, "
            f"{args.latency_s:g} s each in all)"
        )
        print_latency(rows[0], rows[1:])
    elif "latency" in sections:
        progress.stage("latency: bare rclpy echo", est["latency"][0])
        echo = run_case("echo", args.latency_s, 1000.0, log_dir / "latency_echo")
        nodes = []
        for spec in variants:
            name, _, params = spec.partition("=")
            progress.stage(f"latency: {name}", est["latency"][0])
            _, extra, env, companions = latency_variant(spec, node_args)
            if companions:
                raise SystemExit("with.NAME needs the interleaved latency case (--interleave-s > 0)")
            nodes.append(run_case("node", args.latency_s, 1000.0, log_dir / f"latency_{name}", extra, env=env))
            nodes[-1]["label"] = name
        results["latency"] = [echo, *nodes]
        print_latency(echo, nodes)
    if "jitter" in sections:
        pairs = []
        for i, rate in enumerate(rates):
            dur = args.duration_s if i == 0 else args.jitter_s
            progress.stage(f"jitter {rate:.0f} Hz: bare rclpy timer", case_estimate_s(dur))
            base = run_case("timer", dur, rate, log_dir / f"jitter_timer_{rate:.0f}")
            progress.stage(f"jitter {rate:.0f} Hz: node in timer mode", case_estimate_s(dur))
            node = run_case("node-timer", dur, rate, log_dir / f"jitter_node_{rate:.0f}", node_args, args.pose_rate_hz)
            pairs.append((base, node))
        results["jitter"] = pairs
        print_periods("force period jitter (bare rclpy timer vs node in timer mode)", pairs)
    if "levers" in sections:
        rate = args.lever_rate_hz or rates[0]
        progress.stage("levers: bare rclpy timer", est["levers"][0])
        base = run_case("timer", args.lever_s, rate, log_dir / "levers_timer")
        pairs = []
        for spec in levers:
            name, _, params = spec.partition("=")
            progress.stage(f"levers: {name}", est["levers"][0])
            plist = tuple(p for p in params.split(",") if p) if params else LEVER_PRESETS[name]
            pose_rate = next((float(p.split(":=")[1]) for p in plist if p.startswith("pose_rate_hz:=")), args.pose_rate_hz)
            extra = node_args + tuple(a for p in plist if not p.startswith(BENCH_ONLY) for a in ("-p", p))
            extra += tuple(a for p in plist if p.startswith("switch_interval_s:=") for a in ("--switch-interval-s", p[19:]))
            r = run_case("node-timer", args.lever_s, rate, log_dir / f"lever_{name}", extra, pose_rate)
            r["label"] = name
            pairs.append((base, r))
        results["levers"] = pairs
        print_periods("levers (node in timer mode; same-run bare rclpy timer)", pairs)
    if "startup" in sections:
        cache = Path(tempfile.mkdtemp(prefix="skin_sim_numba_cache_"))
        rows = []
        for (kind, name, c), e in zip(
            (("timer", "timer", None), ("node-timer", "cold", cache), ("node-timer", "warm", cache)), est["startup"]
        ):
            progress.stage(f"start-up: {'bare rclpy timer' if kind == 'timer' else f'node, {name} numba cache'}", e)
            rows.append(run_startup(kind, log_dir / f"start_{name}", c))
        rows[1]["label"], rows[2]["label"] = "node cold cache", "node warm cache"
        results["startup"] = rows
        print("\nstart to first force at the observer, s (fresh NUMBA_CACHE_DIR, then the same again)")
        for r in rows:
            warm = f" (numba warm-up in the node {r['numba_warmup_s']:.2f} s)" if "numba_warmup_s" in r else ""
            print(f"  {r.get('label', 'bare rclpy timer'):>16}: {r['first_force_s']:6.2f}{warm}")
    if "joinstall" in sections:
        rows = []
        for trial in range(args.join_trials):
            for mode in JOIN_TRANSPORTS:  # interleaved: the same machine load for both
                progress.stage(f"join stall: trial {trial + 1}/{args.join_trials}, Fast DDS transports {mode}", JOIN_TRIAL_EST_S)
                rows.append(join_stall(mode, log_dir / f"join_{mode}_{trial}", node_args))
        results["joinstall"] = rows
        print_join_stall(rows)
    return results


if __name__ == "__main__":
    raise SystemExit(main())
