"""The device path's CPU budget (issue 27): each process's CPU, rclpy messages per device tick, the bare echo baseline.

Used by ``skin-sim bench-device``:

- :class:`ProcCpu` reads a process's CPU time (its threads and its children: the node's display worker) at the
  phase marks, so each phase reports **% of a core** per process;
- :func:`echo_baseline` runs the bare rclpy echo (``skin-sim echo --executor single``: one ``PoseStamped`` in, one
  ``WrenchStamped`` out, rclpy's ``SingleThreadedExecutor`` and message objects, as a first rclpy program would)
  fed at the device rate by :func:`feed`, in the same run: the floor every figure is a ratio to;
- :class:`DiagListener` keeps the newest diagnostics of the node and the bridge (achieved and server rate,
  watchdog releases, rate changes);
- :func:`skin_sim_node.rate.device_tick_messages` is the message budget per device tick, evaluated at the rates the
  run measured.

The budget (docs/devices.md): node plus bridge at most one core at a 1 kHz device on this 2-core machine, about
twice the bare echo, leaving a core for the driver and a renderer.
"""

from __future__ import annotations

import argparse
import os
import sys
import threading
import time

ECHO_S = 4.0
"""How long the echo baseline is fed (s): 4000 poses at 1 kHz, after 1.5 s of discovery (excluded)."""


class ProcCpu:
    """CPU seconds of one process and its children, read at marks.

    Parameters
    ----------
    pid : int
    """

    def __init__(self, pid: int, threads: bool = False):
        import psutil

        self.proc = psutil.Process(pid)
        self.marks: list[tuple[float, float]] = []
        self.threads = threads
        self.thread_marks: list[dict[int, tuple[str, float]]] = []
        """With ``threads``: ``{tid: (group, CPU seconds)}`` of the live threads at each mark (:func:`thread_group`)."""

    def cpu_s(self) -> float:
        """CPU seconds so far (user + system), children included; the last value once the process is gone."""
        import psutil

        try:
            t = self.proc.cpu_times()
            kids = 0.0
            for c in self.proc.children(recursive=True):
                try:
                    ct = c.cpu_times()
                    kids += ct.user + ct.system
                except psutil.Error:
                    pass
            return t.user + t.system + kids
        except psutil.Error:
            return self.marks[-1][1] if self.marks else float("nan")

    def threads_s(self) -> dict[int, tuple[str, float]]:
        """``{tid: (group, CPU seconds so far)}`` of the process's live threads (:func:`thread_group`; its children
        not included); empty once the process is gone."""
        import psutil

        from skin_sim_node.ros_util import thread_names

        pid = self.proc.pid
        try:
            names = thread_names(pid)
            threads = self.proc.threads()
            return {t.id: (thread_group(names.get(t.id, ""), t.id, pid), t.user_time + t.system_time) for t in threads}
        except (psutil.Error, OSError):
            return {}

    def mark(self) -> None:
        """Record (wall time, CPU seconds) now, and with ``threads`` each thread's CPU seconds."""
        self.marks.append((time.monotonic(), self.cpu_s()))
        if self.threads:
            self.thread_marks.append(self.threads_s())

    def pct(self, i: int, j: int) -> float:
        """% of one core between marks ``i`` and ``j``."""
        (t0, c0), (t1, c1) = self.marks[i], self.marks[j]
        return 100.0 * (c1 - c0) / (t1 - t0) if t1 > t0 else float("nan")

    def thread_pct(self, i: int, j: int) -> dict[str, float]:
        """% of one core per thread group between marks ``i`` and ``j``: each thread's CPU between them (all of it for
        a thread started in between), summed under its group at mark ``j``; a thread that ended in between is not
        counted, nor are the children (``pct`` less their sum is those)."""
        if not self.thread_marks:
            return {}
        (t0, _), (t1, _) = self.marks[i], self.marks[j]
        a, b = self.thread_marks[i], self.thread_marks[j]
        if t1 <= t0:
            return {}
        out: dict[str, float] = {}
        for tid, (group, cpu) in b.items():
            prev = a.get(tid)  # the same thread at mark i (not a new one that reused its id)
            out[group] = out.get(group, 0.0) + cpu - (prev[1] if prev is not None and prev[1] <= cpu else 0.0)
        return {g: 100.0 * v / (t1 - t0) for g, v in sorted(out.items())}


def thread_group(name: str, tid: int, pid: int) -> str:
    """The group a thread's CPU is counted in: ``main`` (the process's first thread: its executor), a thread that
    is named ``skin-*`` (``skin-servo-0``, ``skin-link-1``, ``skin-node-clock``: :func:`skin_sim_node.ros_util.start_own_thread`)
    under its name, Fast DDS's threads (``dds.*``: receive, events, async writes) as ``dds``, the rest ``other``
    (rclpy's and Python's unnamed threads, the display's)."""
    from skin_sim_node.ros_util import OWN_THREAD_PREFIX

    if tid == pid:
        return "main"
    if name.startswith(OWN_THREAD_PREFIX):
        return name
    if name.startswith("dds."):
        return "dds"
    return "other"


class DiagListener:
    """The newest ``diagnostics`` key-values of each status name (node, bridge), on a participant of its own.

    Parameters
    ----------
    topics : tuple of str
        The diagnostics topics read (a bridge in a hand's namespace publishes ``/<hand>/diagnostics``).
    """

    def __init__(self, topics: tuple[str, ...] = ("/diagnostics",)):
        import rclpy
        from diagnostic_msgs.msg import DiagnosticArray

        from skin_sim_node.ros_util import make_executor, spin_context

        self.ctx = rclpy.Context()
        rclpy.init(context=self.ctx)
        self.node = rclpy.create_node(f"bench_diag_{os.getpid()}", context=self.ctx, start_parameter_services=False)
        self.latest: dict[str, dict[str, str]] = {}
        self._lock = threading.Lock()
        for topic in topics:
            self.node.create_subscription(DiagnosticArray, topic, self._on_diag, 10)
        self._ex = make_executor("events", self.ctx)
        self._ex.add_node(self.node)
        self._stop = threading.Event()
        self._th = threading.Thread(target=spin_context, args=(self._ex, self.ctx, self._stop), daemon=True)
        self._th.start()

    def _on_diag(self, msg) -> None:
        with self._lock:
            for st in msg.status:
                self.latest[st.name] = {kv.key: kv.value for kv in st.values}

    def find(self, suffix: str) -> dict[str, str]:
        """The newest values of the status whose name ends with ``suffix`` (``haptic loop``, ``device render``)."""
        with self._lock:
            for name, values in self.latest.items():
                if name.endswith(suffix):
                    return dict(values)
        return {}

    def close(self) -> None:
        """Stop the thread and leave the graph."""
        import rclpy

        self._stop.set()
        self._th.join(timeout=2.0)
        try:
            self.node.destroy_node()
        except Exception:
            pass
        rclpy.try_shutdown(context=self.ctx)


def feed(seconds: float, rate_hz: float = 1000.0) -> int:
    """Publish ``tool/pose`` at ``rate_hz`` on absolute deadlines (SCHED_FIFO 90 where allowed) for ``seconds``."""
    import rclpy

    from msgs_schema.convert import PoseCdr
    from msgs_schema.qos import publisher
    from skin_sim_node.ros_util import set_realtime, sleep_until_ns

    set_realtime(90)
    rclpy.init()
    node = rclpy.create_node("echo_feed", start_parameter_services=False)
    pub = publisher(node, "tool_pose")
    cdr = PoseCdr("tissue")
    time.sleep(1.5)  # discovery of the echo
    period = int(1e9 / rate_hz)
    t0 = time.monotonic_ns()
    print(f"FEED start {time.monotonic()}", flush=True)
    for k in range(int(seconds * rate_hz)):
        sleep_until_ns(t0 + k * period)
        pub.publish(cdr.fill(time.time_ns(), (0.0, 0.0, 0.001)))
    print(f"FEED end {time.monotonic()}", flush=True)
    node.destroy_node()
    rclpy.try_shutdown()
    return 0


def echo_baseline(scene, seconds: float = ECHO_S) -> float:
    """% of a core of the bare rclpy echo fed at 1 kHz for ``seconds`` (its start-up excluded), in ``scene``."""
    import subprocess

    from skin_sim_node.scenes import REPO

    echo = scene.start("echo", "echo", "--executor", "single")
    scene.wait_for_log(echo, "live: echo")
    cpu = ProcCpu(echo.popen.pid)
    log = open(scene.log_dir / "echo_feed.log", "w")
    fd = subprocess.Popen(
        [sys.executable, "-m", "skin_sim_lab.perf.cpu_budget", "--feed", str(seconds)],
        stdout=log,
        stderr=subprocess.STDOUT,
        env=scene.env,
        cwd=REPO,
    )
    try:
        while "FEED start" not in (scene.log_dir / "echo_feed.log").read_text():
            if fd.poll() is not None:
                raise RuntimeError(f"echo feed exited: {(scene.log_dir / 'echo_feed.log').read_text()[-1000:]}")
            time.sleep(0.01)
        time.sleep(0.3)  # the first poses' discovery hand-shake
        cpu.mark()
        time.sleep(max(seconds - 0.6, 0.5))
        cpu.mark()
        fd.wait(timeout=seconds + 30)
    finally:
        if fd.poll() is None:  # raised (or timed out): the feed is not left publishing beside what follows
            fd.kill()
            fd.wait()
        log.close()
    echo.popen.terminate()
    echo.popen.wait(timeout=10)
    return cpu.pct(0, 1)


def main(argv=None) -> int:
    """``python -m skin_sim_lab.perf.cpu_budget --feed SECONDS``: the echo baseline's 1 kHz pose feeder."""
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--feed", type=float, required=True)
    return feed(ap.parse_args(argv).feed)


if __name__ == "__main__":
    raise SystemExit(main())
