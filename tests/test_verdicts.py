"""Closing verdict lines: replay's check of a bag's recorded forces, soak's and scale's verdicts, the demo's checks."""

from __future__ import annotations

import shutil
from pathlib import Path

from msgs_schema import convert as cv
from skin_sim_node.bags import replay
from skin_sim_node.bags.io import BagWriter, deserialize, iter_raw, open_bag, qos_profiles, serialize, topic_types
from skin_sim_node.bags.published import answered_only, check_published, format_check
from skin_sim_node.verdicts import exit_code, verdict_line

DATA = Path(__file__).parent / "data"
PRESS = DATA / "press_hold_release"


def _with_recorded_wrenches(tmp_path, bump_n: float = 0.0, keep_every: int = 1) -> tuple[Path, int]:
    """The golden input bag plus ``/tool/wrench`` from its expected outputs (every ``keep_every``-th, as a node that
    skipped poses), one of them off by ``bump_n``; returns the bag and the bumped stamp."""
    bag = tmp_path / "recorded"
    wt = "/tool/wrench"
    with BagWriter(bag, "mcap") as w:
        for src, topics in ((PRESS / "input", None), (PRESS / "expected", [wt])):
            with open_bag(src) as r:
                types = topic_types(r)
                want = topics or list(types)
                for topic, msgtype, t_ns, raw in iter_raw(src, r, want):
                    w.write_raw(topic, msgtype, t_ns, raw)
    # rewrite the wrench topic with a bump: read back, patch, write a second bag
    out = tmp_path / "recorded2"
    bumped = None
    k = 0
    with open_bag(bag) as r, BagWriter(out, "mcap") as w:
        types = topic_types(r)
        for topic, msgtype, t_ns, raw in iter_raw(bag, r, list(types)):
            if topic == wt:
                k += 1
                if k % keep_every:
                    continue
                msg = deserialize(raw, msgtype)
                if bump_n and bumped is None and msg.wrench.force.z > 0.5 * 0.5:
                    msg.wrench.force.z += bump_n
                    bumped = cv.stamp_ns(msg.header)
                raw = serialize(msg, msgtype)
                w.write_raw(topic, msgtype, t_ns, raw, qos_profiles("tool_wrench"))
            else:
                w.write_raw(topic, msgtype, t_ns, raw)
    shutil.rmtree(bag)
    return out, bumped


def test_replay_passes_a_recording_whose_forces_are_the_offline_answer(tmp_path, capsys):
    bag, _ = _with_recorded_wrenches(tmp_path, keep_every=3)  # a node that answered every third pose only
    assert replay.main([str(bag), "--out", str(tmp_path / "o"), "--no-report", "--grid-rate-hz", "0"]) == 0
    out = capsys.readouterr().out
    assert "recorded forces vs offline:" in out and ": agrees" in out
    assert out.strip().splitlines()[-1] == "replay PASS: the bag's recorded forces vs offline"


def test_replay_fails_a_recording_that_disagrees_with_the_offline_answer(tmp_path, capsys):
    bag, stamp = _with_recorded_wrenches(tmp_path, bump_n=4.5)
    assert stamp is not None
    assert replay.main([str(bag), "--out", str(tmp_path / "o"), "--no-report", "--grid-rate-hz", "0"]) == 1
    out = capsys.readouterr().out
    assert "DISAGREES" in out and "max |dF| 4.500e+00 N" in out
    assert out.strip().splitlines()[-1].startswith("replay FAIL: the bag's recorded forces vs offline")


def test_replay_of_a_bag_without_wrenches_prints_no_recorded_check(tmp_path, capsys):
    assert replay.main([str(PRESS / "input"), "--out", str(tmp_path / "o"), "--no-report", "--grid-rate-hz", "0"]) == 0
    assert "recorded forces" not in capsys.readouterr().out


def test_check_published_names_the_worst_stamp():
    off = {1: 0.0, 2: 1.0, 3: 2.0}
    c = check_published(off, {2: 1.0, 3: 2.5, 9: 7.0})  # 9 answers no replayed pose: not held against it
    assert not c.ok and c.worst_stamp_ns == 3 and c.worst == (2.5, 2.0)
    assert "published 2.5000 N, offline 2.0000 N" in format_check(c, "x", t0_ns=1)
    assert check_published(off, {2: 1.0 + 1e-3}).ok  # within 1 % of the 2 N peak
    nothing = check_published(off, {7: 1.0})
    assert not nothing.ok and any("no published wrench" in f for f in nothing.fails)


def test_answered_only_keeps_twists_and_the_answered_poses():
    from skin_sim_node.bags.inputs import InputOptions, read_inputs

    inputs = read_inputs(PRESS / "input", InputOptions())
    stamps = {e[0] for e in inputs.events[::7] if e[1] == 1}
    sub = answered_only(inputs, stamps)
    assert sub.n_poses == len(stamps) and {e[0] for e in sub.events if e[1] == 1} == stamps
    assert sum(e[1] == 0 for e in sub.events) == sum(e[1] == 0 for e in inputs.events)


def test_verdict_line_names_failed_and_passed():
    checks = [(True, "a"), (False, "b (3 > 1)"), (True, "c")]
    assert verdict_line("soak", checks) == "soak FAIL: b (3 > 1); passed: a; c"
    assert verdict_line("soak", checks[::2]) == "soak PASS: a; c"
    assert verdict_line("soak", []) == "soak FAIL: nothing was checked"
    assert exit_code(checks) == 1 and exit_code(checks[::2]) == 0 and exit_code([]) == 1


def _soak_figures(growth=0.05, gaps=0, stale=0):
    phase = {"stale_model": stale, "rendered": 1000}
    return {
        "node_rss_growth_pct": growth,
        "stamp_gaps": {"gaps_over_limit": gaps, "max_gap_ms": 31.5 if gaps else 2.0},
        "device_phases": {"steady": dict(phase, stale_model=0), "throttled 250 Hz": phase},
    }


def test_soak_verdict_names_the_missed_aim():
    from skin_sim_lab.perf.soak import soak_checks

    good = soak_checks(_soak_figures())
    assert exit_code(good) == 0 and verdict_line("soak", good).startswith("soak PASS: node memory growth +0.050 %")
    bad = soak_checks(_soak_figures(gaps=1297, stale=3))
    line = verdict_line("soak", bad)
    assert exit_code(bad) == 1
    assert line.startswith("soak FAIL: 1297 force-stream gaps over 5.0 ms (longest 31.50 ms; aim: none); device, throttled")
    assert "passed: node memory growth" in line and "3 of 1000 ticks" in line
    assert exit_code(soak_checks(_soak_figures(growth=float("nan")))) == 1  # no memory figure: not met


def _scale_row(n, missed):
    return {"sessions": n, "per_session": [{"node_missed_pct": m} for m in missed], "worst_missed_pct": max(missed)}


def test_scale_verdict_says_which_session_missed_how_much():
    from skin_sim_lab.perf.scale import scale_checks, sessions_held

    rows = [_scale_row(1, [0.05]), _scale_row(2, [0.02, 7.8])]
    assert sessions_held(rows) == 1
    checks = scale_checks(rows, 2)
    line = verdict_line("scale", checks)
    assert exit_code(checks) == 1
    assert line == (
        "scale FAIL: 2 session(s): /s2 missed 7.800 % of ticks (limit 0.1 %); passed: 1 session(s): worst missed 0.050 % <= 0.1 %"
    )
    assert sessions_held([_scale_row(1, [7.8])]) == 0
    assert exit_code(scale_checks(rows[:1], 1)) == 0
    stopped = scale_checks(rows[:1], 3)  # the run stopped before 2 and 3 were measured
    assert exit_code(stopped) == 1 and "2..3 sessions not measured" in verdict_line("scale", stopped)


def test_scale_progress_moves_within_a_stage_and_ends_at_its_total():
    import time

    from skin_sim_lab.perf.scale import WaitingProgress

    p = WaitingProgress([5.0, 5.0], "test")
    try:
        p.stage("first", 5.0)
        end = time.monotonic() + 30.0
        while p.bar.n < 1 and time.monotonic() < end:  # a condition, not a rate: generous timeout
            time.sleep(0.05)
        assert p.bar.n >= 1  # the bar moved before the stage ended
        p.stage("second", 5.0)
        assert p.bar.n == 5  # the first stage's estimate, whatever the ticker had done
    finally:
        p.close()
    assert p.bar.n == 10
