"""Live replay: publish a bag's tool inputs to a running node at recorded timing and compare.

The recorded stamps are kept, so the node's wrench stamps equal the pose stamps and match
the offline replay's one for one. The node must not reject old stamps: a node started here
gets ``-p max_stamp_age_s:=0.0``; an ``--attach``-ed node must have been started with it.

The inputs are published by a process of its own (:mod:`.live_source`); this process records.
Before the first recorded pose a discovery handshake publishes lifted poses (at the first
pose's x, y, stamped 5 s before the bag) until the node answers one, then waits past the
watchdog: a lifted tool leaves the model at rest, the state the offline replay starts from, and
the first recorded pose, 5 s of stamps later (past ``stall_hold_s``), restarts contact as the
offline replay's first pose does. Within one stamp the twist is published first, so the
node's tick uses it, as the offline tick does.

A node with hands (issue 32, :func:`run_live_hands`): every hand's inputs go out in the offline two-hand replay's order
(:func:`skin_sim_node.bags.offline.merged_events`), with a handshake pose per hand, and each hand's wrenches are checked.
"""

from __future__ import annotations

import json
import subprocess
import sys
import time
from collections.abc import Sequence
from dataclasses import replace
from pathlib import Path

import numpy as np

from msgs_schema import convert as cv
from msgs_schema.topics import TOPICS, hand_topic

from ..scenes import REPO
from ..verdicts import verdict_line
from .compare import LIVE, describe, diff_outputs, verdict
from .inputs import POSE, Inputs
from .io import BagWriter, deserialize, qos_profiles
from .offline import ReplayResult, merged_events

HANDSHAKE_LEAD_NS = 5_000_000_000


LIVE_QUEUE_DEPTH = 500
"""Pose/twist reader history of the node a live replay starts. Replay wants every sample answered in order,
not the newest only. 10 covered a node descheduled for a few ms, but under ``LOCALHOST`` discovery Fast DDS can
freeze a process's receive path for ~333 ms while it opens a joining participant's shared-memory port
(eProsima/Fast-DDS#6535; ``docs/performance_rate.md``): the README's record -> replay --live -> compare sequence
then lost 324 of 2860 poses (one 386 ms hole) in one CI run of four. 500 holds half a second at 1 kHz."""


def _events_file(events: list[tuple], hands: Sequence[str], path: Path) -> None:
    """The merged events (:func:`merged_events`: ``(stamp, hand index, rank, frame, xyz, quat)``) as arrays for the
    publisher process, with each event's hand and the hands' names."""
    names = sorted({e[3] for e in events})
    np.savez(
        path,
        stamps=np.array([e[0] for e in events], dtype=np.int64),
        ranks=np.array([e[2] == POSE for e in events], dtype=np.int8),
        frame_names=np.array(names),
        frame_ids=np.array([names.index(e[3]) for e in events], dtype=np.int32),
        xyz=np.array([e[4] for e in events], dtype=np.float64).reshape(-1, 3),
        quat=np.array([e[5] or (0.0, 0.0, 0.0, 1.0) for e in events], dtype=np.float64).reshape(-1, 4),
        hands=np.array([e[1] for e in events], dtype=np.int8),
        hand_names=np.array(list(hands)),
    )


def _run_source(
    rec, inputs: Sequence[Inputs], hands: Sequence[str], speed: float, out: Path, timeout_s: float = 30.0
) -> tuple[dict, float]:
    """Start the publisher process, wait for every hand's node to answer a handshake pose, stream; returns its stats."""
    events = merged_events(inputs)
    first = min(e[0] for e in events if e[2] == POSE)
    base = first - HANDSHAKE_LEAD_NS
    path = (out / "live_inputs.npz").resolve()  # the publisher process runs in the repository folder
    _events_file(events, hands, path)
    argv = [
        sys.executable,
        "-m",
        "skin_sim_node.bags.live_source",
        str(path),
        "--speed",
        f"{speed}",
        "--handshake-base-ns",
        str(base),
    ]
    proc = subprocess.Popen(argv, stdin=subprocess.PIPE, stdout=subprocess.PIPE, text=True, cwd=REPO)
    try:
        t0 = time.perf_counter()
        end = time.monotonic() + timeout_s
        waiting = {_wrench_label(ns): ns for ns in hands}  # the hands whose node has not answered a handshake pose yet
        seen = 0
        while waiting:
            new = rec.records[seen:]  # the recorder's thread appends; read each record once
            seen += len(new)
            for k in [k for k in waiting if any(base <= s < first for s in live_forces(new, k))]:
                del waiting[k]
            if not waiting:
                break
            if time.monotonic() > end or proc.poll() is not None:
                names = ", ".join(sorted(ns or "(unnamed)" for ns in waiting.values()))
                raise TimeoutError(
                    "the node never answered a handshake pose"
                    + (f" of hand {names}" if hands != ("",) else "")
                    + ": is it running on this ROS_DOMAIN_ID, with max_stamp_age_s:=0.0?"
                )
            time.sleep(0.01)
        t_handshake = time.perf_counter() - t0
        assert proc.stdin is not None  # started with stdin=PIPE
        proc.stdin.write("go\n")
        proc.stdin.flush()
        span_s = (events[-1][0] - events[0][0]) * 1e-9 / speed
        stdout, _ = proc.communicate(timeout=span_s + timeout_s)
        return json.loads(stdout.strip().splitlines()[-1]), t_handshake
    finally:
        if proc.poll() is None:
            proc.kill()
            proc.wait()
        path.unlink(missing_ok=True)


def _wrench_label(ns: str) -> str:
    """The recorder's label of hand ``ns``'s wrenches: the key for the single-tool names, else the topic name."""
    return "tool_wrench" if not ns else hand_topic("tool_wrench", ns)


def recorder_labels(keys) -> dict[str, tuple[str, str]]:
    """``{label: (key, topic name)}`` for the :class:`~.recorder.Recorder`'s ``keys`` (a contract key, or
    ``(key, name)``): its label is the key where the name is the contract's (a hand ``''``, the single-tool names), else
    the name (``left/tool/wrench``)."""
    out = {}
    for k in keys:
        key, name = (k, TOPICS[k].name) if isinstance(k, str) else k
        out[key if name == TOPICS[key].name else name] = (key, name)
    return out


def force_tol_frac(args, hands: bool) -> float:
    """The live check's force tolerance, a fraction of the (hand's) offline peak.

    ``--force-tol-frac`` when given; otherwise ``compare``'s ``LIVE`` contract for one tool, and the recorded two-hand
    check's 5 % (``published.PUBLISHED_HANDS``, on top of its 0.01 N) with hands. A value given is used as given, the
    single-tool default included.
    """
    if args.force_tol_frac is not None:
        return float(args.force_tol_frac)
    if hands:
        from .published import PUBLISHED_HANDS

        return PUBLISHED_HANDS.force_rel
    return LIVE.force_rel


def live_forces(records, label: str = "tool_wrench") -> dict[int, np.ndarray]:
    """``{stamp_ns: force vector (N)}`` of the recorded live wrenches (``label``: a hand's, :func:`_wrench_label`)."""
    out = {}
    for _, key, raw in records:
        if key == label:
            stamp, _, f = cv.read_wrench(deserialize(raw, "geometry_msgs/msg/WrenchStamped"))
            out[stamp] = np.array(f, dtype=float)
    return out


def agreement(offline: ReplayResult, live: dict[int, np.ndarray]) -> dict:
    """Max and RMS force difference at matched stamps (whole vectors, :func:`diff_outputs`) and the fraction of
    poses answered."""
    d = diff_outputs((offline.forces_by_stamp(), {}), (live, {}))
    peak = offline.peak_force_n
    nan = float("nan")
    return {
        "offline_answered": d.n_a,
        "live_answered": d.matched,
        "fraction_answered": d.matched_fraction,
        "max_df_n": d.max_df_n if d.matched else nan,
        "rms_df_n": d.rms_df_n if d.matched else nan,
        "peak_force_n": peak,
        "max_df_frac_of_peak": d.max_df_n / peak if d.matched and peak > 0 else nan,
    }


def run_live(inputs: Inputs, offline: ReplayResult, args, out: Path, recorded=None) -> int:
    """Start (or attach to) a node, stream the inputs, record its outputs to ``out/live``, compare.

    ``recorded``: the bag's own published forces checked against offline
    (:class:`skin_sim_node.bags.published.PublishedCheck`), part of the verdict; None when the bag has none.
    Prints one closing line, ``PASS: ...`` or ``FAIL: ...``, naming each check; returns 0 or 1.
    """
    records, src, t_handshake = _stream_live([inputs], ("",), args, out)
    live = live_forces(records)
    stats = agreement(offline, live)
    span = (inputs.events[-1][0] - inputs.events[0][0]) * 1e-9
    stats.update({"speed": args.speed, "recorded_span_s": span, "handshake_s": t_handshake, **src})
    t_stream = src["stream_wall_s"]
    # the PASS is compare's verdict on the same two sets of wrenches (compare OUT/outputs OUT/live agrees)
    tol = replace(LIVE, force_rel=force_tol_frac(args, hands=False), min_matched=args.min_answered)
    fails = verdict(diff_outputs((offline.forces_by_stamp(), {}), (live, {})), tol)
    what = "live node's forces and answered fraction vs offline"
    checks = [(not fails, what + (f" ({'; '.join(fails)})" if fails else ""))]
    if recorded is not None:
        stats["recorded_max_df_n"] = recorded.diff.max_df_n
        stats["recorded_matched"] = recorded.diff.matched
        stats["recorded_agrees"] = recorded.ok
        what = "the bag's recorded forces vs offline"
        checks.append((recorded.ok, what + ("" if recorded.ok else f" ({'; '.join(recorded.fails)})")))
    ok = all(c for c, _ in checks)
    stats["live_pass"] = not fails
    stats["pass"] = bool(ok)
    (out / "live_summary.json").write_text(json.dumps(stats, indent=2) + "\n")
    print(
        f"live replay: streamed {span:.3f} s of inputs in {t_stream:.3f} s (speed {args.speed:g}; handshake {t_handshake:.2f} s) "
        f"-> {out / 'live'}\n"
        f"node answered {stats['live_answered']} of {stats['offline_answered']} poses ({stats['fraction_answered']:.2%}); "
        f"at matched stamps max |dF| = {stats['max_df_n']:.3e} N ({stats['max_df_frac_of_peak']:.3%} of peak "
        f"{offline.peak_force_n:.4f} N), RMS dF = {stats['rms_df_n']:.3e} N\n"
        f"publish lateness p50 {stats['publish_late_ms_p50']:.3f} ms, p99 {stats['publish_late_ms_p99']:.3f} ms, "
        f"max {stats['publish_late_ms_max']:.3f} ms\n"
        f"limits, as skin-sim compare's defaults: {describe(tol)}\n" + verdict_line("live replay", checks)
    )
    return 0 if ok else 1


def run_live_hands(
    inputs: Sequence[Inputs], offline: Sequence[ReplayResult], hands: Sequence[str], args, out: Path, recorded=None
) -> int:
    """:func:`run_live` for a node with hands (issue 32): every hand's inputs streamed in the offline replay's merged
    order, each hand's live wrenches checked.

    Each hand's check: the node answered at least ``--min-answered`` of the poses the offline replay answers
    (``offline``, one per hand), and its live forces agree with the offline two-hand replay of the poses the node
    answered (every hand's, :func:`skin_sim_node.bags.published.check_hands`) to 0.01 N + 5 % of the hand's offline
    peak, as a recording's (``PUBLISHED_HANDS``; ``--force-tol-frac``, when given, replaces the 5 %).
    ``recorded``: ``{hand: PublishedCheck}`` of the bag's own wrenches, part of the verdict. Prints one line per hand
    and one closing line naming each check; returns 0 or 1.
    """
    from .published import PUBLISHED_HANDS, check_hands, format_check

    records, src, t_handshake = _stream_live(inputs, tuple(hands), args, out)
    live = {ns: live_forces(records, _wrench_label(ns)) for ns in hands}
    tol = replace(PUBLISHED_HANDS, force_rel=force_tol_frac(args, hands=True))
    forces = check_hands(inputs, hands, args.params, live, tol) if any(live.values()) else {}
    events = merged_events(inputs)
    span = (events[-1][0] - events[0][0]) * 1e-9
    stats: dict = {"speed": args.speed, "recorded_span_s": span, "handshake_s": t_handshake, **src, "hands": {}}
    t0_ns = min(int(r.stamps_ns[0]) for r in offline)
    lines, checks = [], []
    for ns, res in zip(hands, offline):
        h = stats["hands"][ns] = agreement(res, live[ns])  # answered: of the poses the whole offline replay answers
        fails = (
            []
            if h["fraction_answered"] >= args.min_answered
            else [f"answered {h['fraction_answered']:.4f} of the offline answers < {args.min_answered}"]
        )
        head = f"hand {ns}: node answered {h['live_answered']} of {h['offline_answered']} poses ({h['fraction_answered']:.2%})"
        if ns in forces:
            c, unchecked = forces[ns]
            fails += c.fails
            h.update(answered_max_df_n=c.diff.max_df_n, answered_peak_n=c.diff.peak_a_n, unchecked=unchecked)
            line = format_check(c, head + "; live forces vs offline", t0_ns, tol)
            lines.append(line + (f" ({unchecked} later answers not checked)" if unchecked else ""))
        else:
            fails.append("no live wrench")
            lines.append(head + ": no live wrench")
        h["live_pass"] = not fails
        what = f"hand {ns}'s live forces and answered fraction vs offline"
        checks.append((not fails, what + (f" ({'; '.join(fails)})" if fails else "")))
    for ns, c in (recorded or {}).items():
        stats["hands"][ns].update(recorded_max_df_n=c.diff.max_df_n, recorded_matched=c.diff.matched, recorded_agrees=c.ok)
        what = f"hand {ns}'s recorded forces vs offline"
        checks.append((c.ok, what + ("" if c.ok else f" ({'; '.join(c.fails)})")))
    ok = all(c for c, _ in checks)
    stats["pass"] = bool(ok)
    (out / "live_summary.json").write_text(json.dumps(stats, indent=2) + "\n")
    print(
        f"live replay: streamed {span:.3f} s of inputs of hands {', '.join(hands)} in {src['stream_wall_s']:.3f} s "
        f"(speed {args.speed:g}; handshake {t_handshake:.2f} s) -> {out / 'live'}\n"
        + "\n".join(lines)
        + f"\npublish lateness p50 {stats['publish_late_ms_p50']:.3f} ms, p99 {stats['publish_late_ms_p99']:.3f} ms, "
        f"max {stats['publish_late_ms_max']:.3f} ms\n"
        f"limits per hand: >= {args.min_answered:.0%} of the offline answers answered; forces as a two-hand recording's "
        f"({describe(replace(tol, min_matched=0.0))})\n" + verdict_line("live replay", checks)
    )
    return 0 if ok else 1


def _stream_live(inputs: Sequence[Inputs], hands: Sequence[str], args, out: Path) -> tuple[list, dict, float]:
    """Start (or attach to) the node, stream every hand's inputs, write what it published to ``out/live``.

    Returns the kept records ``(rx_ns, label, cdr)`` (a hand's label: :func:`_wrench_label`), the publisher's stats and
    the handshake's wall time.
    """
    from ..scenes import Scene
    from .recorder import Recorder, use_scene_env

    scene = None if args.attach else Scene(out / "live_logs")
    if scene is not None:
        use_scene_env(scene.env)
    hand_keys = ["tool_wrench"] + (["contact"] if args.contact else [])
    tissue_keys = ["diagnostics"] + (["height_map", "layer_heights"] if args.images else [])
    if hands == ("",):  # the single-tool names, as before hands existed
        keys: list = hand_keys[:1] + tissue_keys[:1] + hand_keys[1:] + tissue_keys[1:]
    else:
        keys = [(k, hand_topic(k, ns)) for ns in hands for k in hand_keys] + tissue_keys
    topics = recorder_labels(keys)
    # kept in memory while streaming and written afterwards: no disk work competes with the node for the 2 cores
    rec = Recorder(keys, None, name="skin_sim_live_replay", keep=True)
    try:
        if scene is not None:
            # recorded stamps are old: no age check. Offline replay has no watchdog, so a scheduling
            # stall of the live node longer than 50 ms must not release the tissue mid-replay.
            # input_queue_depth LIVE_QUEUE_DEPTH: after a stall the node answers every queued pose in order
            extra = ["-p", "max_stamp_age_s:=0.0", "-p", "watchdog_s:=1.0", "-p", f"input_queue_depth:={LIVE_QUEUE_DEPTH}"]
            if not args.images:  # the display worker competes for the 2 cores; the comparison needs no grids
                extra += ["-p", "display_rate_hz:=0.0", "-p", "publish_mesh:=false"]
            node = scene.node(*extra, params=args.params)
            scene.wait_for_log(node, "live:", timeout_s=args.timeout_s)
        src, t_handshake = _run_source(rec, inputs, hands, args.speed, out)
        time.sleep(0.3)  # answers in flight
    finally:
        rec.close()
        if scene is not None:
            scene.stop_all()
    custom = {"skin_sim.source": inputs[0].bag.name}
    if hands != ("",):  # as the offline two-hand output (offline.replay_hands_to_bag): the view plays every hand
        custom.update({"skin_sim.hands": ",".join(hands), **({"skin_sim.params": Path(args.params).name} if args.params else {})})
    with BagWriter(out / "live", args.storage, custom_data=custom, overwrite=True) as w:
        for rx, label, raw in rec.records:
            key, name = topics[label]
            w.write_raw("/" + name, TOPICS[key].type, rx, raw, qos_profiles(key))
    return rec.records, src, t_handshake
