"""The demo's summary helpers (pure: no processes)."""

from skin_sim_node.demo import force_at_deepest

MS = 1_000_000


def test_force_at_deepest_takes_the_wrench_that_answers_the_deepest_pose():
    poses = [(k * MS, 0.0, 0.0, -2e-3 * min(k, 10 - k) / 5) for k in range(11)]  # down to 2 mm at k = 5, back up
    wrenches = [(k * MS + MS // 4, k * MS, 0.1 * min(k, 10 - k)) for k in range(11)]  # each 0.25 ms after its pose
    depth_m, force_n = force_at_deepest(poses, wrenches, window_ns=MS)
    assert abs(depth_m - 2e-3) < 1e-15 and force_n == max(w[2] for w in wrenches) == 0.1 * 5


def test_force_at_deepest_without_data_is_none():
    assert force_at_deepest([], [(0, 0, 1.0)]) is None
    assert force_at_deepest([(0, 0.0, 0.0, -1e-3)], [(10**9, 0, 1.0)]) is None  # no wrench near the deepest instant
