"""A stall is not a restart (issue 31 item 2), offline: the session's clock and the pose stamps, no DDS.

A needle (21 G and 18 G) goes in 5 mm at 10 mm/s and back out. The poses stop for 60, 150 or 500 ms at each phase
(before the skin's puncture, just after it, deep, withdrawing), past the 50 ms watchdog, in two ways:

- **held**: the hand holds still through the pause (the stamps resume where they stopped, later);
- **dropped**: the hand goes on and its poses in the pause are lost (the first pose after it is where the hand is).

After the pause the force is within 0.2 x the unpaused path's + 0.05 N of it at the same point of the path (the issue's
"within 1.2 x + 0.05 N", both ways: a force that collapsed fails too), no layer is
punctured twice, and the track keeps its entry. Where the hand reversed inside a dropped pause the path in between is
unknown to any server (the model takes the straight line): those cases are left out, and said so. With
``stall_hold_s`` 0 (a stall released at the watchdog, as before issue 31) the same check fails: the test can fail.
The path and the runs are :mod:`skin_sim_lab.validation.stall` (``skin-sim stall`` prints the table); the same over DDS
with the bridge: tests/test_stall_ros.py.
"""

from __future__ import annotations

import numpy as np
import pytest

from msgs_schema.parameters import SessionParams
from skin_sim_lab.validation.stall import (
    MS,
    PAUSES_MS,
    PHASES_S,
    START_M,
    T0,
    skipped,
)
from skin_sim_lab.validation.stall import excess_after as _excess_after
from skin_sim_lab.validation.stall import punctures as _punctures
from skin_sim_lab.validation.stall import run as _run
from skin_sim_node.session import STALL_RESUMED, WATCHDOG, HapticSession
from skin_sim_node.session.haptic import MAX_SUBSTEPS, substeps
from skin_sim_node.tools import make_tool


@pytest.fixture(scope="module", params=[21, 18])
def needle_base(request):
    return request.param, _run(request.param)[0]


@pytest.mark.parametrize("mode", ["held", "dropped"])
def test_a_stall_keeps_the_track_and_the_force_continues(needle_base, mode):
    gauge, base = needle_base
    assert base[-1][2] == 0 and _punctures(base) >= 2  # the unpaused path punctures the skin and leaves the tissue
    checked = 0
    for phase, at in PHASES_S.items():
        for pause in PAUSES_MS:
            if skipped(mode, at, pause):
                continue  # the hand turned inside the gap, or the path ended there
            rows, s = _run(gauge, at, pause, mode)
            assert s.counts[WATCHDOG] == 1 and s.counts[STALL_RESUMED] == 1, (phase, pause, dict(s.counts))
            excess = _excess_after(rows, base, at)
            assert excess <= 0.0, f"{gauge} G, {phase}, {pause} ms {mode}: {excess:+.3f} N off 0.2 x unpaused + 0.05 N"
            assert _punctures(rows) == _punctures(base), (phase, pause)  # no second puncture, none missed
            entries = {e for _, _, _, e in rows if e is not None}
            assert len(entries) == 1, (phase, pause, entries)  # one track: the stall did not start another
            checked += 1
    assert checked == (12 if mode == "held" else 6)


def test_a_stall_released_at_the_watchdog_restarts_the_needle_and_jolts():
    """The control: ``stall_hold_s`` 0 is the behaviour before issue 31 (the tissue released at the watchdog). The
    resumed withdrawal then meets a fresh insertion's push-out, above the bound the test above holds."""
    base = _run(21)[0]
    rows, s = _run(21, PHASES_S["withdrawing"], 60, "held", stall_hold_s=0.0)
    assert _excess_after(rows, base, PHASES_S["withdrawing"]) > 0.5
    k = next(i for i, r in enumerate(rows) if r[0] >= PHASES_S["withdrawing"])
    assert rows[k][2] < base[k][2]  # the cut layers forgotten: a fresh track where the needle stood


def test_the_tissue_keeps_its_arms_anchor_and_patch_through_a_stall(default_cfg):
    """A flat punch pressed 1.5 mm and dragged 0.5 mm (stick): a 150 ms stall holds the tool where it was, so the
    friction anchor and the patch stay, the viscoelastic arms relax under it as under a held hand, and the resumed
    force continues the unpaused one's (lower by that relaxation only)."""

    def path(k):
        return (0.5e-3 * min(max(k - 500, 0) / 100, 1.0), 0.0, -1.5e-3 * min(k / 300, 1.0))

    def run(pause_ms):
        s = HapticSession(make_tool(default_cfg), SessionParams(max_stamp_age_s=0.0))
        now, out, snap = T0, [], None
        for k in range(900):
            if k == 650 and pause_ms:
                snap = s.model.state()
                for _ in range(pause_ms):
                    now += MS
                    r = s.tick(now, MS)
                assert r.stale and not any(r.force_n)
            now += MS
            s.on_pose(T0 + k * MS + (pause_ms * MS if k >= 650 else 0), "tissue", path(k), now_ns=now)
            out.append(np.array(s.tick(now, MS).force_n))
        return np.array(out), s, snap

    base, _, _ = run(0)
    paused, s, snap = run(150)
    state = s.model.state()
    np.testing.assert_array_equal(state["centre"], snap["centre"])  # the patch stayed where the tool was
    after = paused[650:]
    assert np.all(np.linalg.norm(after, axis=1) <= 1.2 * np.linalg.norm(base[650:], axis=1) + 0.05)
    assert after[0][0] == pytest.approx(base[650][0], rel=0.05)  # the sideways (anchor) force is back, not restarted
    assert after[0][2] < base[650][2] and after[0][2] > 0.8 * base[650][2]  # relaxed under the held tool, not released


def test_a_long_interval_is_stepped_in_parts():
    assert substeps(0.05, 0.1) == 1 and substeps(0.1, 0.1) == 1 and substeps(0.25, 0.1) == 3
    assert substeps(100.0, 0.1) == MAX_SUBSTEPS and substeps(5.0, 0.0) == 1


@pytest.mark.parametrize("shape", ["needle", "flat"])
def test_a_stalled_live_session_answers_as_the_offline_replay_of_its_poses(default_cfg, shape):
    """The live session held the tissue unstepped through the stall and stepped the whole gap when poses resumed, as the
    offline replay (no clock: it never sees a stall) steps the same stamps: the same forces, bit for bit, once the
    published force has come back from the stall's zero at the rate bound (never a step; below the offline force
    meanwhile)."""
    cfg = default_cfg.replace(**{"tool.shape": shape})
    live = HapticSession(make_tool(cfg), SessionParams(max_stamp_age_s=0.0))
    offline = HapticSession(make_tool(cfg), SessionParams(max_stamp_age_s=0.0))
    now, prev, a, b = T0, None, [], []
    for k in range(900):
        stamp = T0 + k * MS + (300 * MS if k >= 400 else 0)  # the hand holds still for 300 ms at 3.5 mm
        if k == 400:
            for _ in range(300):
                now += MS
                assert live.tick(now, MS).stale or _ < 50
        now += MS
        xyz = (0.0, 0.0, START_M - 1e-5 * min(k, 400) + 1e-5 * max(k - 400, 0))
        live.on_pose(stamp, "tissue", xyz, now_ns=now, quat=(0.0, 0.0, 0.0, 1.0))
        a.append(live.tick(now, MS).force_n)
        offline.on_pose(stamp, "tissue", xyz, quat=(0.0, 0.0, 0.0, 1.0))
        b.append(offline.tick(stamp, 0 if prev is None else stamp - prev).force_n)
        prev = stamp
    assert live.counts[STALL_RESUMED] == 1 and offline.counts[STALL_RESUMED] == 0
    a, b = np.linalg.norm(a, axis=1), np.linalg.norm(b, axis=1)
    assert b.max() > 0.3 and b[400] > 0.1
    rate = live.params.max_force_rate_n_per_s * 1e-3  # N per 1 ms tick
    back = 400 + int(np.ceil(b[400] / rate)) + 1  # the ticks the force takes to come back at the rate bound
    assert np.all(np.diff(a[399:back]) <= rate + 1e-12) and np.all(a[400:back] <= b[400:back])
    np.testing.assert_array_equal(a[:400], b[:400])
    np.testing.assert_array_equal(a[back:], b[back:])
