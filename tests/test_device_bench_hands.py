"""The two-device benchmark's ground truth and merge (issue 32, ``skin-sim bench-device --hands 2``): no DDS, no timing.

The truth is the offline two-hand session stepped on both emulators' poses merged by stamp; it must be
tests/test_two_hands_ros.py's two-hand truth (each hand its session on :func:`skin_sim_node.tools.make_tools`'
tools, stepped in stamp order across hands), one device's must be the single benchmark's, and a hand held still
beside another's drag must feel the drag through the tissue.
"""

from __future__ import annotations

import numpy as np
import pytest

from skin_sim_lab.perf.device_bench import (
    HOLD_XY_M,
    PERIOD_NS,
    ground_truth,
    ground_truth_hands,
    hand,
    hold_beside,
    merge_by_stamp,
)
from skin_sim_lab.perf.device_bench_hands import (
    HAND_PARAMS,
    hand_configs,
    hand_view,
    missed_hand_aims,
    parse_node_params,
)
from skin_sim_node.session import HapticSession
from skin_sim_node.tools import make_tools

T0_STAMP_NS = 1_700_000_000_000_000_000
"""A system-clock stamp of this era (ns), as the emulators stamp their poses."""
PHASE_S = 2.0
"""One drag period per phase: the paths' shape, not their length, matters here."""


def slots_of(path, seconds: float, offset_ns: int = 0, every: int = 1) -> np.ndarray:
    """Emulator slots (:func:`emulate`'s layout) of a scripted hand: deadline, published, stamp, x, v, late."""
    n = int(seconds * 1e9 / PERIOD_NS)
    out = np.zeros((n, 10))
    for k in range(0, n, every):
        t_ns = k * PERIOD_NS + offset_ns
        x, v = path(t_ns * 1e-9, PHASE_S)
        out[k] = (t_ns, t_ns, T0_STAMP_NS + t_ns, *x, *v, 0.0)
    return out


def test_merge_orders_by_stamp_skips_unpublished_and_keeps_hand_order_on_ties():
    a = np.array([30.0, 0.0, 10.0, 20.0])
    b = np.array([10.0, 25.0, 0.0])
    assert merge_by_stamp([a, b]) == [(0, 2), (1, 0), (0, 3), (1, 1), (0, 0)]
    assert merge_by_stamp([a]) == [(0, 2), (0, 3), (0, 0)]
    assert merge_by_stamp([]) == []


def test_hand_configs_are_the_nodes_two_hands():
    _, cfgs = hand_configs()
    assert [(c.tool_shape, c.tool_radius_m) for c in cfgs] == [("flat", 0.0025), ("flat", 0.005)]
    _, one = hand_configs(overrides={})
    assert len(one) == 1
    assert parse_node_params(["second_tool_radius_m:=0.004", "hand_ns:=right"]) == {
        "second_tool_radius_m": 0.004,
        "hand_ns": "right",
    }
    _, cfgs = hand_configs(overrides=HAND_PARAMS | {"second_tool_radius_m": 0.004})
    assert cfgs[1].tool_radius_m == 0.004
    with pytest.raises(ValueError):
        parse_node_params(["hand_ns=right"])


def test_one_device_truth_is_the_single_benchmarks():
    sp, cfgs = hand_configs(overrides={})
    slots = slots_of(hand, 1.5, every=1)
    slots[100:110] = 0.0  # slots the emulator did not publish
    np.testing.assert_array_equal(ground_truth_hands([slots], cfgs, sp)[0], ground_truth(slots))


def test_two_hand_truth_is_the_offline_two_hand_session_in_stamp_order():
    """tests/test_two_hands_ros.py's ``offline``, written out: the truth of each published pose, both hands merged."""
    sp, cfgs = hand_configs()
    right = slots_of(hand, 2.6)
    left = slots_of(hold_beside, 2.6, offset_ns=PERIOD_NS // 2, every=2)  # the left at 500 Hz, half a slot later
    truth = ground_truth_hands([right, left], cfgs, sp)
    sessions = [HapticSession(t, sp) for t in make_tools(cfgs)]
    rows = sorted([(r[2], 0, i) for i, r in enumerate(right) if r[2]] + [(r[2], 1, i) for i, r in enumerate(left) if r[2]])
    prev = [None, None]
    for stamp, h, i in rows:
        row, s = (right, left)[h][i], sessions[h]
        s.on_twist(int(stamp), "tissue", row[6:9])
        assert s.on_pose(int(stamp), "tissue", row[3:6]) is None
        f = s.tick(int(stamp), 0 if prev[h] is None else int(stamp) - prev[h]).force_n
        np.testing.assert_array_equal(truth[h][i], f)
        prev[h] = int(stamp)
    assert not truth[1][1::2].any()  # the left's unpublished slots stay zero


def test_the_held_hand_feels_the_drag_and_the_drag_feels_the_held_hand():
    sp, cfgs = hand_configs()
    right, left = slots_of(hand, 4.0), slots_of(hold_beside, 4.0)
    assert tuple(left[-1, 3:5]) == HOLD_XY_M and not left[-1, 6:9].any()
    two = ground_truth_hands([right, left], cfgs, sp)
    alone_right = ground_truth_hands([right], cfgs[:1], sp)[0]
    alone_left = ground_truth_hands([left], cfgs[1:], sp)[0]
    drag = slice(2000, 4000)  # the drag's first period (WARM_S = 2 s)
    # held still, its force moves with the drag: the coupling (its force beside the drag less its force alone, which
    # relaxes slowly by itself: viscoelastic memory) spans more than 5 % of its force (11 % when written)
    coupling = two[1][drag, 2] - alone_left[drag, 2]
    assert np.ptp(coupling) > 0.05 * np.abs(alone_left[drag, 2]).max(), np.ptp(coupling)
    assert np.any(np.abs(two[0][drag, 2] - alone_right[drag, 2]) > 1e-3)  # and the drag's force differs from alone


def test_hand_view_and_aims_name_the_hand():
    cpu = {"node": 30.0, "bridge_right": 40.0, "bridge_left": 41.0, "emulator_right": 20.0, "emulator_left": 21.0}
    res = {
        "recs": {"right": {"r": 1}, "left": {"l": 2}},
        "cpu": {"steady": cpu},
        "diag": {"steady_end": {"node": {"count_x": "1", "hand_left_count_x": "2", "hand_left_rate_hz": "999.0"}}},
    }
    left = hand_view(res, "left", "hand_left_")
    assert left["rec"] == {"l": 2}
    assert left["cpu"]["steady"] == {"node": 30.0, "bridge": 41.0, "emulator": 21.0}
    assert left["diag"]["steady_end"]["node"] == {"count_x": "2", "rate_hz": "999.0", "server_rate_hz": "999.0"}
    assert hand_view(res, "right", "")["diag"]["steady_end"]["node"]["count_x"] == "1"
    ok = {
        "over_true": 0, "over_limit": 0, "answered": 1.0, "gaps_5ms": 0, "render_p99_pct": 1.0, "hold_p99_pct": 0.5,
        "watchdog_releases": 0, "cpu_pct": {"node": 90.0, "bridge": 90.0},
    }  # fmt: skip
    ph = {name: dict(ok) for name in ("steady", "join", "throttle")}
    ph["kill"] = dict(ok, kill_zero_ms=10.0, kill_step_pct=1.0)
    bad = {name: dict(p) for name, p in ph.items()}
    bad["steady"]["answered"] = 0.99
    # render below hold-last and the CPU budget are not two-hand aims; the answered share is, named with its hand
    assert missed_hand_aims({"right": ph, "left": bad}) == ["answered: left steady 99.00%"]
    # a kill after the emulators stopped is no kill: the run's schedule is missed, named once for both hands
    late = {name: dict(p) for name, p in ph.items()}
    late["kill"]["kill_at_s"] = 4.3
    late["throttle"].update(throttle_applied=True, throttle_at_s=0.1, throttle_at_max_s=0.2)
    assert missed_hand_aims({"right": late, "left": late}) == [
        "schedule: kill 4.30 s into its phase (its figures are not a kill's)"
    ]


def test_one_process_node_overrides_go_to_a_file_keyed_by_the_node(tmp_path):
    """``--with-node``: the node's ``-p`` overrides become a parameter file for ``skin_sim_node`` only (a ``-p`` reaches
    every node of the process, and the bridges stop on a parameter they do not have)."""
    import yaml

    from skin_sim_lab.perf.device_bench import node_params

    out = node_params(
        ("-p", "hand_ns:=right", "-p", "second_hand_ns:=left", "-p", "rate_hz:=500.0", "--log-level", "warn"), tmp_path
    )
    assert out[:2] == ("--log-level", "warn") and out[2] == "--params-file"
    assert yaml.safe_load(open(out[3])) == {
        "/**/skin_sim_node": {"ros__parameters": {"hand_ns": "right", "second_hand_ns": "left", "rate_hz": 500.0}}
    }
    assert node_params((), tmp_path) == ()


def test_a_run_that_raises_leaves_no_process_behind(tmp_path, monkeypatch):
    """The benchmark starts hogs, emulators (SCHED_FIFO 90) and stall probes outside its scene; a run that raises must
    not leave one of them running beside every later run (an emulator left spinning in its teardown did, session 11).
    Here the bare echo's baseline raises after a hog has started: the hog is gone when ``run`` has raised."""
    import subprocess

    from skin_sim_lab.perf import cpu_budget, device_bench

    class Proc:
        popen = type("P", (), {"pid": 1})()

        def log(self) -> str:
            return ""

    class FakeScene:  # stands for the ROS scene: node and bridge started, their logs empty
        env = {"ROS_DOMAIN_ID": "0", "ROS_AUTOMATIC_DISCOVERY_RANGE": "LOCALHOST"}

        def __init__(self, log_dir):
            pass

        def __enter__(self):
            return self

        def __exit__(self, *exc):
            return False

        def node(self, *args):
            return Proc()

        def start(self, *args):
            return Proc()

        def wait_for_log(self, *args, **kwargs):
            return None

    started = []

    class Recorded(subprocess.Popen):
        def __init__(self, *args, **kwargs):
            super().__init__(*args, **kwargs)
            started.append(self)

    def boom(scene):
        raise RuntimeError("the echo baseline failed")

    for var, value in FakeScene.env.items():
        monkeypatch.setenv(var, value)  # run() sets them from the scene; restored after the test
    monkeypatch.setattr(device_bench, "Scene", FakeScene)
    monkeypatch.setattr(cpu_budget, "echo_baseline", boom)
    monkeypatch.setattr(subprocess, "Popen", Recorded)
    try:
        with pytest.raises(RuntimeError, match="echo baseline"):
            device_bench.run(2.0, 1, tmp_path)
        assert len(started) == 1  # the hog
        assert all(p.poll() is not None for p in started)
    finally:
        for p in started:  # never leave a busy loop behind this test, whatever it found
            if p.poll() is None:
                p.kill()
                p.wait()


def test_a_process_cpu_is_split_by_its_threads_names():
    """``ProcCpu`` counts each thread's CPU under its group: a thread named ``skin-*`` under its name, the
    first thread as ``main``. A named thread that burns CPU shows it (50 ms of it, however long that takes); one
    asleep all that time shows almost none."""
    import os
    import threading
    import time

    from skin_sim_lab.perf.cpu_budget import ProcCpu, thread_group
    from skin_sim_node.ros_util import start_own_thread

    assert thread_group("skin-servo-0", 11, 10) == "skin-servo-0"
    assert thread_group("dds.udp.7412", 11, 10) == "dds"
    assert thread_group("python", 10, 10) == "main" and thread_group("python", 11, 10) == "other"
    stop = threading.Event()

    def burn():
        while not stop.is_set():
            sum(range(1000))

    threads = [threading.Thread(target=f, daemon=True) for f in (burn, stop.wait)]
    for t, name in zip(threads, ("test-burn", "test-idle")):
        start_own_thread(t, name)  # named when it returns
    cpu = ProcCpu(os.getpid(), threads=True)
    try:
        cpu.mark()
        # until the busy thread has 50 ms of CPU: no rate is asked of the machine, only that the split follows it
        t_end = time.monotonic() + 60.0
        while time.monotonic() < t_end:
            time.sleep(0.05)
            cpu.mark()
            if cpu.thread_pct(0, len(cpu.marks) - 1).get("skin-test-burn", 0.0) * (cpu.marks[-1][0] - cpu.marks[0][0]) >= 5.0:
                break
    finally:
        stop.set()
        for t in threads:
            t.join()
    pct = cpu.thread_pct(0, len(cpu.marks) - 1)
    span_s = cpu.marks[-1][0] - cpu.marks[0][0]
    assert pct["skin-test-burn"] * span_s >= 5.0, (pct, span_s)  # 50 ms of CPU: % x s / 100
    assert pct["skin-test-idle"] * span_s < 0.5, (pct, span_s)  # asleep: under 5 ms in all that time
    assert "main" in pct
