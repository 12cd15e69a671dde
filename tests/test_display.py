"""The display worker's schedule, on a clock of its own (no DDS, no scheduler)."""

from __future__ import annotations

import numpy as np

from skin_sim_node.server.display import mesh_due


def meshes(build_times_s, rate_hz):
    """Times at which the worker sends a mesh, given the times at which it built a grid."""
    sent, last = [], -np.inf
    for t in build_times_s:
        if mesh_due(t, last, rate_hz, joined=False):
            sent.append(t)
            last = t
    return sent


def test_mesh_follows_its_rate_by_the_clock_not_by_the_build_count():
    # a slow press changes the grid about 20 times a second, at irregular instants
    rng = np.random.default_rng(3)
    builds = np.cumsum(rng.uniform(0.02, 0.08, 400))  # ~20 s of builds
    for rate in (2.0, 5.0):
        sent = meshes(builds, rate)
        achieved = (len(sent) - 1) / (sent[-1] - sent[0])
        assert 0.75 * rate <= achieved <= rate  # at most the rate; a build may come up to 80 ms after it is due
        assert np.all(np.diff(sent) >= 1.0 / rate - 1e-12)


def test_mesh_goes_out_at_once_for_a_joining_reader_and_never_at_rate_zero():
    assert mesh_due(10.0, 9.99, 5.0, joined=True)
    assert not mesh_due(10.0, 9.99, 5.0, joined=False)
    assert not mesh_due(10.0, -np.inf, 0.0, joined=True)
