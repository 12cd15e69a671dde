"""The machine stall probe of the device benchmarks (skin_sim_lab.perf.stall_probe): what it records and how a command
gap is judged against it."""

import os
import subprocess
import sys
import time
from pathlib import Path

import numpy as np
import pytest

from skin_sim_lab.perf import stall_probe as sp


def test_the_overlap_is_the_union_of_stalls_on_every_cpu_clipped_to_the_gap():
    ms = 1_000_000
    rows = np.array(
        [
            (0, 10 * ms, 13 * ms, 0),  # 3 ms stall on CPU 0
            (1, 12 * ms, 15 * ms, 100_000),  # 3 ms on CPU 1, overlapping it: the union is 10-15 ms
            (0, 30 * ms, 30 * ms + 500_000, 0),  # recorded late, but under STALL_NS: not a stall
            (1, 40 * ms, 42 * ms, 0),
            (0, 50 * ms, 98 * ms, 47 * ms),  # 48 ms late, 47 of them runnable: held off (RT throttling), not a stall
        ],
        dtype=np.int64,
    )
    assert sp.stall_overlap_ns(rows, 9 * ms, 20 * ms) == 5 * ms
    assert sp.stall_overlap_ns(rows, 11 * ms, 14 * ms) == 3 * ms  # clipped at both ends
    assert sp.stall_overlap_ns(rows, 29 * ms, 33 * ms) == 0.0  # the short one does not count
    assert sp.stall_overlap_ns(rows, 0, 100 * ms) == 7 * ms
    assert sp.summary(rows, 0, 35 * ms) == (2, 3.0)
    assert sp.summary(rows, 35 * ms, 100 * ms) == (1, 2.0)
    assert sp.summary(rows[:0], 0, 100 * ms) == (0, 0.0)
    assert sp.stall_overlap_ns(rows, 45 * ms, 100 * ms) == 0.0  # the held one is never taken out of a gap
    assert len(sp.held(rows)) == 1 and sp.held(rows)[0, 1] == 50 * ms


def test_a_gap_is_the_machines_only_when_the_stall_takes_it_within_the_aim(tmp_path):
    """analyse's rule, on the probe's numbers: a 6.4 ms gap with a 5.07 ms stall inside is the machine's (1.3 ms
    left); a 6.4 ms gap with a 1.2 ms stall is not (5.2 ms left)."""
    ms = 1_000_000
    big = np.array([(1, 101 * ms, 101 * ms + 5_070_000, 0)], dtype=np.int64)
    small = np.array([(1, 101 * ms, 101 * ms + 1_200_000, 0)], dtype=np.int64)
    a, b = 100 * ms, 100 * ms + 6_400_000
    assert (b - a) - sp.stall_overlap_ns(big, a, b) <= 5 * ms
    assert (b - a) - sp.stall_overlap_ns(small, a, b) > 5 * ms


def test_the_probes_run_on_each_cpu_and_write_their_records(tmp_path):
    procs = sp.start(tmp_path)
    time.sleep(1.5)  # its imports, then some periods
    rows = sp.stop(procs, tmp_path)
    for p in procs:
        assert p.returncode == 0
    logs = sorted(tmp_path.glob("stall_probe_cpu*.log"))
    assert len(logs) == len(procs) >= 1
    assert all("PROBE cpu" in f.read_text() for f in logs)
    assert len(sorted(tmp_path.glob("stall_probe_cpu*.npy"))) == len(procs)
    assert rows.shape[1] == 4 and np.all(rows[:, 2] - rows[:, 1] > sp.RECORD_NS)  # only late wake-ups are kept
    assert np.all(rows[:, 3] >= 0)  # the run-queue wait since the wake-up before


def test_a_probe_held_off_by_rt_throttling_is_not_counted_as_the_machines(tmp_path):
    """A real-time thread spinning on CPU 1 for 2.2 s uses up the CPU's real-time share (sched_rt_runtime_us), and
    the kernel throttles every real-time thread there, the probe's too, for the rest of each second: a probe late by
    tens of ms that waited runnable all along. That is the benchmark's own load, never a stall of the machine."""
    runtime = Path("/proc/sys/kernel/sched_rt_runtime_us")
    if not runtime.exists() or int(runtime.read_text()) < 0 or 1 not in os.sched_getaffinity(0):
        pytest.skip("no RT throttling on this kernel, or no CPU 1")
    code = (
        "import os, time\n"
        "os.sched_setaffinity(0, {1})\n"
        "try:\n    os.sched_setscheduler(0, os.SCHED_FIFO, os.sched_param(10))\nexcept OSError:\n    raise SystemExit(3)\n"
        "t = time.monotonic() + 2.2\n"
        "while time.monotonic() < t:\n    pass\n"
    )
    procs = sp.start(tmp_path)
    time.sleep(1.0)
    spinner = subprocess.run([sys.executable, "-c", code], check=False)
    rows = sp.stop(procs, tmp_path)
    if spinner.returncode == 3:
        pytest.skip("SCHED_FIFO not permitted")
    held = sp.held(rows)
    # The throttled stretch on CPU 1 is what is left of each period beyond sched_rt_runtime_us (50 ms of the default
    # 1 s): at least one held row there late by over half of it. Other CPUs are not asserted on: a busy host (CI beside
    # other jobs) can hold a probe there too, and those rows are held by the same rule (a CI run had one on CPU 0,
    # 8.7 ms late, 8.6 ms of it runnable).
    period_us = int(Path("/proc/sys/kernel/sched_rt_period_us").read_text())
    throttle_ns = (period_us - int(runtime.read_text())) * 1000
    if throttle_ns < 4 * sp.STALL_NS:
        pytest.skip(f"RT throttling leaves {throttle_ns / 1e6:g} ms a period: too short to tell from a stall")
    throttled = held[(held[:, 0] == 1) & (held[:, 2] - held[:, 1] > throttle_ns / 2)]
    assert len(throttled) >= 1, rows
    late = throttled[0]
    assert sp.stall_overlap_ns(rows[rows[:, 0] == 1], float(late[1]), float(late[2])) < late[2] - late[1]


def test_a_probe_that_fails_to_start_leaves_no_other_probe_running(tmp_path, monkeypatch):
    """The second CPU's probe fails to start: the first one, already started, is killed and reaped before the error
    goes on (a stand-in process object: no real SCHED_FIFO 99 probe is started)."""
    if len(os.sched_getaffinity(0)) < 2:
        pytest.skip("needs two CPUs")

    class Started:
        def __init__(self):
            self.calls: list[str] = []

        def kill(self):
            self.calls.append("kill")

        def wait(self, timeout=None):
            self.calls.append("wait")
            return -9

    started: list[Started] = []

    def popen(*args, **kwargs):
        if started:
            raise OSError("no such interpreter")
        started.append(Started())
        return started[-1]

    monkeypatch.setattr(sp.subprocess, "Popen", popen)
    with pytest.raises(OSError, match="no such interpreter"):
        sp.start(tmp_path)
    assert len(started) == 1 and started[0].calls == ["kill", "wait"]
