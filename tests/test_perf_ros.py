"""Issue 7 parts 3-5 over real processes: bench statistics, timing levers, soak, DDS across namespaces.

Nothing here asserts a rate or a latency (the CI machine is shared): the checks are counted
(samples, slots, scheduling policies, memory) or structural; figures live in docs/performance_rate.md.
"""

from __future__ import annotations

import os
import shutil
import subprocess
import sys
import threading
import time

import numpy as np
import pytest

rclpy = pytest.importorskip("rclpy")

from msgs_schema.qos import subscription  # noqa: E402
from skin_sim_lab.perf.bench_node import period_stats  # noqa: E402
from skin_sim_lab.perf.soak import GapCounter, growth_pct, run_soak  # noqa: E402
from skin_sim_node.ros_util import LoopTiming, PeriodicLoop, set_realtime  # noqa: E402
from skin_sim_node.scenes import DEFAULT_PARAMS, REPO, Scene  # noqa: E402

pytestmark = [pytest.mark.ros, pytest.mark.usefixtures("ros_domain")]
MS = 1_000_000


def _policy(tid: int) -> int:
    return os.sched_getscheduler(tid) & ~os.SCHED_RESET_ON_FORK


def test_period_stats_counts_empty_slots_and_late_periods():
    t = list(np.arange(100) * MS)  # 1 kHz, 99 periods
    del t[50]  # one empty slot: a 2 ms period
    t[70] += int(0.6 * MS)  # 1.6 ms then 0.4 ms: one late period, rounds to one empty slot
    st = period_stats(t, 1000.0)
    assert st["samples"] == 99
    assert st["missed_pct"] == pytest.approx(100 * 2 / 99)
    assert st["late_pct"] == pytest.approx(100 * 2 / 98)
    assert st["period_ms"][2] == pytest.approx(2.0)


def test_gap_counter_spans_batches_and_growth_ignores_warmup():
    g = GapCounter(5 * MS)
    g.add(np.array([0, 1, 2]) * MS)
    g.add(np.array([9, 10]) * MS)  # the 7 ms gap straddles the batches
    s = g.summary()
    assert (s["periods"], s["gaps_over_limit"], s["max_gap_ms"]) == (4, 1, 7.0)
    rss = [50] * 5 + [100] * 10 + [101] * 10  # warm-up growth, then +1 %
    assert growth_pct(rss, 5) == pytest.approx(1.0)


def test_periodic_loop_realtime_lever_applies_or_warns():
    assert set_realtime(100) is not None  # out of range: a reason, not an exception
    policy = {}

    def fn(_now, _el):
        policy.setdefault("p", _policy(0))

    loop = PeriodicLoop(MS, fn, name="t-rt", timing=LoopTiming(rt_priority=10, spin_ns=100_000, timer_slack_ns=1000))
    loop.start()
    end = time.monotonic() + 10
    while "p" not in policy and time.monotonic() < end:
        time.sleep(0.01)
    loop.stop()
    assert loop.ticks >= 1
    if loop.warnings:
        assert "not permitted" in loop.warnings[0] and policy["p"] != os.SCHED_FIFO
    else:
        assert policy["p"] == os.SCHED_FIFO
    assert _policy(0) != os.SCHED_FIFO  # the caller's own thread is untouched
    assert threading.current_thread() is threading.main_thread()


def _fifo_threads(pid: int) -> int:
    n = 0
    for tid in os.listdir(f"/proc/{pid}/task"):
        try:
            n += _policy(int(tid)) == os.SCHED_FIFO
        except OSError:
            pass
    return n


@pytest.mark.skipif(shutil.which("setpriv") is None, reason="needs setpriv (util-linux) to drop CAP_SYS_NICE")
def test_node_rt_priority_is_opt_in_and_degrades_with_a_warning(tmp_path):
    """Two nodes ask for SCHED_FIFO: one may (root here), one runs without CAP_SYS_NICE. Both serve forces."""
    from skin_sim_node.bags.monitor import Monitor

    with Scene(tmp_path, domain_id=int(os.environ["ROS_DOMAIN_ID"])) as scene:
        base = [
            sys.executable,
            "-m",
            "skin_sim_node.cli",
            "node",
            "--ros-args",
            "--params-file",
            str(DEFAULT_PARAMS),
            "-p",
            "loop_mode:=timer",
            "-p",
            "rt_priority:=20",
            "-p",
            "display_rate_hz:=0.0",
        ]
        procs = {}
        for name, prefix in (("granted", []), ("denied", ["setpriv", "--inh-caps=-sys_nice", "--bounding-set=-sys_nice"])):
            log = tmp_path / f"{name}.log"
            with open(log, "w") as fh:
                p = subprocess.Popen(
                    prefix + base + ["-r", f"__ns:=/{name}"], stdout=fh, stderr=subprocess.STDOUT, env=scene.env, cwd=REPO
                )
            procs[name] = (p, log)
        try:
            for p, log in procs.values():
                end = time.monotonic() + 180
                while "live:" not in log.read_text() and time.monotonic() < end:
                    assert p.poll() is None, log.read_text()
                    time.sleep(0.1)
            granted_log, denied_log = procs["granted"][1].read_text(), procs["denied"][1].read_text()
            if os.geteuid() == 0:
                assert "SCHED_FIFO 20 for the haptic threads (process scope)" in granted_log
                assert _fifo_threads(procs["granted"][0].pid) >= 3  # the tick clock, the executor, the display loop
            assert "not permitted" in denied_log and "running at normal priority" in denied_log
            assert _fifo_threads(procs["denied"][0].pid) == 0
            mon = Monitor(name="test_rt_observer", images=False)
            try:
                got = {}
                for name in procs:
                    got[name] = []
                    subscription(mon.node, "tool_wrench", lambda m, n=name: got[n].append(1), name=f"/{name}/tool/wrench")
                mon.wait_for(lambda: all(len(v) > 50 for v in got.values()), 60, "forces from both nodes")
            finally:
                mon.close()
        finally:
            for p, _ in procs.values():
                p.terminate()
                assert p.wait(timeout=10) == 0


def test_short_soak(tmp_path):
    """~20 s of the 10 min soak: the drag-press loop closes, memory is flat after warm-up."""
    r = run_soak(20.0, 5.0, tmp_path, quiet=True)
    assert r["forces"] > 1000  # the loop closed and kept answering (1 kHz nominal: ~20000)
    assert r["pressing_pct"] > 10  # the drag path pressed into the tissue
    assert r["rss_samples"] >= 15
    assert r["node_rss_growth_pct"] <= 1.0, r
    assert r["stamp_gaps"]["periods"] == r["forces"] - 1


def _netns_possible() -> str | None:
    if os.geteuid() != 0:
        return "needs root for ip netns"
    if shutil.which("ip") is None:
        return "needs iproute2 (ip)"
    probe = f"ssim_probe_{os.getpid()}"
    r = subprocess.run(["ip", "netns", "add", probe], capture_output=True, text=True)
    if r.returncode != 0:
        return f"cannot create network namespaces here: {r.stderr.strip()}"
    subprocess.run(["ip", "netns", "del", probe], capture_output=True)
    return None


def test_dds_across_network_namespaces():
    reason = _netns_possible()
    if reason:
        pytest.skip(reason)
    env = dict(os.environ, CASES="cross_udp", PY=sys.executable)
    r = subprocess.run(
        ["bash", str(REPO / "scripts" / "netns_scale.sh"), "3"], capture_output=True, text=True, env=env, timeout=300
    )
    assert r.returncode == 0, r.stdout + r.stderr
    line = next(ln for ln in r.stdout.splitlines() if ln.startswith("across namespaces (veth), UDPv4:"))
    assert int(line.split(":")[1].split()[0]) > 100  # forces crossed the veth both ways
    before = subprocess.run(["ip", "netns", "list"], capture_output=True, text=True).stdout
    assert "ssim_" not in before  # the trap removed the namespaces


def test_bench_timer_case_reports_periods_and_node_counts(tmp_path):
    """One short ``skin-sim bench`` jitter case end to end: its figures are those of the stamps it recorded and of
    the node's own diagnostics (recomputed here), whatever the machine's load made of them."""
    from skin_sim_lab.perf.bench_node import diag_counts, run_case

    r = run_case("node-timer", 2.0, 1000.0, tmp_path, ("-p", "display_rate_hz:=0.0"), settle_s=1.0, keep_stamps=True)
    assert r["samples"] > 100 and r["wrenches"] == len(r["stamps_ns"])
    again = period_stats(r["stamps_ns"], 1000.0)
    assert again["samples"] == r["samples"] and again["missed_pct"] == r["missed_pct"] and again["period_ms"] == r["period_ms"]
    counts = diag_counts(r["diagnostics"])
    assert counts == {k: r[k] for k in counts}
    assert r["node_ticks"] > 100 and r["node_rate_hz"] > 0


def test_diag_counts_sums_the_windows_after_the_first():
    from skin_sim_lab.perf.bench_node import diag_counts

    def d(total, missed, late, hz):
        return {
            "ticks_total": str(total),
            "missed_slots_window": str(missed),
            "late_ticks_window": str(late),
            "achieved_rate_hz": str(hz),
            "period_us_p99": "1100",
            "kernel_us_p99": "20",
        }

    c = diag_counts([d(500, 99, 99, 1.0), d(1500, 10, 4, 990.0), d(2500, 30, 6, 1000.0)])
    assert (c["node_windows"], c["node_ticks"], c["node_late_ticks"]) == (2, 2000, 10)
    assert c["node_missed_pct"] == pytest.approx(100 * 40 / 2040) and c["node_rate_hz"] == pytest.approx(995.0)
    assert diag_counts([d(1, 0, 0, 1.0)]) == {"node_windows": 1}


def test_scale_one_session_in_its_namespace(tmp_path):
    """``skin-sim scale`` with one namespaced session: its diagnostics arrive (under its namespace) and count ticks."""
    from skin_sim_lab.perf.scale import run_scale

    rows = run_scale(1, 3.0, 1000.0, "timer", ["display_rate_hz:=0.0"], tmp_path)
    s = rows[0]["per_session"][0]
    assert s["node_windows"] >= 1 and s["node_ticks"] > 100


def test_progress_prints_a_line_per_stage_with_the_remaining_estimate(capsys):
    from skin_sim_lab.perf.bench_node import Progress

    p = Progress([30.0, 60.0, 30.0], "test")
    for name, est in (("a", 30.0), ("b", 60.0), ("c", 30.0)):
        p.stage(name, est)
    p.close()
    lines = [ln for ln in capsys.readouterr().out.splitlines() if ln.startswith("[")]
    assert [ln.split("] ")[1] for ln in lines] == ["a (~30 s)", "b (~60 s)", "c (~30 s)"]
    assert "~2.0 min left" in lines[0] and "~1.5 min left" in lines[1] and "~0.5 min left" in lines[2]
    assert lines[0].startswith("[1/3, 0.0 min elapsed")
