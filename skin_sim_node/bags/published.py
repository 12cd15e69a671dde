"""Does a force a node published equal the offline answer to the same inputs?

``replay --live`` and ``demo`` both hold a set of wrenches that a live node published (the input
bag's own ``/tool/wrench``, or what the demo received) and the offline replay of the poses those
wrenches answer (:func:`skin_sim_node.bags.offline.replay`, the same session code without DDS or a
wall clock). In ``input`` loop mode a wrench is stamped with the pose it answers, so the two match
one for one by stamp. A published force that differs from the offline answer by more than
``force_rel`` of the offline peak is a failure: the node did not compute what the model computes.
"""

from __future__ import annotations

from dataclasses import dataclass, replace
from typing import Any

import numpy as np

from .compare import LIVE, Diff, Tolerances, describe, diff_outputs, verdict
from .inputs import POSE, Inputs

PUBLISHED = replace(LIVE, min_matched=0.0)
"""Published against offline: the force as ``replay --live`` checks it (1 % of peak). No matched fraction is
required (a recording node with a keep-last-1 reader answers only the poses it saw), but at least one stamp
must match, or nothing was checked."""


PUBLISHED_HANDS = replace(PUBLISHED, force_abs_n=0.01, force_rel=0.05)
"""A hand's recorded forces against the offline two-hand answer: 0.01 N + 5 % of its offline peak (one hand: 1 % of
peak). The node ticks the hands in the order their poses arrive, each over its receive-clock interval; offline takes
them in stamp order over stamp intervals. A few ms of scheduling delay while the other hand moves changes the field
under this tool by tens of um: measured on a finger's release beside the needle, 4.6e-2 N (2.6 % of the needle's peak)
with the machine's load average at 7. A two-hand live replay (``replay --live``) holds each hand's live forces to it;
the live two-hand test (tests/test_two_hands_ros.py) holds each force to 5 % of itself + 0.01 N for the same reason."""


@dataclass(frozen=True)
class PublishedCheck:
    """The published wrenches against the offline answer at matched stamps.

    Attributes
    ----------
    diff : Diff
        A: the offline answer, B: the published forces.
    fails : list of str
        Failed checks (empty: the published forces are the offline answer).
    worst_stamp_ns : int or None
        Stamp of the largest difference.
    worst : tuple of float or None
        ``(published_n, offline_n)``: the two forces' magnitudes at ``worst_stamp_ns``.
    """

    diff: Diff
    fails: list
    worst_stamp_ns: int | None
    worst: tuple | None

    @property
    def ok(self) -> bool:
        """True when every matched published force is within tolerance of the offline one."""
        return not self.fails


def check_published(offline: dict[int, Any], published: dict[int, Any], tol: Tolerances = PUBLISHED) -> PublishedCheck:
    """Compare ``published`` with ``offline`` at their common stamps, as whole vectors.

    Parameters
    ----------
    offline, published : dict
        ``{stamp_ns: force vector (N)}`` (scalars work too).
    tol : Tolerances
        The force tolerance; :data:`PUBLISHED` by default.

    Returns
    -------
    PublishedCheck
    """
    d = diff_outputs((offline, {}), (published, {}))
    fails = verdict(d, tol)
    if d.matched == 0:
        fails.append("no published wrench answers a replayed pose (stamps differ)")
    common = set(offline) & set(published)

    def gap(s):
        return float(np.linalg.norm(np.subtract(published[s], offline[s])))

    worst = max(common, key=gap, default=None)
    pair = None if worst is None else (float(np.linalg.norm(published[worst])), float(np.linalg.norm(offline[worst])))
    return PublishedCheck(d, fails, worst, pair)


def format_check(c: PublishedCheck, what: str, t0_ns: int | None = None, tol: Tolerances = PUBLISHED) -> str:
    """One line: how many published forces were checked, the largest difference, and the verdict.

    ``t0_ns``: stamps are printed as seconds after it (default: the first offline stamp is unknown, so ns).
    """
    d = c.diff
    head = f"{what}: {d.matched} of {d.n_b} published forces answer a replayed pose; max |dF| {d.max_df_n:.3e} N"
    if c.worst_stamp_ns is not None and c.worst is not None:
        at = f"t = {(c.worst_stamp_ns - t0_ns) * 1e-9:.3f} s" if t0_ns is not None else f"stamp {c.worst_stamp_ns}"
        head += f" at {at} (published {c.worst[0]:.4f} N, offline {c.worst[1]:.4f} N)"
    head += f", offline peak {d.peak_a_n:.4f} N; limit {describe(tol)}"
    return head + (": agrees" if c.ok else ": DISAGREES (" + "; ".join(c.fails) + ")")


def answered_only(inputs: Inputs, stamps: set[int]) -> Inputs:
    """``inputs`` with only the poses whose stamp is in ``stamps`` (the poses a live node answered); twists kept.

    A live node with a keep-last-1 pose reader skips poses when it is descheduled; replaying only the poses it
    answered gives the offline answer to the inputs the node actually used.
    """
    events = [e for e in inputs.events if e[1] != POSE or e[0] in stamps]
    return replace(inputs, events=events, n_poses=sum(1 for e in events if e[1] == POSE))


def check_hands(inputs, hands, params, published: dict[str, dict], tol: Tolerances) -> dict[str, tuple[PublishedCheck, int]]:
    """Each hand's published wrenches (a recording's, or a live replay's) against the offline answer of the one tissue
    to the poses that node answered: ``{hand: (check, answers not checked)}`` for the hands with published wrenches.

    Only the poses answered are replayed, every hand's in stamp order (:func:`skin_sim_node.bags.offline.replay_hands`).
    A hand's answers stamped after another hand's last answered pose are not checked: the node then ticks the other hand
    on its fallback clock (its field keeps relaxing), and the offline replay holds that field where its last pose left it.
    """
    from .offline import replay_hands

    answered = [answered_only(inp, set(published[ns])) for ns, inp in zip(hands, inputs)]
    results = replay_hands(answered, params, None, 0.0)
    last = min(int(r.stamps_ns[-1]) for r in results if r.stamps_ns.size)
    out = {}
    for ns, res in zip(hands, results):
        if not published[ns]:
            continue
        kept = {s: f for s, f in published[ns].items() if s <= last}
        offline = res.forces_by_stamp()
        unchecked = sum(1 for s in published[ns] if s > last and s in offline)
        out[ns] = (check_published(offline, kept, tol), unchecked)
    return out
