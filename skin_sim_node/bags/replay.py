"""``skin-sim replay BAG``: run the model over a bag's tool inputs offline (or ``--live`` against a node).

Offline: writes ``OUT/outputs`` (a rosbag2 of tool/wrench, tissue/contact and display grids),
``OUT/report.png`` and ``OUT/summary.json``, and prints the summary. ``--live`` then also
publishes the inputs to a node at recorded timing and compares its wrenches with the
offline ones (see :mod:`skin_sim_node.bags.live`). When the bag holds the wrenches its node
published (``/tool/wrench``, as ``skin-sim record`` writes), each is checked against the offline
answer to the poses that node answered (:mod:`skin_sim_node.bags.published`). Exit codes: 0 ok,
1 a published force disagrees with the offline answer (the recording's or the live node's) or the
live node answered too few poses, 2 unusable bag (the message names the problem).
"""

from __future__ import annotations

import argparse
import sys
import time
from pathlib import Path

from ..scenes import DEFAULT_PARAMS
from ..session import UNKNOWN_FRAME
from ..verdicts import verdict_line
from .compare import LIVE
from .inputs import add_input_arguments, input_options, read_inputs
from .io import STORAGES, BagError, custom_data
from .offline import replay, replay_to_bag
from .published import PublishedCheck, answered_only, check_published, format_check
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
        default=LIVE.force_rel,
        help=f"max |dF| allowed, fraction of peak (default {LIVE.force_rel}, as skin-sim compare)",
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
        recorded = custom_data(args.bag).get("skin_sim.params")
        shipped = DEFAULT_PARAMS.parent / recorded if recorded else None
        args.params = shipped if shipped is not None and shipped.is_file() else DEFAULT_PARAMS
        print(f"params: {args.params}" + (" (recorded with the bag)" if args.params == shipped else ""))
    if not args.params.is_file():  # before any output is written
        print(f"skin-sim replay: error: --params {args.params}: no such file", file=sys.stderr)
        return 2
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
