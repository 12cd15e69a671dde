"""The machine's own stalls, measured beside a device benchmark: one probe process per CPU.

Each probe pins itself to one CPU, runs at SCHED_FIFO :data:`PROBE_PRIORITY` (above every thread of the device path,
the emulators' 90 included) and sleeps to absolute deadlines :data:`PERIOD_NS` apart on CLOCK_MONOTONIC
(``clock_nanosleep(TIMER_ABSTIME)``, as cyclictest does). Nothing of the benchmark can hold it off its CPU, so a wake-up
much later than its deadline means the CPU itself was away: on this virtual machine, the host not running that virtual
CPU (the guest's ``/proc/stat`` reports no steal time here), or the kernel with preemption off. A scheduling trace
(``perf record -e sched:sched_switch -e sched:sched_wakeup -a``, 2026-12-06) showed such stalls: one CPU with no
scheduling event at all for 5.07 and 5.17 ms, the 1 kHz emulator on it silent, and the bridge process's GIL holder
frozen on it, so both devices' commands stopped (6.4 and 5.6 ms gaps) while the other CPU ran.

A late wake-up is not always the machine's. The kernel's RT throttling (``sched_rt_runtime_us``, 950 ms of every
second for real-time threads) stops every real-time thread of a CPU, the probe's too, once they have used their share:
that is the benchmark's own load, and the trace of a trial that raised the node's threads to 79 beside two bridges
showed late wake-ups of up to 47 ms. A throttled (or preempted) probe is runnable while it waits; a probe whose CPU
was away is not even woken. So each probe reads its own ``run_delay`` (``/proc/thread-self/schedstat``: the time it
waited on a run queue while runnable) at each wake-up, and a late wake-up is a stall of the machine only when it spent
less than half of its lateness waiting to run (:func:`stalls`).

Each probe records every wake-up more than :data:`RECORD_NS` late as ``(cpu, deadline_ns, wake_ns, waited_ns)``; it
stops on SIGTERM or SIGINT and writes its records (``np.save``). :func:`stall_overlap_ns` gives how much of an interval the
recorded stalls cover, which the device benchmark takes out of a command gap before it counts the gap (a gap that is
within the aim once the machine's own absence is taken out is the machine's, reported apart).

The probe's cost: one wake-up per period per CPU, about 10 us of Python each (1 % of each CPU at 1 kHz).
"""

from __future__ import annotations

import argparse
import gc
import os
import signal
import subprocess
import sys
import time
from pathlib import Path

import numpy as np

PROBE_PRIORITY = 99
"""SCHED_FIFO priority of a probe: the highest, so that only the CPU's absence (or the kernel) delays it."""
PERIOD_NS = 1_000_000
"""The probe's period (1 ms): a stall of a few milliseconds, the size of the 5 ms gap aim, is resolved to one period."""
RECORD_NS = 200_000
"""A wake-up later than this after its deadline is recorded (0.2 ms: the probe's own wake-up latency on this machine
is tens of microseconds; see :data:`STALL_NS` for what counts)."""
STALL_NS = 1_000_000
"""A recorded wake-up at least this late is a stall of the machine (1 ms: a whole period missed)."""
MAX_RECORDS = 100_000


def probe(cpu: int, out: Path) -> int:
    """Run one probe on ``cpu`` until SIGTERM or SIGINT; write its late wake-ups to ``out`` (.npy, rows ``(cpu,
    deadline_ns, wake_ns, waited_ns)``, ``waited_ns`` the run-queue wait since the wake-up before). Returns the exit
    code."""
    from skin_sim_node.ros_util import set_realtime, sleep_until_ns

    stop = [False]

    def on_signal(_sig, _frame) -> None:
        stop[0] = True

    signal.signal(signal.SIGTERM, on_signal)
    signal.signal(signal.SIGINT, on_signal)
    os.sched_setaffinity(0, {cpu})
    why = set_realtime(PROBE_PRIORITY)
    print(f"PROBE cpu {cpu} rt={'granted' if why is None else why}", flush=True)
    rows = np.zeros((MAX_RECORDS, 4), dtype=np.int64)
    n = 0
    stat = os.open("/proc/thread-self/schedstat", os.O_RDONLY)  # "<on-CPU ns> <run-queue wait ns> <slices>"
    waited = int(os.pread(stat, 64, 0).split()[1])
    gc.collect()
    gc.freeze()
    gc.disable()  # no collector pass in the loop: it allocates nothing that lives
    parent = os.getppid()
    deadline = time.monotonic_ns() + PERIOD_NS
    while not stop[0] and os.getppid() == parent:  # it ends with the benchmark, however that ends (no FIFO 99 orphan)
        sleep_until_ns(deadline)
        now = time.monotonic_ns()
        w = int(os.pread(stat, 64, 0).split()[1])
        if now - deadline > RECORD_NS and n < MAX_RECORDS:
            rows[n] = (cpu, deadline, now, w - waited)
            n += 1
        waited = w
        deadline += PERIOD_NS
        if deadline < now:  # a stall longer than a period: the next deadline after now (one record per stall)
            deadline = now + PERIOD_NS - (now - deadline) % PERIOD_NS
    np.save(out, rows[:n])
    return 0


def start(log_dir: Path, env: dict | None = None) -> list[subprocess.Popen]:
    """One probe per CPU this process may use, writing ``stall_probe_cpu<N>.npy`` in ``log_dir``. A probe that does not
    start stops the ones that did before the error goes on (no SCHED_FIFO 99 process is left behind)."""
    procs: list[subprocess.Popen] = []
    try:
        for cpu in sorted(os.sched_getaffinity(0)):
            argv = [sys.executable, "-m", "skin_sim_lab.perf.stall_probe", "--cpu", str(cpu)]
            argv += ["--out", str(log_dir / f"stall_probe_cpu{cpu}.npy")]
            with open(log_dir / f"stall_probe_cpu{cpu}.log", "w") as log:  # the child keeps its own copy
                procs.append(subprocess.Popen(argv, stdout=log, stderr=subprocess.STDOUT, env=env, cwd=Path(__file__).parents[2]))
    except BaseException:
        for p in procs:
            p.kill()
            p.wait()
        raise
    return procs


def stop(procs: list[subprocess.Popen], log_dir: Path) -> np.ndarray:
    """Stop the probes and return every CPU's records, rows ``(cpu, deadline_ns, wake_ns, waited_ns)`` by deadline."""
    for p in procs:
        p.send_signal(signal.SIGTERM)
    for p in procs:
        try:
            p.wait(timeout=10)
        except subprocess.TimeoutExpired:
            p.kill()
            p.wait()
    return load(log_dir)


def load(log_dir: Path) -> np.ndarray:
    """The probes' records in ``log_dir`` (rows ``(cpu, deadline_ns, wake_ns, waited_ns)``, by deadline; none: shape
    (0, 4))."""
    parts = [np.load(f) for f in sorted(Path(log_dir).glob("stall_probe_cpu*.npy"))]
    rows = np.concatenate(parts) if parts else np.zeros((0, 4), dtype=np.int64)
    return rows[np.argsort(rows[:, 1], kind="stable")] if len(rows) else rows.reshape(0, 4)


def _late(rows: np.ndarray, lo_ns: float, hi_ns: float, away: bool) -> np.ndarray:
    """The records :data:`STALL_NS` late or more with their deadline in ``[lo_ns, hi_ns)``: with ``away`` those that
    spent less than half of it runnable on a run queue (the CPU was away), else the others (module docstring)."""
    late = rows[:, 2] - rows[:, 1]
    was_away = rows[:, 3] < late / 2
    return rows[(late >= STALL_NS) & (was_away == away) & (rows[:, 1] >= lo_ns) & (rows[:, 1] < hi_ns)]


def stalls(rows: np.ndarray, lo_ns: float = -np.inf, hi_ns: float = np.inf) -> np.ndarray:
    """The records that are stalls of the machine, with their deadline in ``[lo_ns, hi_ns)``: :data:`STALL_NS` late
    or more, less than half of it spent runnable on a run queue (module docstring)."""
    return _late(rows, lo_ns, hi_ns, away=True)


def held(rows: np.ndarray, lo_ns: float = -np.inf, hi_ns: float = np.inf) -> np.ndarray:
    """Late wake-ups (:data:`STALL_NS` or more) spent mostly runnable: the probe held off a CPU that was there (RT
    throttling, the kernel): not the machine's, never taken out of a gap."""
    return _late(rows, lo_ns, hi_ns, away=False)


def stall_overlap_ns(rows: np.ndarray, a_ns: float, b_ns: float) -> float:
    """How long (ns) the stalls in ``rows`` cover of ``[a_ns, b_ns]``: the union over every CPU of each stall's
    ``[deadline, wake]`` (a lower bound of the CPU's absence, which may have begun before the deadline)."""
    s = stalls(rows)
    iv = sorted((max(float(d), a_ns), min(float(w), b_ns)) for _, d, w, _ in s if w > a_ns and d < b_ns)
    total, end = 0.0, -np.inf
    for lo, hi in iv:
        if hi <= end:
            continue
        total += hi - max(lo, end)
        end = hi
    return total


def summary(rows: np.ndarray, lo_ns: float, hi_ns: float) -> tuple[int, float]:
    """Stalls with their deadline in ``[lo_ns, hi_ns)``: how many, and the longest (ms; 0 without one)."""
    s = stalls(rows, lo_ns, hi_ns)
    return len(s), float((s[:, 2] - s[:, 1]).max() * 1e-6) if len(s) else 0.0


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(prog="python -m skin_sim_lab.perf.stall_probe", description=__doc__.splitlines()[0])
    ap.add_argument("--cpu", type=int, required=True)
    ap.add_argument("--out", type=Path, required=True)
    args = ap.parse_args(argv)
    return probe(args.cpu, args.out)


if __name__ == "__main__":
    raise SystemExit(main())
