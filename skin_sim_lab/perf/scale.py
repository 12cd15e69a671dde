"""``skin-sim scale``: how many 1 kHz tissue sessions this machine holds side by side.

Session ``i`` is skin_sim_node + device bridge + simulated Touch (looping the ``drag`` hand
path), all under the ROS namespace ``/s<i>`` in one DDS domain: three processes, each with a
1 kHz loop. Sessions are added one at a time; after each addition every running session is
measured for ``--step-s`` seconds from its node's own diagnostics (cheap: 1 Hz per session, so
the observer does not load the machine it measures): missed ticks = empty 1/rate slots
between the node's ticks (``missed_slots_window``) over the expected tick count, late = tick
periods over 1.5 T. The machine "holds" n sessions while every session misses < 0.1 % (issue 7).
It ends with one line, ``scale PASS: ...`` or ``scale FAIL: ...``, naming each step and the sessions
over the limit; exit 1 unless all ``--max-sessions`` were held.
"""

from __future__ import annotations

import argparse
import json
import os
import tempfile
import threading
import time
from pathlib import Path

from skin_sim_node.scenes import DEFAULT_PARAMS, Scene
from skin_sim_node.verdicts import exit_code, verdict_line

from .bench_node import CASE_OVERHEAD_S, SETTLE_S, Progress, cpu_steal_ms, diag_counts

MISSED_LIMIT_PCT = 0.1  # issue 7
nan = float("nan")


class DiagObserver:
    """Collects the haptic-loop diagnostics of the nodes under the given namespaces."""

    def __init__(self):
        import rclpy

        from skin_sim_node.ros_util import make_executor, spin_context

        self.context = rclpy.Context()
        rclpy.init(context=self.context)
        self.node = rclpy.create_node("scale_observer", context=self.context)
        self.records: dict[str, list[dict]] = {}
        self._lock = threading.Lock()
        self._executor = make_executor("events", self.context)
        self._executor.add_node(self.node)
        self._stop = threading.Event()
        self._thread = threading.Thread(target=spin_context, args=(self._executor, self.context, self._stop), daemon=True)
        self._thread.start()

    def watch(self, ns: str) -> None:
        from msgs_schema.qos import subscription

        self.records[ns] = []

        def cb(msg, ns=ns):
            for st in msg.status:
                if "haptic loop" in st.name:
                    with self._lock:
                        self.records[ns].append({kv.key: kv.value for kv in st.values})

        subscription(self.node, "diagnostics", cb, name=f"{ns}/diagnostics")

    def clear(self) -> None:
        with self._lock:
            for v in self.records.values():
                v.clear()

    def summary(self, ns: str) -> dict:
        with self._lock:
            recs = list(self.records[ns])
        return diag_counts(recs)

    def close(self) -> None:
        import rclpy

        self._stop.set()
        self._thread.join(timeout=2.0)
        self.node.destroy_node()
        rclpy.try_shutdown(context=self.context)


class WaitingProgress(Progress):
    """:class:`~skin_sim_lab.perf.bench_node.Progress` whose bar moves once a second within a stage (up to the
    stage's estimate), also while a session's processes start: the stage line alone left it at 0 % for 37 s."""

    def __init__(self, stages_est_s: list[float], desc: str):
        super().__init__(stages_est_s, desc)
        self._lock = threading.Lock()
        self._done = threading.Event()
        threading.Thread(target=self._tick, daemon=True).start()

    def _tick(self) -> None:
        while not self._done.wait(1.0):
            with self._lock:
                if self._open >= 1:
                    self.bar.update(1)
                    self._open -= 1

    def stage(self, name: str, est_s: float) -> None:
        with self._lock:
            super().stage(name, est_s)

    def wait(self, seconds: float) -> None:
        """Sleep ``seconds`` (the bar moves meanwhile)."""
        time.sleep(seconds)

    def close(self) -> None:
        self._done.set()
        with self._lock:
            super().close()


def start_session(scene: Scene, i: int, rate_hz: float, mode: str, node_params: list[str]):
    ns = f"/s{i}"
    ros = ("--ros-args", "-r", f"__ns:={ns}")
    extra = [a for p in node_params for a in ("-p", p)]
    node = scene.start(
        f"node_s{i}",
        "node",
        *ros,
        "--params-file",
        str(DEFAULT_PARAMS),
        "-p",
        f"loop_mode:={mode}",
        "-p",
        f"rate_hz:={rate_hz}",
        *extra,
    )
    scene.wait_for_log(node, "live:", timeout_s=180)
    scene.start(f"bridge_s{i}", "bridge", *ros)
    scene.start(f"device_s{i}", "device", "--hand-path", "drag", "--loop", "--start-delay-s", "1.0", *ros)
    return ns


def run_scale(
    max_sessions: int, step_s: float, rate_hz: float, mode: str, node_params: list[str], log_dir: Path, keep_going: bool = True
) -> list[dict]:
    """Add sessions one at a time up to ``max_sessions`` (or, unless ``keep_going``, until one misses > 0.1 %)."""
    rows = []
    with Scene(log_dir) as scene:
        os.environ["ROS_DOMAIN_ID"] = scene.env["ROS_DOMAIN_ID"]
        os.environ["ROS_AUTOMATIC_DISCOVERY_RANGE"] = scene.env["ROS_AUTOMATIC_DISCOVERY_RANGE"]
        obs = DiagObserver()
        est = step_estimate_s(step_s)
        progress = WaitingProgress([est] * max_sessions, "skin-sim scale")
        try:
            for n in range(1, max_sessions + 1):
                progress.stage(f"session {n}: start node + bridge + device, settle {SETTLE_S:.0f} s, measure {step_s:.0f} s", est)
                obs.watch(start_session(scene, n, rate_hz, mode, node_params))
                progress.wait(SETTLE_S)  # discovery, the device's start delay, a joining reader's stall (see SETTLE_S)
                obs.clear()
                load0, steal0 = os.getloadavg()[0], cpu_steal_ms()
                progress.wait(step_s)
                steal_ms = cpu_steal_ms() - steal0
                sessions = [obs.summary(f"/s{i}") for i in range(1, n + 1)]
                worst = max(s.get("node_missed_pct", float("inf")) for s in sessions)
                row = {
                    "sessions": n,
                    "per_session": sessions,
                    "worst_missed_pct": worst,
                    "load_1min": (load0, os.getloadavg()[0]),
                    "steal_ms": steal_ms,
                }
                rows.append(row)
                print(
                    f"  {n} session(s): missed "
                    + ", ".join(f"{s.get('node_missed_pct', nan):.3f}" for s in sessions)
                    + " % | late "
                    + ", ".join(f"{s.get('node_late_pct', nan):.3f}" for s in sessions)
                    + " % | period p99 "
                    + ", ".join(f"{s.get('node_period_us_p99', nan):.0f}" for s in sessions)
                    + f" us | worst missed {worst:.3f} % {'<=' if worst <= MISSED_LIMIT_PCT else '>'} {MISSED_LIMIT_PCT} %"
                    + f" | steal {steal_ms:.0f} ms",
                    flush=True,
                )
                if worst > MISSED_LIMIT_PCT and not keep_going:
                    break
        finally:
            progress.close()
            obs.close()
    return rows


def step_estimate_s(step_s: float) -> float:
    """Wall time of one added session: its three processes' start-up, the settle time, the measured step."""
    return step_s + SETTLE_S + CASE_OVERHEAD_S


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(
        prog="skin-sim scale",
        description=__doc__.splitlines()[0],
        epilog=f"Duration: per added session (--step-s + {SETTLE_S:.0f} s settle + ~{CASE_OVERHEAD_S:.0f} s start-up), "
        "about 45 s each: ~3 min with the defaults (4 sessions). The estimate is printed at start, then one line per step.",
    )
    ap.add_argument("--max-sessions", type=int, default=4)
    ap.add_argument("--step-s", type=float, default=30.0, help="measured seconds after each added session")
    ap.add_argument("--rate-hz", type=float, default=1000.0)
    ap.add_argument(
        "--mode", choices=("timer", "input"), default="timer", help="node loop_mode (timer: ticks are the node's own)"
    )
    ap.add_argument("--node-param", action="append", default=[], help="node parameter NAME:=VALUE (repeatable)")
    ap.add_argument("--keep-going", action="store_true", help="add sessions past the first that misses > 0.1 %%")
    ap.add_argument("--json", type=Path)
    args = ap.parse_args(argv)
    log_dir = Path(tempfile.mkdtemp(prefix="skin_sim_scale_"))
    print(
        f"skin-sim scale: up to {args.max_sessions} sessions at {args.rate_hz:.0f} Hz ({args.mode} mode), about "
        f"{args.max_sessions * step_estimate_s(args.step_s) / 60:.1f} min; "
        f"{args.step_s:.0f} s each, "
        f"{os.cpu_count()} cores, load {os.getloadavg()[0]:.2f}; node params {args.node_param}; logs {log_dir}",
        flush=True,
    )
    rows = run_scale(args.max_sessions, args.step_s, args.rate_hz, args.mode, args.node_param, log_dir, args.keep_going)
    held = sessions_held(rows)
    print(f"sessions held with every session under {MISSED_LIMIT_PCT} % missed ticks: {held}")
    checks = scale_checks(rows, args.max_sessions)
    print(verdict_line("scale", checks), flush=True)
    if args.json:
        args.json.write_text(json.dumps({"rows": rows, "held": held}, indent=1))
    return exit_code(checks)


def sessions_held(rows: list[dict]) -> int:
    """Sessions held: the largest n such that with 1..n sessions running every session missed <= the limit."""
    held = 0
    for r in rows:
        if not r["worst_missed_pct"] <= MISSED_LIMIT_PCT:
            break
        held = r["sessions"]
    return held


def scale_checks(rows: list[dict], max_sessions: int) -> list[tuple[bool, str]]:
    """One check per measured step (n sessions side by side): each session's missed ticks against the limit.

    A failing step names the sessions over the limit and by how much; a step never measured (the run stopped at
    the first failure) is a failure too, so the verdict passes only when ``max_sessions`` were held.
    """
    checks = []
    for r in rows:
        n = r["sessions"]
        over = [(i + 1, s.get("node_missed_pct", float("nan"))) for i, s in enumerate(r["per_session"])]
        over = [(i, m) for i, m in over if not m <= MISSED_LIMIT_PCT]  # NaN (no diagnostics) fails
        if over:
            names = ", ".join(f"/s{i} missed {m:.3f} %" for i, m in over)
            checks.append((False, f"{n} session(s): {names} of ticks (limit {MISSED_LIMIT_PCT} %)"))
        else:
            checks.append((True, f"{n} session(s): worst missed {r['worst_missed_pct']:.3f} % <= {MISSED_LIMIT_PCT} %"))
    if len(rows) < max_sessions:
        checks.append((False, f"{len(rows) + 1}..{max_sessions} sessions not measured (stopped at the first failure)"))
    return checks


if __name__ == "__main__":
    raise SystemExit(main())
