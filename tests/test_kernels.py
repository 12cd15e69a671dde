"""Each kernel of the paper form, the shared modal kernels and the grid, compiled and as .py_func, against the NumPy
reference (the layered form's: tests/test_layered.py; the baseline solvers': tests/test_solvers.py)."""

import math

import numpy as np
import pytest
from conftest import kernel

from skin_sim_lab.oracles import reference as ref
from skin_sim_node.model import SkinModel
from skin_sim_node.model import grid as gk
from skin_sim_node.model import layout as lo
from skin_sim_node.model import modal_kernels as mk
from skin_sim_node.model import paper as pk

K = np.array([9745.0, 130.0, 16.2])
B = np.array([21.7, 0.29, 0.036])
A = np.full(3, 1.96e-5)
THICK = np.array([75e-6, 1.2e-3, 4e-3])


@pytest.mark.parametrize("n", [1, 2, 3])
@pytest.mark.parametrize("velocity", [0.0, 0.01, -0.01])
def test_reuss_split_matches_reference_and_laws(compiled, n, velocity):
    split = kernel(pk.reuss_split, compiled)
    depth = 0.8 * THICK[:n].sum()
    comp = np.zeros(3)
    sigma, force, hit = split(n, depth, velocity, K, B, A, THICK, comp)
    c_ref, s_ref, f_ref, h_ref = ref.reuss_split_ref(n, depth, velocity, K, B, A, THICK)
    np.testing.assert_allclose(comp[:n], c_ref, rtol=1e-12, atol=1e-15)
    assert sigma == pytest.approx(s_ref, rel=1e-12) and force == pytest.approx(f_ref, rel=1e-12)
    assert hit == h_ref
    assert comp[:n].sum() == pytest.approx(depth, rel=1e-12)  # depths sum to the tool depth
    assert force >= 0.0
    free = (comp[:n] > 0) & (comp[:n] < THICK[:n])
    stresses = (K[:n] * comp[:n] + B[:n] * velocity) / A[:n]
    np.testing.assert_allclose(stresses[free], sigma, rtol=1e-9)  # iso-stress (eq 4)


def test_reuss_two_layer_closed_form_eq8_corrected(compiled):
    """Eq 7/8 with the sign typo corrected: dx_D = ((b_E A_D - b_D A_E) v + k_E dx_E A_D) / (k_D A_E)."""
    split = kernel(pk.reuss_split, compiled)
    k = np.array([300.0, 100.0, 1.0])
    b = np.array([0.5, 2.0, 0.0])
    a = np.array([1e-5, 2e-5, 1e-5])
    thick = np.full(3, 1.0)
    comp = np.zeros(3)
    v = 0.01
    split(2, 2e-3, v, k, b, a, thick, comp)
    dx_e = comp[0]
    dx_d = ((b[0] * a[1] - b[1] * a[0]) * v + k[0] * dx_e * a[1]) / (k[1] * a[0])
    assert comp[1] == pytest.approx(dx_d, rel=1e-12)
    depth = ((b[0] * a[1] - b[1] * a[0]) * v + (k[0] * a[1] + k[1] * a[0]) * dx_e) / (k[1] * a[0])
    assert depth == pytest.approx(2e-3, rel=1e-12)


def test_reuss_damping_sign(compiled):
    """Pressing in (v > 0) stiffens the response, pulling out softens it."""
    split = kernel(pk.reuss_split, compiled)
    comp = np.zeros(3)
    f0 = split(3, 2e-3, 0.0, K, B, A, THICK, comp)[1]
    f_in = split(3, 2e-3, +0.005, K, B, A, THICK, comp)[1]
    f_out = split(3, 2e-3, -0.005, K, B, A, THICK, comp)[1]
    assert f_out < f0 < f_in


def test_reuss_layer_bound_keeps_force_transmitted(compiled):
    """A fast press drives the stiff epidermis's Reuss compression negative: it is held at 0
    and the force is the stress through the remaining layers, which still grows with depth."""
    split = kernel(pk.reuss_split, compiled)
    comp = np.zeros(3)
    f1 = split(3, 2e-3, 0.05, K, B, A, THICK, comp)[1]
    assert comp[0] == 0.0
    f2 = split(3, 3e-3, 0.05, K, B, A, THICK, comp)[1]
    assert f2 > f1 > 0


def test_layer_bounds_and_count(compiled, default_cfg):
    lb = kernel(pk.layer_bounds, compiled)
    count = kernel(pk.count_affected, compiled)
    i_ed, i_df = default_cfg.interfaces
    mean = np.array([i_ed.mean_depth_m, i_df.mean_depth_m])
    amp = np.array([i_ed.amplitude_m, i_df.amplitude_m])
    kx = np.array([2 * np.pi / i_ed.wavelength_x_m, 2 * np.pi / i_df.wavelength_x_m])
    bounds = np.zeros(4)
    lb(0.0, 0.0, mean, amp, kx, kx, default_cfg.total_thickness_m, bounds)
    # at the origin both interfaces are at their peaks (shallowest)
    np.testing.assert_allclose(bounds, [0.0, mean[0] - amp[0], mean[1] - amp[1], default_cfg.total_thickness_m])
    assert count(0.0, bounds) == 0
    assert count(bounds[1] * 0.99, bounds) == 1
    assert count(bounds[1] * 1.01, bounds) == 2
    assert count(bounds[2] * 1.01, bounds) == 3
    assert count(bounds[3] * 2.0, bounds) == 3


@pytest.mark.parametrize("gamma", [0.0, 50.0, 300.0, 3000.0])
@pytest.mark.parametrize("dt", [1e-6, 1e-3, 5e-2])
def test_modal_propagator_matches_expm(compiled, gamma, dt):
    prop_fn = kernel(mk.modal_propagator, compiled)
    lam = np.array([[0.0032, 10.0, 300.0, 2999.0, 3000.0, 3001.0]])
    out = np.zeros((4, *lam.shape))
    prop_fn(lam, np.array([gamma]), dt, out)
    np.testing.assert_allclose(out, ref.propagator_expm(lam, np.array([gamma]), dt), rtol=1e-7, atol=1e-10)
    np.testing.assert_allclose(out, ref.propagator_ref(lam, np.array([gamma]), dt), rtol=1e-7, atol=1e-10)


def test_sine_table(compiled):
    fn = kernel(mk.sine_table, compiled)
    out = np.zeros(31)
    fn(0.37, 30, out)
    np.testing.assert_allclose(out, np.sin(np.arange(31) * 0.37), atol=1e-12)


def test_layer_field_matches_reference(compiled, rng):
    field = kernel(gk.layer_field, compiled)
    m_max, n_max = 7, 5
    mm, nn = np.meshgrid(np.arange(1, m_max + 1), np.arange(1, n_max + 1), indexing="ij")
    mode_m, mode_n = mm.ravel().astype(np.int64), nn.ravel().astype(np.int64)
    q = rng.normal(size=mode_m.size)
    xs = np.linspace(-0.06, 0.06, 50)
    ys = np.linspace(-0.05, 0.05, 40)
    out = np.zeros((40, 50))
    args = (np.zeros((m_max, n_max)), np.zeros((m_max + 1, 50)), np.zeros((n_max + 1, 40)), np.zeros((n_max + 1, 50)))
    for cx, cy in [(0.0, 0.0), (0.05, -0.04), (-0.3, 0.0)]:  # centred, clipped by the edge, off the grid
        field(q, cx, cy, mode_m, mode_n, np.unique(mode_m), np.unique(mode_n), 0.06, 0.04, xs, ys, *args, out)
        expect = ref.layer_field_ref(q, cx, cy, mode_m, mode_n, 0.06, 0.04, xs, ys)
        np.testing.assert_allclose(out, expect, atol=1e-12)


def test_point_displacement_matches_field(compiled, rng):
    point = kernel(mk.layer_point_displacement, compiled)
    mode_m = np.array([1, 3, 1, 3], dtype=np.int64)
    mode_n = np.array([1, 1, 3, 3], dtype=np.int64)
    q = rng.normal(size=4)
    bx, by = np.zeros(4), np.zeros(4)
    for x, y in [(0.01, -0.005), (0.0, 0.0), (0.2, 0.0)]:
        expect = ref.layer_field_ref(q, 0.001, 0.002, mode_m, mode_n, 0.06, 0.06, np.array([x]), np.array([y]))[0, 0]
        assert point(q, 0.001, 0.002, mode_m, mode_n, 0.06, 0.06, x, y, bx, by) == pytest.approx(expect, abs=1e-14)


def test_assemble_heights(compiled, rng):
    fn = kernel(gk.assemble_heights, compiled)
    disp = rng.normal(size=(3, 4, 5))
    rest = np.abs(rng.normal(size=(3, 4, 5)))
    out = np.zeros_like(disp)
    fn(disp, rest, out)
    np.testing.assert_allclose(out, ref.assemble_heights_ref(disp, rest))
    np.testing.assert_allclose(out[0], -rest[0] - disp.sum(axis=0))  # surface moves by the total
    np.testing.assert_allclose(out[2], -rest[2] - disp[2])  # fat top moves by the fat only


def test_patch_range(compiled):
    fn = kernel(gk.patch_range, compiled)
    xs = -0.06 + (np.arange(120) + 0.5) * 1e-3
    for c, side in [(0.0, 0.06), (0.0301, 0.06), (-0.05, 0.06), (0.2, 0.06), (0.0005, 0.002)]:
        inside = np.flatnonzero((xs > c - side / 2) & (xs < c + side / 2))
        i0, i1 = fn(xs, c, side)
        assert i1 - i0 == inside.size and (not inside.size or (i0, i1) == (inside[0], inside[-1] + 1))


def test_modal_energy(compiled, rng):
    fn = kernel(mk.modal_energy, compiled)
    q, v, lam = rng.normal(size=(3, 5)), rng.normal(size=(3, 5)), np.abs(rng.normal(size=(3, 5))) * 100
    assert fn(q, v, lam) == pytest.approx(0.5 * np.sum(v**2 + (lam * q) ** 2), rel=1e-13)


def _driven_model(cfg):
    """A model pressing 2 mm at one point: every layer holds a shape centred there."""
    m = SkinModel(cfg.replace(**{"lod.idle": False}))
    for i in range(30):
        m.step((0.002, -0.001, -2e-3 * (i + 1) / 30), (0.0, 0.0, -0.07), 1e-3)
    return m


@pytest.mark.parametrize("form", ["paper", "layered"])
def test_surface_and_layer_at_match_reference(compiled, default_cfg, form):
    m = _driven_model(default_cfg.replace(form=form))
    a, b = m._arrays, m.basis
    for x, y in [(0.002, -0.001), (0.01, 0.004), (0.05, 0.0)]:
        want = []
        for li in range(3):
            nk = b.k_prefix[m.level[li]]
            xy = (np.array([x]), np.array([y]))
            want.append(
                ref.layer_field_ref(m.q[li, :nk], *m.centre[li], b.mode_m[:nk], b.mode_n[:nk], *m.cfg.patch_size_m, *xy)[0, 0]
            )
            got = kernel(mk.layer_at, compiled)(li, x, y, a.sp, a.blev, a.bk, a.mstate, a.lstate, a.istate, a.sbuf)
            assert got == pytest.approx(want[-1], rel=1e-12, abs=1e-18)
        surface = kernel(mk.surface_at, compiled)(x, y, a.sp, a.blev, a.bk, a.mstate, a.lstate, a.istate, a.sbuf)
        assert surface == pytest.approx(sum(w for w, on in zip(want, m.active) if on), rel=1e-12, abs=1e-18)


def test_begin_tick_contact_test_and_propagators(compiled, default_cfg):
    """The opening of both ticks: off-sheet flag, contact against the deformed surface, propagators for ``dt``."""
    fn = kernel(mk.begin_tick, compiled)
    m = _driven_model(default_cfg.replace(**{"lod.affected_layers": False}))
    a = m._arrays
    arrays = (a.sp, a.bmodes, a.bvec, a.blev, a.bk, a.mstate, a.lstate, a.istate, a.sbuf)
    u = m.surface_displacement_at(0.004, 0.0)
    assert u > 0
    m.release()  # no layer driven: contact needs the tool at the deformed surface
    assert fn(0.004, 0.0, -0.999 * u, 2e-3, *arrays) == (0, False, pytest.approx(u, rel=1e-12), False)
    assert fn(0.004, 0.0, -1.001 * u, 2e-3, *arrays) == (0, False, pytest.approx(u, rel=1e-12), True)
    nv = a.blev.shape[1]
    expect = ref.propagator_ref(a.bmodes[nv:], a.bvec[nv:], 2e-3)
    for li in range(3):
        nk = a.blev[0, a.istate[lo.IS_LEVEL, li]]
        np.testing.assert_allclose(a.mstate[2:6, li, :nk], expect[:, li, :nk], rtol=1e-7, atol=1e-10)
    a.istate[lo.IS_DRIVEN, 1] = 1  # in contact: the tool stays in contact above the deformed surface
    _, was_contact, _, touching = fn(0.004, 0.0, -0.5 * u, 2e-3, *arrays)
    assert was_contact and touching
    assert not fn(0.004, 0.0, 1e-3, 2e-3, *arrays)[3]  # above the rest surface: never
    flags, _, _, touching = fn(0.2, 0.0, -1e-3, 2e-3, *arrays)
    assert flags == lo.FLAG_OFF_SHEET and not touching


def test_drive_and_relax_layer_match_reference(compiled, default_cfg):
    """Driving sets ``q = c beta``, ``v = cdot beta`` (eq 3); relaxing applies the exact damped propagator (eq 2)."""
    cfg = default_cfg.replace(**{"lod.adaptive_modes": False, "lod.affected_layers": False, "lod.idle": False})
    m = SkinModel(cfg)
    a = m._arrays
    drive, relax = kernel(mk.drive_layer, compiled), kernel(mk.relax_layer, compiled)
    drive(1, 1e-3, 0.02, 0.004, -0.002, a.sp, a.bmodes, a.bvec, a.blev, a.mstate, a.lstate, a.istate)
    np.testing.assert_array_equal(m.q[1], 1e-3 * m.basis.beta)
    np.testing.assert_array_equal(m.v[1], 0.02 * m.basis.beta)
    assert m.driven[1] == 1 and tuple(m.centre[1]) == (0.004, -0.002) and m.compression_m[1] == 1e-3
    mk.prepare_propagators(a.bmodes, a.bvec, a.blev, 1e-3, a.mstate, a.lstate, a.istate)
    q0, v0 = m.q[1].copy(), m.v[1].copy()
    relax(1, 1e-3, a.sp, a.bmodes, a.bvec, a.blev, a.mstate, a.lstate, a.istate)
    p = ref.propagator_ref(m.basis.lam, m.basis.gamma, 1e-3)[:, 1]
    np.testing.assert_allclose(m.q[1], p[0] * q0 + p[1] * v0, rtol=1e-7, atol=1e-15)
    np.testing.assert_allclose(m.v[1], p[2] * q0 + p[3] * v0, rtol=1e-7, atol=1e-12)
    assert m.driven[1] == 0


@pytest.mark.parametrize("shape", ["flat", "sphere"])
def test_paper_step_kernel_compiled_matches_py_func(default_cfg, shape):
    """The whole paper-form tick, compiled and as .py_func, over a press-drag-release path."""
    lod = {"lod.adaptive_modes": False, "lod.idle": False}
    c = default_cfg.replace(form="paper", **{"tool.shape": shape, "modes.m": 5, "modes.n": 5, **lod})
    fast, slow = SkinModel(c), SkinModel(c)
    for i in range(400):
        t = i * 1e-3
        z = -3e-3 * math.sin(math.pi * t / 0.3) if t < 0.3 else 1e-3
        vz = -3e-3 * math.pi / 0.3 * math.cos(math.pi * t / 0.3) if t < 0.3 else 0.0
        f1 = fast.step((0.02 * t, 0.001, z), (0.02, 0.0, vz), 1e-3)
        slow.flags = pk.paper_step_kernel.py_func(0.02 * t, 0.001, z, vz, 1e-3, *slow._arrays.args)
        assert f1 == pytest.approx(slow.force_n, rel=1e-12, abs=1e-15) and fast.flags == slow.flags
        np.testing.assert_allclose(fast._out, slow._out, rtol=1e-10, atol=1e-13)
        np.testing.assert_allclose(fast.q, slow.q, rtol=1e-10, atol=1e-16)


def test_step_kernel_matches_numpy_model(default_cfg):
    """The whole compiled (paper-form) step against the NumPy model over a press-drag-release path."""
    cfg = default_cfg.replace(form="paper")
    fast, slow = SkinModel(cfg), ref.NumpySkinModel(cfg)
    dt = 1e-3
    for i in range(400):
        t = i * dt
        z = -4e-3 * math.sin(math.pi * t / 0.3) if t < 0.3 else 2e-3
        vz = -4e-3 * math.pi / 0.3 * math.cos(math.pi * t / 0.3) if t < 0.3 else 0.0
        x = 0.01 * t
        f1 = fast.step((x, 0.002, z), (0.01, 0, vz), dt)
        f2 = slow.step((x, 0.002, z), (0.01, 0, vz), dt)
        assert f1 == pytest.approx(f2, rel=1e-9, abs=1e-12)
        assert fast.flags == slow.flags and fast.n_affected == slow.n_affected
        np.testing.assert_allclose(fast.q, slow.q, rtol=1e-8, atol=1e-15)
    disp, heights = slow.build_grid()
    g = fast.build_grid()
    np.testing.assert_allclose(g.displacement_m, disp, atol=1e-12)
    np.testing.assert_allclose(g.heights_m, heights, atol=1e-12)
