"""The node's answer journal (skin_sim_node.server.journal) and the demo's reading of it (skin_sim_node.demo.hands)."""

from __future__ import annotations

import math

import numpy as np

from skin_sim_node.demo.hands import Answers
from skin_sim_node.server.journal import AnswerJournal, load_journal


def test_the_journal_keeps_every_answer_per_hand_in_the_nodes_order(tmp_path):
    j = AnswerJournal(tmp_path / "sub" / "journal.npz")
    j.append(1, 2_000, (0.01, 0.0, -0.001), (0.0, 0.0, 0.0, 1.0), (0.0, 0.0, 0.5))
    j.append(0, 1_000, (0.0, 0.0, -0.002), (math.nan,) * 4, (0.1, 0.0, 1.2))
    j.append(1, 3_000, (0.01, 0.0, -0.0015), (0.0, 0.0, 0.0, 1.0), (0.0, 0.0, 0.7))
    j.append(1, 3_000, (0.01, 0.0, -0.0016), (0.0, 0.0, 0.0, 1.0), (0.0, 0.0, 0.8))  # a stamp answered twice
    j.append(0, 9_000, (math.nan,) * 3, (math.nan,) * 4, (0.0, 0.0, 0.0))  # a tick of the node's clock: no pose
    assert len(j) == 5
    path = j.save()
    assert path == tmp_path / "sub" / "journal.npz" and path.exists()
    d = load_journal(path)
    assert d[1]["order"].tolist() == [0, 2, 3] and d[0]["order"].tolist() == [1, 4]
    assert d[1]["stamp_ns"].tolist() == [2_000, 3_000, 3_000]
    np.testing.assert_array_equal(d[0]["force_n"], [[0.1, 0.0, 1.2], [0.0, 0.0, 0.0]])
    ans = Answers.from_journal(path)
    assert ans.answered == [(2_000, "left"), (1_000, "right"), (3_000, "left")]  # the node's order, not the stamps'
    assert ans.poses["right"][1_000] == ((0.0, 0.0, -0.002), None)  # no orientation given: none replayed
    assert ans.forces["left"][3_000].tolist() == [0.0, 0.0, 0.7]  # the first answer of a stamp, as a reader keeps it
    assert 9_000 in ans.forces["right"] and 9_000 not in ans.poses["right"]  # its wrench is checked, nothing stepped
