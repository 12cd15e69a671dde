"""``skin-sim replay BAG``: run the model over a bag's tool inputs offline (or ``--live`` against a node).

Offline: writes ``OUT/outputs`` (a rosbag2 of tool/wrench, tissue/contact and display grids),
``OUT/report.png`` and ``OUT/summary.json``, and prints the summary. ``--live`` then also
publishes the inputs to a node at recorded timing and compares its wrenches with the
offline ones (see :mod:`skin_sim_node.bags.live`; with hands, every hand's). When the bag holds the wrenches its node
published (``/tool/wrench``, as ``skin-sim record`` writes), each is checked against the offline
answer to the poses that node answered (:mod:`skin_sim_node.bags.published`). Exit codes: 0 ok,
1 a published force disagrees with the offline answer (the recording's or the live node's) or the
live node answered too few poses, 2 unusable bag (the message names the problem).
"""

from __future__ import annotations

import argparse
import json
import sys
import time
from pathlib import Path

from msgs_schema.topics import hand_topic

from ..scenes import DEFAULT_PARAMS
from ..session import UNKNOWN_FRAME
from ..verdicts import verdict_line
from .compare import LIVE
from .inputs import add_input_arguments, input_options, read_hand_inputs, read_inputs
from .io import STORAGES, BagError, recorded_params
from .offline import hands_of, replay, replay_hands_to_bag, replay_to_bag
from .published import PUBLISHED_HANDS, PublishedCheck, answered_only, check_hands, check_published, format_check
from .report import format_summary, write_report


def build_parser() -> argparse.ArgumentParser:
    ap = argparse.ArgumentParser(prog="skin-sim replay", description=__doc__.splitlines()[0])
    ap.add_argument("bag", type=Path, help="rosbag2 folder (MCAP or sqlite3) or a single .mcap/.db3 file")
    ap.add_argument("--out", type=Path, help="output folder (default out/replay/<bag name>)")
    ap.add_argument(
        "--params",
        type=Path,
        default=None,
        help="node parameter file (default: the shipped preset the bag was recorded with, skin-sim record's "
        "skin_sim.params, else config/default.yaml)",
    )
    ap.add_argument("--storage", choices=sorted(STORAGES), default="mcap", help="output bag storage (default mcap)")
    ap.add_argument("--grid-rate-hz", type=float, default=60.0, help="display grids per second of stamp time (0: none)")
    ap.add_argument("--no-report", action="store_true", help="skip report.png")
    add_input_arguments(ap)
    g = ap.add_argument_group("live replay")
    g.add_argument("--live", action="store_true", help="also replay against a running node and compare")
    g.add_argument("--speed", type=float, default=1.0, help="playback speed factor (default 1.0: recorded timing)")
    g.add_argument("--attach", action="store_true", help="use an already running node (it needs max_stamp_age_s:=0.0)")
    g.add_argument("--images", action="store_true", help="also record the node's display grids in the live bag")
    g.add_argument("--contact", action="store_true", help="also record tissue/contact in the live bag (more load on 2 cores)")
    g.add_argument(
        "--force-tol-frac",
        type=float,
        default=None,
        help=f"max |dF| allowed, fraction of peak (default {LIVE.force_rel}, as skin-sim compare; with hands the default is "
        "0.01 N + 5 %% of each hand's peak, and a value given replaces the 5 %%)",
    )
    g.add_argument(
        "--min-answered",
        type=float,
        default=LIVE.min_matched,
        help=f"min fraction of poses answered (default {LIVE.min_matched}, as skin-sim compare)",
    )
    g.add_argument("--timeout-s", type=float, default=180.0, help="node start-up timeout (numba warm-up, discovery)")
    return ap


def main(argv=None) -> int:
    args = build_parser().parse_args(argv)
    out = args.out or Path("out/replay") / args.bag.resolve().name
    if args.params is None:  # a needle bag replayed with the flat punch's preset would disagree with its own forces
        shipped = recorded_params(args.bag)
        args.params = shipped or DEFAULT_PARAMS
        print(f"params: {args.params}" + (" (recorded with the bag)" if shipped is not None else ""))
    if not args.params.is_file():  # before any output is written
        print(f"skin-sim replay: error: --params {args.params}: no such file", file=sys.stderr)
        return 2
    hands = hands_of(args.params)
    if hands != ("",):  # the node's hands (hand_ns, second_hand_ns): each hand's topics under its namespace
        return replay_hands_main(args, out, hands)
    try:
        inputs = read_inputs(args.bag, input_options(args))
        t0 = time.perf_counter()
        res = replay_to_bag(inputs, out / "outputs", args.params, args.storage, args.grid_rate_hz)
        t_replay = time.perf_counter() - t0
    except BagError as exc:
        print(f"skin-sim replay: error: {exc}", file=sys.stderr)
        return 2
    hint = inputs.frame_hint(res.tissue_frame) if res.counts.get(UNKNOWN_FRAME) else None
    if res.stamps_ns.size == 0:
        print(
            f"skin-sim replay: error: {args.bag}: none of {res.n_poses} poses was answered ("
            + (", ".join(f"{k} {v}" for k, v in sorted(res.counts.items())) or "no events")
            + ")"
            + (f"; {hint}" if hint else ""),
            file=sys.stderr,
        )
        return 2
    summary = write_report(res, out, title=f"offline replay of {args.bag}") if not args.no_report else res.summary()
    print(
        f"offline replay of {args.bag} ({inputs.pose_topic}"
        + (f", {inputs.twist_topic}" if inputs.twist_topic else "")
        + f") in {t_replay:.2f} s -> {out / 'outputs'}"
    )
    print(format_summary(summary))
    if hint:
        print(f"note: {hint}")
    if not args.no_report:
        print(f"report: {out / 'report.png'} (force over time; surface and cross-section at peak force), {out / 'summary.json'}")
    checked = check_recording(args, inputs)
    if checked is not None:
        print(format_check(checked, "recorded forces vs offline", int(res.stamps_ns[0])))
    if not args.live:
        if checked is not None:
            print(verdict_line("replay", [(checked.ok, "the bag's recorded forces vs offline")]))
        return 0 if checked is None or checked.ok else 1
    from .live import run_live

    return run_live(inputs, res, args, out, recorded=checked)


HAND_OPTIONS = ("pose_topic", "twist_topic", "convention")
"""Foreign-bag options that name one tool's topics: a parameter file with hands names each hand's."""


def replay_hands_main(args, out: Path, hands: tuple[str, ...]) -> int:
    """``replay`` of a bag of a node with hands (issue 32): every hand through the one tissue, each hand reported.

    Writes ``OUT/outputs`` (each hand's ``<hand>/tool/wrench`` and ``<hand>/tissue/contact``, the tissue's grids),
    ``OUT/<hand>/report.png`` and ``OUT/<hand>/summary.json`` per hand and ``OUT/summary.json`` (every hand), and checks
    each hand's recorded wrenches against the offline answer. Returns the exit code.
    """
    named = [f"--{o.replace('_', '-')}" for o in HAND_OPTIONS if getattr(args, o) is not None]
    if named:
        print(
            f"skin-sim replay: error: {' '.join(named)}: {args.params} names the hands {', '.join(hands)} (hand_ns, "
            "second_hand_ns), whose topics are <hand>/tool/pose and <hand>/tool/twist; give a single-hand --params "
            "to replay one tool's topics",
            file=sys.stderr,
        )
        return 2
    try:
        inputs = read_hand_inputs(args.bag, hands, args.frame)
        t0 = time.perf_counter()
        results = replay_hands_to_bag(inputs, out / "outputs", args.params, args.storage, args.grid_rate_hz)
        t_replay = time.perf_counter() - t0
    except BagError as exc:
        print(f"skin-sim replay: error: {exc}", file=sys.stderr)
        return 2
    for ns, inp, res in zip(hands, inputs, results):
        if res.stamps_ns.size == 0:
            hint = inp.frame_hint(res.tissue_frame) if res.counts.get(UNKNOWN_FRAME) else None
            print(
                f"skin-sim replay: error: {args.bag}: none of hand {ns}'s {res.n_poses} poses was answered ("
                + (", ".join(f"{k} {v}" for k, v in sorted(res.counts.items())) or "no events")
                + ")"
                + (f"; {hint}" if hint else ""),
                file=sys.stderr,
            )
            return 2
    print(f"offline replay of {args.bag} (hands {', '.join(hands)}) in {t_replay:.2f} s -> {out / 'outputs'}")
    summaries = {}
    for ns, inp, res in zip(hands, inputs, results):
        title = f"offline replay of {args.bag}, hand {ns} (the pictures: this hand's own field)"
        summaries[ns] = write_report(res, out / ns, title=title) if not args.no_report else res.summary()
        twist = f", {inp.twist_topic}" if inp.twist_topic else ""
        print(f"hand {ns} ({inp.pose_topic}{twist}): {format_summary(summaries[ns])}")
    out.mkdir(parents=True, exist_ok=True)
    (out / "summary.json").write_text(json.dumps({"hands": summaries}, indent=2) + "\n")
    if not args.no_report:
        print(
            f"report: {', '.join(str(out / ns / 'report.png') for ns in hands)} (force over time; each hand's own field), "
            f"{out / 'summary.json'}"
        )
    checks = check_recording_hands(args.bag, args.params, inputs, hands)
    if checks:
        t0_ns = min(int(r.stamps_ns[0]) for r in results)
        for ns, (c, unchecked) in checks.items():
            line = format_check(c, f"hand {ns}: recorded forces vs offline", t0_ns, PUBLISHED_HANDS)
            print(line + (f" ({unchecked} later answers not checked: see below)" if unchecked else ""))
        if any(u for _, u in checks.values()):
            print(
                "note: answers after another hand's last pose are not checked: the node then ticks that hand on its "
                "fallback clock (its field relaxes under the other tool), which the offline replay does not emulate"
            )
    if args.live:
        from .live import run_live_hands

        return run_live_hands(inputs, results, hands, args, out, recorded={ns: c for ns, (c, _) in checks.items()})
    if not checks:
        return 0
    print(verdict_line("replay", [(c.ok, f"hand {ns}'s recorded forces vs offline") for ns, (c, _) in checks.items()]))
    return 0 if all(c.ok for c, _ in checks.values()) else 1


def check_recording_hands(bag, params, inputs, hands) -> dict[str, tuple[PublishedCheck, int]]:
    """Each hand's recorded ``<hand>/tool/wrench`` against the offline answer of the one tissue to the poses the
    recording node answered (:func:`skin_sim_node.bags.published.check_hands`): ``{hand: (check, answers not
    checked)}``, empty without recorded wrenches."""
    from .compare import read_outputs

    published = {}
    for ns in hands:
        try:
            published[ns], _ = read_outputs(bag, hand_topic("tool_wrench", ns), grids=False)
        except BagError:
            published[ns] = {}
    if not any(published.values()):
        return {}
    return check_hands(inputs, hands, params, published, PUBLISHED_HANDS)


def check_recording(args, inputs) -> PublishedCheck | None:
    """The bag's own ``/tool/wrench`` (what its node published) against the offline answer, or None without one.

    Only the poses the recording node answered are replayed (their stamps are the wrench stamps), so a pose
    the node skipped does not count against it.
    """
    from .compare import read_outputs

    try:
        published, _ = read_outputs(args.bag, grids=False)
    except BagError:
        return None
    if not published:
        return None
    res = replay(answered_only(inputs, set(published)), args.params, None, 0.0)
    return check_published(res.forces_by_stamp(), published)


if __name__ == "__main__":
    raise SystemExit(main())
