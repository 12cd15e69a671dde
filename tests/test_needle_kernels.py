"""The needle's kernels (skin_sim_node/model/needle_kernels.py), compiled and as .py_func, against the pure-NumPy
reference (needle_reference.NumpyNeedleModel, the first cut): track start and crossings, dimple, rupture insertion,
the step over insert-retract-reinsert paths, and the law; plus the state's attributes, copies and bad input."""

from __future__ import annotations

import math

import numpy as np
import pytest

from skin_sim_lab.oracles.needle_reference import NumpyNeedleModel
from skin_sim_node.model import layout as lay
from skin_sim_node.model import needle as needle_mod
from skin_sim_node.model import needle_kernels as nk
from skin_sim_node.model.config import preset
from skin_sim_node.model.needle import NeedleModel, NeedleParams, warm_up

KERNELS = ("dimple_force", "needle_law_kernel", "needle_step_kernel", "reset_track", "rupture_insertion", "start_track")
TICK_FIELDS = ("axial_n", "dimple_n", "cutting_n", "friction_n", "dimple_m", "insertion_m")


@pytest.fixture(scope="module")
def cfg():
    return preset("default")


@pytest.fixture(params=["compiled", "py_func"])
def variant(request, monkeypatch):
    """NeedleModel with its kernels compiled, or with each kernel it calls as ``.py_func``."""
    if request.param == "py_func":
        for name in KERNELS:
            monkeypatch.setattr(needle_mod, name, getattr(nk, name).py_func)
    return request.param


def axis_at(angle_deg: float) -> np.ndarray:
    th = math.radians(angle_deg)
    return np.array([math.cos(th), 0.0, -math.sin(th)])


def in_out_path(u, x0: float, n: int) -> list[np.ndarray]:
    """Through every layer, back 2 mm (friction reverses, no second puncture), in again, then out of the tissue."""
    down = -u[2]
    start = np.array([x0, 0.0, 0.0]) - 0.2e-3 * u
    deep, back = 6.5e-3 / down, 4.5e-3 / down
    s = np.concatenate(
        [
            np.linspace(0.0, deep, n),
            np.linspace(deep, back, n // 3),
            np.linspace(back, deep, n // 3),
            np.linspace(deep, -0.5e-3, n // 2),
        ]
    )
    return [start + si * u for si in s]


def assert_tick_close(a, b):
    assert a.ruptured == b.ruptured and a.punctured == b.punctured
    for f in TICK_FIELDS:
        assert getattr(a, f) == pytest.approx(getattr(b, f), rel=1e-9, abs=1e-11), f
    np.testing.assert_allclose(a.force_n, b.force_n, rtol=1e-9, atol=1e-11)
    np.testing.assert_allclose(a.lateral_n, b.lateral_n, rtol=1e-9, atol=1e-11)


def assert_law_close(a, b):
    assert (a is None) == (b is None)
    if a is None:
        return
    np.testing.assert_allclose(a.axis, b.axis, atol=1e-15)
    for f in a.FIELDS:
        # finite differences over 1 um: the slopes carry the forces' rounding over 1e-6
        tol = dict(rel=1e-7, abs=1e-4) if f.endswith("gradient_n_per_m") else dict(rel=1e-9, abs=1e-11)
        assert getattr(a, f) == pytest.approx(getattr(b, f), **tol), f


# --- track start ----------------------------------------------------------------------------------


@pytest.mark.parametrize("angle_deg", [90.0, 60.0, 30.0])
@pytest.mark.parametrize("where", ["peak", "valley", "saddle"])
def test_crossings_match_the_scan(cfg, variant, angle_deg, where):
    """At a peak, a valley and a saddle of the dermis-fat interface, vertical and oblique: the Lipschitz march finds
    the same first crossing of every interface as the reference's 2 um scan and bisection."""
    w = cfg.interfaces[1].wavelength_x_m
    x = {"peak": 0.0, "valley": 0.5 * w, "saddle": 0.25 * w}[where]
    u = axis_at(angle_deg)
    tip = np.array([x, 0.0, 0.0]) + 1e-5 * u
    fast, slow = NeedleModel(cfg), NumpyNeedleModel(cfg)
    fast.step(tip, u)
    slow.step(tip, u)
    np.testing.assert_allclose(fast.entry, slow.entry, atol=1e-15)
    np.testing.assert_allclose(fast.axis, slow.axis, atol=1e-15)
    np.testing.assert_allclose(fast.crossings, slow.crossings, rtol=0.0, atol=1e-12)


def test_the_march_takes_the_first_of_several_crossings(cfg):
    """At 30 degrees the epidermis-dermis interface (slope A k = 1.26) is steeper than the axis (tan 30 = 0.58): the
    axis can cross it more than once. Over entry points along a wavelength, the first crossing is the reference's, and
    ``axis_crossing`` compiled and as .py_func agree."""
    i0 = cfg.interfaces[0]
    u = axis_at(30.0)
    for x in np.linspace(0.0, i0.wavelength_x_m, 7):
        fast, slow = NeedleModel(cfg), NumpyNeedleModel(cfg)
        tip = np.array([x, 0.013e-3, 0.0]) + 1e-5 * u
        fast.step(tip, u)
        slow.step(tip, u)
        assert fast.crossings[1] == pytest.approx(slow.crossings[1], abs=1e-12)
        args = (fast.lp, fast.npar, fast.nstate, fast.nbuf)
        assert nk.axis_crossing.py_func(1, *args) == nk.axis_crossing(1, *args)
        assert nk.axis_gap(fast.crossings[1], 1, *args) == pytest.approx(0.0, abs=1e-15)


def test_a_shallow_or_degenerate_axis_starts_no_track(cfg, variant):
    m = NeedleModel(cfg)
    assert not np.any(m.step((0.0, 0.0, -1e-4), axis_at(5.0)).force_n) and not m.inserted
    assert not np.any(m.step((0.0, 0.0, -1e-4), (0.0, 0.0, 0.0)).force_n) and not m.inserted
    assert not np.any(m.step((0.0, 0.0, 1e-4), (0.0, 0.0, -1.0)).force_n) and not m.inserted


# --- laws -----------------------------------------------------------------------------------------


@pytest.mark.parametrize("angle_deg", [90.0, 45.0])
def test_dimple_and_rupture_insertion_match_the_reference(cfg, variant, angle_deg):
    """The dimple law of each intact layer, and the rupture insertion: the series chain inverted at the threshold (the
    kernel) against bisection on the dimple law (the reference)."""
    u = axis_at(angle_deg)
    tip = np.array([0.7e-3, 0.3e-3, 0.0]) + 1e-5 * u
    fast, slow = NeedleModel(cfg, NeedleParams.gauge(25)), NumpyNeedleModel(cfg, NeedleParams.gauge(25))
    fast.step(tip, u)
    slow.step(tip, u)
    for k in range(3):
        for w in (0.0, 1e-5, 1e-3, 4e-3, 5.2e-3):
            assert fast.dimple_force_n(k, w) == pytest.approx(slow.dimple_force_n(k, w), rel=1e-10, abs=1e-14)
        fast.ruptured = slow.ruptured = k
        assert fast.rupture_insertion_m() == pytest.approx(slow.rupture_insertion_m(), rel=0.0, abs=1e-12)
        f = fast.dimple_force_n(k, fast.rupture_insertion_m() - fast.crossings[k])
        assert f == pytest.approx(fast.params.puncture_force_n(k), rel=1e-9)  # the threshold, reached
    fast.ruptured = slow.ruptured = 3
    assert fast.rupture_insertion_m() == slow.rupture_insertion_m() == math.inf


@pytest.mark.parametrize(("angle_deg", "x0", "gauge", "lubricated"), [(90.0, 0.0, 21, True), (30.0, 1.1e-3, 18, False)])
def test_step_and_law_match_the_reference(cfg, variant, angle_deg, x0, gauge, lubricated):
    """Every tick of an insert-retract-reinsert-withdraw path, and the law after it, as the reference's."""
    u = axis_at(angle_deg)
    params = NeedleParams.gauge(gauge, lubricated=lubricated)
    fast, slow = NeedleModel(cfg, params), NumpyNeedleModel(cfg, params)
    n = 240 if variant == "py_func" else 700
    punctured = []
    for p in in_out_path(u, x0, n):
        a, b = fast.step(p, u), slow.step(p, u)
        assert_tick_close(a, b)
        assert_law_close(fast.law(a, p), slow.law(b, p))
        assert fast.inserted == slow.inserted and fast.ruptured == slow.ruptured
        punctured += a.punctured
    assert punctured == [0, 1, 2]
    assert not fast.inserted and not slow.inserted


def test_the_law_cache_is_the_law(cfg):
    """The law's cache of the rupture ahead (NS_LAW_*) gives what a model without it gives, tick by tick (to the rounding
    of the insertion where the line past the rupture was evaluated)."""
    m = NeedleModel(cfg)
    for p in in_out_path(axis_at(60.0), 0.4e-3, 400):
        t = m.step(p, axis_at(60.0))
        cold = m.copy()
        cold.nstate[lay.NS_LAW_K] = 0.0
        assert_law_close(m.law(t, p), cold.law(t, p))


def test_step_kernel_compiled_equals_py_func(cfg):
    """The step and law kernels called directly, compiled and as .py_func on twin arrays: identical floats."""
    a, b = NeedleModel(cfg), NeedleModel(cfg)
    u = axis_at(60.0)
    for p in in_out_path(u, 0.2e-3, 150):
        ra = nk.needle_step_kernel(*p, *u, *a._args, a.nout)
        rb = nk.needle_step_kernel.py_func(*p, *u, *b._args, b.nout)
        assert ra == rb
        np.testing.assert_array_equal(a.nout, b.nout)
        np.testing.assert_array_equal(a.nstate, b.nstate)
        if ra:
            o = a.nout
            args = (*p, o[lay.NO_INSERTION_M], o[lay.NO_DIMPLE] + o[lay.NO_CUT], o[lay.NO_FRICTION], int(o[lay.NO_RUPTURED]))
            nk.needle_law_kernel(*args, *a._args, a.nlaw)
            nk.needle_law_kernel.py_func(*args, *b._args, b.nlaw)
            np.testing.assert_array_equal(a.nlaw, b.nlaw)


def test_axial_at_is_pure_and_advance_front_matches(cfg):
    """The law's look-ahead evaluation leaves the track as it was, and compiled equals .py_func."""
    m = NeedleModel(cfg)
    u = axis_at(90.0)
    for z in np.linspace(1e-4, -5.1e-3, 300):
        m.step((0.0, 0.0, z), u)
    state, track = m.nstate.copy(), m.ntrack.copy()
    for ins in (1e-3, 5.0e-3, 5.3e-3, 6.0e-3):
        args = (ins, 1e-6, 0.0, -1e-6, m.ruptured, m.front_m, 0.0, 0.0, 0.0, 0.0, *m._args)
        assert nk.axial_at(*args) == pytest.approx(nk.axial_at.py_func(*args), rel=1e-12)
        for k in range(4):
            assert nk.advance_front(ins, k, 1e-3, m.ntrack) == nk.advance_front.py_func(ins, k, 1e-3, m.ntrack)
    np.testing.assert_array_equal(m.nstate, state)
    np.testing.assert_array_equal(m.ntrack, track)


# --- the model's state --------------------------------------------------------------------------------


def test_attributes_copy_and_reset(cfg):
    """The reference's attributes read the state arrays; a copy is independent; reset forgets the track."""
    m = NeedleModel(cfg)
    u = axis_at(90.0)
    for z in np.linspace(1e-4, -5.6e-3, 600):
        m.step((0.0, 0.0, z), u)
    assert m.inserted and m.ruptured == 3 and m.front_m > 0.0 and m.last_m == pytest.approx(5.6e-3)
    assert np.all(np.diff(m.crossings) > 0.0) and np.all(np.abs(m.dahl) <= 1.0)
    c = m.copy()
    c.step((0.0, 0.0, -4e-3), u)
    assert m.last_m == pytest.approx(5.6e-3) and c.last_m == pytest.approx(4e-3)
    assert not np.shares_memory(c.nstate, m.nstate) and c.dahl[0] != m.dahl[0]
    m.reset()
    assert not m.inserted and m.ruptured == 0 and list(m.axis) == [0.0, 0.0, -1.0] and not np.any(m.crossings)
    assert c.inserted


def test_non_finite_input_is_a_one_line_error(cfg):
    m = NeedleModel(cfg)
    with pytest.raises(ValueError, match="needle tip must be finite"):
        m.step((0.0, math.nan, -1e-3), (0.0, 0.0, -1.0))
    with pytest.raises(ValueError, match="needle axis must be finite"):
        m.step((0.0, 0.0, -1e-3), (0.0, math.inf, -1.0))
    assert not m.inserted
    out = np.zeros(lay.NO_SIZE)
    assert not nk.needle_step_kernel(0.0, 0.0, math.nan, 0.0, 0.0, -1.0, *m._args, out) and not np.any(out)


def test_warm_up_runs_every_path(cfg):
    warm_up(cfg)
