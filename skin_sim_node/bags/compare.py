"""``skin-sim compare BAG_A BAG_B``: diff two output bags (force and grids) with tolerances.

Wrenches are matched by header stamp; the force check is ``max |F_A - F_B| <= force_abs_n
+ force_rel * peak |F_A|`` over matched stamps, and at least ``min_matched`` of A's (the
reference's) stamps must be found in B. Grids (``tissue/layer_heights``) are matched by stamp
too; ``max |dz| <= grid_m`` over matched frames. Exit 0: within tolerances, 1: they differ,
2: a bag cannot be used.

The defaults are :data:`LIVE`, the same contract as ``skin-sim replay --live``'s PASS (force
within 1 % of peak, 95 % of the reference's poses answered; wrenches of B that answer no pose
of A, such as the live node's fallback-clock ticks, are counted but not held against it), so
``compare OUT/outputs OUT/live`` agrees with the replay that wrote them. ``--exact``
(:data:`EXACT`) is for two offline replays: equal to 1e-6, every stamp in both.
"""

from __future__ import annotations

import argparse
import sys
from dataclasses import dataclass, replace
from pathlib import Path

import numpy as np

from msgs_schema import convert as cv
from msgs_schema.topics import TOPICS

from .io import BagError, UnknownMessageTypeError, describe_topics, iter_messages, open_bag, topic_types


@dataclass(frozen=True)
class Tolerances:
    """When two output bags count as the same.

    Attributes
    ----------
    force_abs_n, force_rel : float
        ``max |dF| <= force_abs_n + force_rel * peak |F_A|`` over matched stamps.
    min_matched : float
        Fraction of A's wrench (and grid) stamps that B must hold.
    max_extra : float
        Fraction of B's wrench stamps allowed to be absent from A (inf: any).
    grid_m : float
        ``max |dz|`` over matched grid frames (m).
    """

    force_abs_n: float
    force_rel: float
    min_matched: float
    max_extra: float
    grid_m: float


LIVE = Tolerances(force_abs_n=0.0, force_rel=0.01, min_matched=0.95, max_extra=float("inf"), grid_m=1e-9)
"""Live node against offline replay (``replay --live`` PASS and ``compare``'s default). 1 % of peak: the
node runs the same session code on the same stamps, so forces agree to 0-0.3 % (docs/bags.md); 95 %:
the haptic QoS keeps the newest pose only, and a node descheduled for a few ms on a loaded machine skips
some (92-98 % measured on a 2-core VM)."""

EXACT = Tolerances(force_abs_n=1e-6, force_rel=1e-6, min_matched=1.0, max_extra=0.0, grid_m=1e-9)
"""Two offline replays of the same inputs (a CI gate on a model change): the same stamps, forces to 1e-6."""


class NoOutputTopicError(BagError):
    """An output bag has no wrench topic."""


def _topic(types: dict[str, str], name: str) -> str | None:
    for t in (name, "/" + name.lstrip("/"), name.lstrip("/")):
        if t in types:
            return t
    return None


def read_outputs(
    bag, wrench_topic: str = TOPICS["tool_wrench"].name, grid_topic: str = TOPICS["layer_heights"].name, grids: bool = True
) -> tuple[dict[int, np.ndarray], dict[int, np.ndarray]]:
    """``({stamp_ns: force vector (fx, fy, fz)}, {stamp_ns: layer_heights})`` of an output bag."""
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
                forces[stamp] = np.array(f, dtype=float)
            else:
                images[cv.stamp_ns(msg.header)] = cv.read_image(msg)
    return forces, images


def hand_wrench_topics(bag) -> list[str]:
    """The hands' wrench topics of an output bag without ``/tool/wrench``: ``/<hand>/tool/wrench`` (a node with hands,
    issue 32), sorted; empty for a single-tool bag."""
    bag = Path(bag)
    with open_bag(bag) as reader:
        types = topic_types(reader)
    name, wtype = TOPICS["tool_wrench"].name, TOPICS["tool_wrench"].type
    if _topic(types, name) is not None:
        return []
    return sorted(t for t, ty in types.items() if ty == wtype and t.endswith("/" + name) and t.count("/") == 3)


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
        """Fraction of A's (the reference's) wrench stamps found in B."""
        return self.matched / max(self.n_a, 1)

    @property
    def extra_fraction(self) -> float:
        """Fraction of B's wrench stamps that A does not hold."""
        return (self.n_b - self.matched) / max(self.n_b, 1)


def _norms(f: np.ndarray) -> np.ndarray:
    """Magnitudes of a stack of force vectors ``(n, 3)``, or of scalars ``(n,)``."""
    return np.linalg.norm(f, axis=-1) if f.ndim == 2 else np.abs(f.reshape(-1))


def diff_outputs(a: tuple[dict, dict], b: tuple[dict, dict]) -> Diff:
    """B against A, each ``(wrenches, grids)`` of :func:`read_outputs`: forces at common stamps, grids by shape and height."""
    (fa, ga), (fb, gb) = a, b
    """Force and grid differences of B against A; forces are vectors (or scalars), compared as a whole: ``|F_A - F_B|``."""
    common = sorted(set(fa) & set(fb))
    da = _norms(np.array([fa[s] for s in common], dtype=float) - np.array([fb[s] for s in common], dtype=float))
    peak = float(_norms(np.array(list(fa.values()), dtype=float)).max(initial=0.0))
    gc = sorted(set(ga) & set(gb))
    dz = max((float(np.max(np.abs(ga[s] - gb[s]))) if ga[s].shape == gb[s].shape else float("inf") for s in gc), default=0.0)
    return Diff(
        len(fa),
        len(fb),
        len(common),
        float(np.max(np.abs(da))) if da.size else 0.0,
        float(np.sqrt(np.mean(da**2))) if da.size else 0.0,
        peak,
        len(ga),
        len(gb),
        len(gc),
        dz,
    )


def verdict(d: Diff, tol: Tolerances = LIVE) -> list[str]:
    """The failed checks (empty: within tolerances)."""
    fails = []
    limit = tol.force_abs_n + tol.force_rel * d.peak_a_n
    if not d.max_df_n <= limit:  # NaN fails too
        fails.append(f"max |dF| {d.max_df_n:.3e} N > {limit:.3e} N")
    if d.matched_fraction < tol.min_matched:
        fails.append(f"matched {d.matched_fraction:.4f} of A's wrench stamps < {tol.min_matched}")
    if d.extra_fraction > tol.max_extra:
        fails.append(f"{d.n_b - d.matched} of B's wrench stamps are not in A (allowed fraction {tol.max_extra})")
    if d.grids_matched and d.max_dz_m > tol.grid_m:
        fails.append(f"max |dz| {d.max_dz_m:.3e} m > {tol.grid_m:.3e} m")
    if d.grids_a and d.grids_matched < tol.min_matched * d.grids_a:
        fails.append(f"matched {d.grids_matched} of A's {d.grids_a} grid frames")
    return fails


def describe(tol: Tolerances) -> str:
    """The tolerances in one line, as the verdict prints them."""
    extra = "" if tol.max_extra == float("inf") else f", at most {tol.max_extra:.0%} of B's stamps not in A"
    return (
        f"max |dF| <= {tol.force_abs_n:g} N + {tol.force_rel:.2%} of peak, >= {tol.min_matched:.0%} of A's stamps matched{extra}"
    )


def format_table(d: Diff, a: str = "A", b: str = "B") -> str:
    """The :class:`Diff` as a text table, bag ``a`` against bag ``b``."""
    rows = [
        (
            "wrenches",
            f"{d.n_a}",
            f"{d.n_b}",
            f"{d.matched} matched ({d.matched_fraction:.2%} of A; {d.n_b - d.matched} of B not in A)",
        ),
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
    """``skin-sim compare A B``: print the diff and the verdict; exit 1 if they differ beyond the tolerances, 2 on a bad bag."""
    ap = argparse.ArgumentParser(prog="skin-sim compare", description=__doc__.splitlines()[0])
    ap.add_argument("bag_a", type=Path, help="reference output bag")
    ap.add_argument("bag_b", type=Path, help="output bag to check")
    ap.add_argument(
        "--exact",
        action="store_true",
        help=f"two offline replays: {describe(EXACT)} (default: live, {describe(LIVE)})".replace("%", "%%"),
    )
    ap.add_argument(
        "--force-abs-n", type=float, help=f"absolute force tolerance (N; live {LIVE.force_abs_n:g}, exact {EXACT.force_abs_n:g})"
    )
    ap.add_argument(
        "--force-rel",
        type=float,
        help=f"force tolerance, fraction of A's peak (live {LIVE.force_rel:g}, exact {EXACT.force_rel:g})",
    )
    ap.add_argument("--grid-m", type=float, help=f"grid height tolerance (m, default {LIVE.grid_m:g})")
    ap.add_argument(
        "--min-matched",
        type=float,
        help=f"min fraction of A's stamps in B (live {LIVE.min_matched:g}, exact {EXACT.min_matched:g})",
    )
    ap.add_argument("--no-grids", action="store_true", help="compare forces only")
    ap.add_argument(
        "--wrench-topic",
        default=TOPICS["tool_wrench"].name,
        help="wrench topic (default tool/wrench; in a bag of a node with hands, each hand's <hand>/tool/wrench)",
    )
    ap.add_argument("--grid-topic", default=TOPICS["layer_heights"].name)
    args = ap.parse_args(argv)
    tol = replace(
        EXACT if args.exact else LIVE,
        **{k: v for k in ("force_abs_n", "force_rel", "grid_m", "min_matched") if (v := getattr(args, k)) is not None},
    )
    fails = []
    try:
        topics = [args.wrench_topic]
        if args.wrench_topic == TOPICS["tool_wrench"].name:
            topics = hand_wrench_topics(args.bag_a) or topics  # each hand's forces, the tissue's grids once
        for i, wt in enumerate(topics):
            grids = not args.no_grids and i == 0
            a = read_outputs(args.bag_a, wt, args.grid_topic, grids)
            b = read_outputs(args.bag_b, wt, args.grid_topic, grids)
            d = diff_outputs(a, b)
            if len(topics) > 1:
                print(f"{wt}:")
            print(format_table(d, str(args.bag_a), str(args.bag_b)))
            fails += [f"{wt}: {f}" if len(topics) > 1 else f for f in verdict(d, tol)]
    except BagError as exc:
        print(f"skin-sim compare: error: {exc}", file=sys.stderr)
        return 2
    print(f"tolerances ({'exact' if args.exact else 'live'}): {describe(tol)}")
    print("DIFFERENT: " + "; ".join(fails) if fails else "SAME within tolerances")
    return 1 if fails else 0


if __name__ == "__main__":
    raise SystemExit(main())
