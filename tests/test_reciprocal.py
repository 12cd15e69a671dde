"""The load maps that make the two-tool coupling a potential's (skin_sim_node.tools.reciprocal, issue 32)."""

from __future__ import annotations

import numpy as np
import pytest

from skin_sim_node.model import preset
from skin_sim_node.tools import TOOLS
from skin_sim_node.tools.reciprocal import LAW_DEPTHS_M, LoadMap, load_map, static_law


@pytest.fixture(scope="module")
def maps():
    return load_map(TOOLS["flat"], preset("default")), load_map(TOOLS["needle"], preset("needle"))


def test_the_static_law_is_the_relaxed_hold():
    """The static law at 1 mm is a 2.5 mm punch's force after 1.5 s held at 1 mm (433.7 N/m: docs/two_hands.md), the
    chain stiffening with depth; a needle's stops before its puncture."""
    e, f = static_law(TOOLS["flat"], preset("default"))
    k = int(np.argmin(np.abs(e - 1e-3)))
    assert f[k] / e[k] == pytest.approx(433.7, abs=0.5)
    secant = f[1:] / e[1:]
    assert np.all(np.diff(secant) > 0)  # strain-stiffening
    en, fn = static_law(TOOLS["needle"], preset("needle"))
    assert en.size >= 2 and np.all(np.diff(fn) > 0) and en[-1] <= LAW_DEPTHS_M[-1]


@pytest.mark.parametrize("e", [0.03e-3, 0.25e-3, 0.55e-3, 1e-3, 1.95e-3, 2.5e-3, 3.4e-3, 5e-3])
def test_psi_prime_is_the_derivative_of_psi_along_the_law(maps, e):
    """``Psi'`` is exactly ``dPsi/dF`` along the interpolated law (what makes ``phi = G Psi_i Psi_j`` a potential),
    inside the nodes, between them and past the last; the law's slope is continuous at the nodes (a cubic)."""
    for m in maps:
        h = 1e-9
        num = (m.value(e + h) - m.value(e - h)) / (m.force_n(e + h) - m.force_n(e - h))
        assert num == pytest.approx(m.slope(e), rel=1e-6)


def test_two_tools_in_one_state_feel_the_depth_kernel(maps):
    """``Psi' Psi = e`` in one state (the depth coupling the FEM two-punch rows validate), to 0.2 %; an untouched
    tool feels a pressed one by ``sqrt`` of their stiffnesses' ratio (Betti, split evenly)."""
    for m in maps:
        for e in (0.1e-3, 0.5e-3, 1e-3, 2e-3, 2.9e-3):
            assert m.lowering(e, m, e) == pytest.approx(e, rel=2e-3)
    punch, needle = maps
    small = 0.1e-3
    k_needle = needle.forces_n[1] / needle.depths_m[1]
    k_punch = punch.force_n(small) / small
    assert needle.lowering(0.0, punch, small) == pytest.approx(small * np.sqrt(k_punch / k_needle), rel=0.02)


def test_psi_is_odd_and_continuous(maps):
    """A tool pulling the skin up lifts it beside by the same law (odd), and nothing steps at a node."""
    for m in maps:
        for e in (0.3e-3, 1.7e-3):
            assert m.value(-e) == -m.value(e) and m.slope(-e) == m.slope(e)
        for node in m.depths_m[1:]:
            lo, hi = node * (1 - 1e-9), node * (1 + 1e-9)
            assert m.value(hi) == pytest.approx(m.value(lo), rel=1e-6)
            assert m.slope(hi) == pytest.approx(m.slope(lo), rel=1e-6)
        for node in m.depths_m[1:-1]:  # the law's stiffness: no chord jump across a node
            h = 1e-7
            left = (m.force_n(node) - m.force_n(node - h)) / h
            right = (m.force_n(node + h) - m.force_n(node)) / h
            assert right == pytest.approx(left, rel=1e-3)
        assert m.value(0.0) == 0.0 and m.slope(0.0) == m.slopes[0]


def test_a_law_that_does_not_rise_is_refused():
    with pytest.raises(ValueError, match="rising"):
        LoadMap([0.0, 1e-3, 2e-3], [0.0, 0.5, 0.4])
    with pytest.raises(ValueError, match="rising"):
        LoadMap([0.0], [0.0])


def test_the_maps_are_shared():
    """One map per tool type and tissue (cached: each SharedSkin of one scene reads the same)."""
    assert load_map(TOOLS["flat"], preset("default")) is load_map(TOOLS["flat"], preset("default"))
