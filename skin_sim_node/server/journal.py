"""The node's answer journal: every pose a hand answered and the force it published for it, kept in memory and written
at exit (``skin-sim bridge --with-node --journal FILE``). No rclpy.

Why. A check that the published forces are the offline two-hand answer must step the offline tissue on every pose the
node stepped, in order: a pose it misses moves the offline tissue onto another path. A reader over DDS cannot keep all
of them on this machine: two hands at 1 kHz are 2000 poses and 2000 wrenches a second, and rclpy costs about 0.3 ms of
CPU per message here (docs/performance.md), 1.2 cores for the reader alone; the two-hand demo's reader left out 434 of
780 and 214 of 392 of one hand's answers (session 8). The node has them all in hand when it answers: appending one
record per answer costs a list append (about 1 us beside a 0.3 ms message), and the file is written once, at exit.
What DDS delivered is still checked: each wrench a reader received must be the journal's for its stamp.
"""

from __future__ import annotations

import threading
from pathlib import Path

import numpy as np

FIELDS = ("order", "stamp_ns", "position_m", "orientation_xyzw", "force_n")
"""The arrays per hand in the file (``<hand index>/<field>``): the answer's place in the node's order of answers (both
hands), the pose's stamp (ns), its position (m) and orientation (x, y, z, w; tissue frame, as the session took it; NaN
for an orientation the pose did not carry) and the force the wrench carried (N, tissue frame). A tick of the node's
own clock (its watchdog's fallback in input mode; every tick in timer mode) answers no pose: its position is NaN and
its stamp the node's clock, which its wrench carries. Memory: about 0.25 kB per row (1.8 GB an hour at two hands'
1 kHz): the journal is for test and demo runs."""


HELP = (
    "write every pose each hand answered and the force it published, and each tick of the node's clock's force, to FILE "
    "(.npz) at exit (skin_sim_node.server.journal; what the two-hand demo checks against the offline tissue; about "
    "0.25 kB per answer in memory: for test and demo runs)"
)
"""The ``--journal FILE`` option's help, for ``skin-sim node`` and ``skin-sim bridge --with-node``."""


class AnswerJournal:
    """Per hand, every answered pose and its force, in the node's order (thread-safe; the node calls it under its
    lock, the lock here keeps a stand-alone use safe).

    Parameters
    ----------
    path : str or Path
        Where :meth:`save` writes the ``.npz``.
    """

    def __init__(self, path):
        self.path = Path(path)
        self._rows: list[tuple] = []
        self._lock = threading.Lock()

    def append(self, hand: int, stamp_ns: int, position_m, orientation_xyzw, force_n) -> None:
        """One answer: hand index, pose stamp (ns), position (m), orientation (x, y, z, w), published force (N)."""
        with self._lock:
            self._rows.append((hand, stamp_ns, tuple(position_m), tuple(orientation_xyzw), tuple(force_n)))

    def __len__(self) -> int:
        return len(self._rows)

    def save(self) -> Path:
        """Write the journal (``np.savez``; parents created) and return its path."""
        with self._lock:
            rows = list(self._rows)
        arrays: dict[str, np.ndarray] = {}
        for hand in sorted({r[0] for r in rows}):
            idx = [k for k, r in enumerate(rows) if r[0] == hand]
            arrays[f"{hand}/order"] = np.array(idx, dtype=np.int64)
            arrays[f"{hand}/stamp_ns"] = np.array([rows[k][1] for k in idx], dtype=np.int64)
            arrays[f"{hand}/position_m"] = np.array([rows[k][2] for k in idx], dtype=float).reshape(-1, 3)
            arrays[f"{hand}/orientation_xyzw"] = np.array([rows[k][3] for k in idx], dtype=float).reshape(-1, 4)
            arrays[f"{hand}/force_n"] = np.array([rows[k][4] for k in idx], dtype=float).reshape(-1, 3)
        self.path.parent.mkdir(parents=True, exist_ok=True)
        with open(self.path, "wb") as f:  # np.savez would add ".npz" to a name without it
            np.savez(f, **arrays)  # type: ignore[arg-type]  # numpy's stub types the keywords as allow_pickle
        return self.path


def load_journal(path) -> dict[int, dict[str, np.ndarray]]:
    """A journal file as ``{hand index: {field: array}}`` (:data:`FIELDS`)."""
    with np.load(path) as z:
        out: dict[int, dict[str, np.ndarray]] = {}
        for key in z.files:
            hand, field = key.split("/", 1)
            out.setdefault(int(hand), {})[field] = z[key]
    return out
