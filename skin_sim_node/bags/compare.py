"""``skin-sim compare BAG_A BAG_B``: diff two output bags (force and grids) with tolerances.

Wrenches are matched by header stamp; the force check is ``max |F_A - F_B| <= force_abs_n
+ force_rel * peak |F_A|`` over matched stamps, and at least ``min_matched`` of the stamps
of either bag must be matched. Grids (``tissue/layer_heights``) are matched by stamp too;
``max |dz| <= grid_m`` over matched frames. Exit 0: within tolerances, 1: they differ,
2: a bag cannot be used. The defaults suit two offline replays (same model, same inputs).
"""

from __future__ import annotations

import argparse
import sys
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from msgs_schema import convert as cv
from msgs_schema.topics import TOPICS

from .io import BagError, UnknownMessageTypeError, describe_topics, iter_messages, open_bag, topic_types

FORCE_ABS_N = 1e-6
FORCE_REL = 1e-6
GRID_M = 1e-9


class NoOutputTopicError(BagError):
    """An output bag has no wrench topic."""


def _topic(types: dict[str, str], name: str) -> str | None:
    for t in (name, "/" + name.lstrip("/"), name.lstrip("/")):
        if t in types:
            return t
    return None


def read_outputs(bag, wrench_topic: str = TOPICS["tool_wrench"].name, grid_topic: str = TOPICS["layer_heights"].name,
                 grids: bool = True) -> tuple[dict[int, float], dict[int, np.ndarray]]:  # fmt: skip
    """``({stamp_ns: fz}, {stamp_ns: layer_heights})`` of an output bag."""
    bag = Path(bag)
    with open_bag(bag) as reader:
        types = topic_types(reader)
        wt = _topic(types, wrench_topic)
        if wt is None:
            raise NoOutputTopicError(f"{bag}: no wrench topic '{wrench_topic}'; topics present: {describe_topics(types)}")
        if types[wt] != TOPICS["tool_wrench"].type:
            raise UnknownMessageTypeError(
                f"{bag}: unknown message type '{types[wt]}' on wrench topic '{wt}' (expected {TOPICS['tool_wrench'].type})"
            )
        gt = _topic(types, grid_topic) if grids else None
        forces, images = {}, {}
        for topic, _, _, msg in iter_messages(bag, reader, [t for t in (wt, gt) if t]):
            if topic == wt:
                stamp, _, f = cv.read_wrench(msg)
                forces[stamp] = f[2]
            else:
                images[cv.stamp_ns(msg.header)] = cv.read_image(msg)
    return forces, images


@dataclass
class Diff:
    """Force and grid differences of B against A."""

    n_a: int
    n_b: int
    matched: int
    max_df_n: float
    rms_df_n: float
    peak_a_n: float
    grids_a: int
    grids_b: int
    grids_matched: int
    max_dz_m: float

    @property
    def matched_fraction(self) -> float:
        return self.matched / max(self.n_a, self.n_b, 1)


def diff_outputs(a: tuple[dict, dict], b: tuple[dict, dict]) -> Diff:
    (fa, ga), (fb, gb) = a, b
    common = sorted(set(fa) & set(fb))
    da = np.array([fa[s] for s in common]) - np.array([fb[s] for s in common]) if common else np.zeros(0)
    peak = max((abs(v) for v in fa.values()), default=0.0)
    gc = sorted(set(ga) & set(gb))
    dz = max((float(np.max(np.abs(ga[s] - gb[s]))) if ga[s].shape == gb[s].shape else float("inf") for s in gc), default=0.0)
    return Diff(
        len(fa), len(fb), len(common),
        float(np.max(np.abs(da))) if da.size else 0.0, float(np.sqrt(np.mean(da**2))) if da.size else 0.0, peak,
        len(ga), len(gb), len(gc), dz,
    )  # fmt: skip


def verdict(d: Diff, force_abs_n=FORCE_ABS_N, force_rel=FORCE_REL, grid_m=GRID_M, min_matched=1.0) -> list[str]:
    """The failed checks (empty: within tolerances)."""
    fails = []
    tol = force_abs_n + force_rel * d.peak_a_n
    if d.max_df_n > tol:
        fails.append(f"max |dF| {d.max_df_n:.3e} N > {tol:.3e} N")
    if d.matched_fraction < min_matched:
        fails.append(f"matched {d.matched_fraction:.4f} of wrench stamps < {min_matched}")
    if d.grids_matched and d.max_dz_m > grid_m:
        fails.append(f"max |dz| {d.max_dz_m:.3e} m > {grid_m:.3e} m")
    if (d.grids_a or d.grids_b) and d.grids_matched < min_matched * max(d.grids_a, d.grids_b):
        fails.append(f"matched {d.grids_matched} of {max(d.grids_a, d.grids_b)} grid frames")
    return fails


def format_table(d: Diff, a: str = "A", b: str = "B") -> str:
    rows = [
        ("wrenches", f"{d.n_a}", f"{d.n_b}", f"{d.matched} matched ({d.matched_fraction:.2%})"),
        ("peak |F| (N)", f"{d.peak_a_n:.6f}", "", ""),
        ("max |dF| (N)", "", "", f"{d.max_df_n:.3e}"),
        ("RMS dF (N)", "", "", f"{d.rms_df_n:.3e}"),
        ("grid frames", f"{d.grids_a}", f"{d.grids_b}", f"{d.grids_matched} matched"),
        ("max |dz| (m)", "", "", f"{d.max_dz_m:.3e}"),
    ]
    w = 12
    head = [f"{'':14s} {'A':>{w}} {'B':>{w}}  difference"]
    return "\n".join([f"A: {a}", f"B: {b}", *head, *(f"{r[0]:14s} {r[1]:>{w}} {r[2]:>{w}}  {r[3]}" for r in rows)])


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(prog="skin-sim compare", description=__doc__.splitlines()[0])
    ap.add_argument("bag_a", type=Path, help="reference output bag")
    ap.add_argument("bag_b", type=Path, help="output bag to check")
    ap.add_argument("--force-abs-n", type=float, default=FORCE_ABS_N, help=f"absolute force tolerance (N, default {FORCE_ABS_N})")
    ap.add_argument(
        "--force-rel", type=float, default=FORCE_REL, help=f"force tolerance, fraction of A's peak (default {FORCE_REL})"
    )
    ap.add_argument("--grid-m", type=float, default=GRID_M, help=f"grid height tolerance (m, default {GRID_M})")
    ap.add_argument("--min-matched", type=float, default=1.0, help="min fraction of stamps matched (default 1.0)")
    ap.add_argument("--no-grids", action="store_true", help="compare forces only")
    ap.add_argument("--wrench-topic", default=TOPICS["tool_wrench"].name)
    ap.add_argument("--grid-topic", default=TOPICS["layer_heights"].name)
    args = ap.parse_args(argv)
    try:
        a = read_outputs(args.bag_a, args.wrench_topic, args.grid_topic, not args.no_grids)
        b = read_outputs(args.bag_b, args.wrench_topic, args.grid_topic, not args.no_grids)
    except BagError as exc:
        print(f"skin-sim compare: error: {exc}", file=sys.stderr)
        return 2
    d = diff_outputs(a, b)
    print(format_table(d, str(args.bag_a), str(args.bag_b)))
    fails = verdict(d, args.force_abs_n, args.force_rel, args.grid_m, args.min_matched)
    print("DIFFERENT: " + "; ".join(fails) if fails else "SAME within tolerances")
    return 1 if fails else 0


if __name__ == "__main__":
    raise SystemExit(main())
