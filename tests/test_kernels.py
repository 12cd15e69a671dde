"""Each kernel, compiled and as .py_func, against the NumPy reference."""

import math

import numpy as np
import pytest
from conftest import kernel

from skin_sim_node.model import kernels as kn
from skin_sim_node.model import reference as ref

K = np.array([9745.0, 130.0, 16.2])
B = np.array([21.7, 0.29, 0.036])
A = np.full(3, 1.96e-5)
THICK = np.array([75e-6, 1.2e-3, 4e-3])


@pytest.mark.parametrize("n", [1, 2, 3])
@pytest.mark.parametrize("velocity", [0.0, 0.01, -0.01])
def test_reuss_split_matches_reference_and_laws(compiled, n, velocity):
    split = kernel(kn.reuss_split, compiled)
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
    split = kernel(kn.reuss_split, compiled)
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
    split = kernel(kn.reuss_split, compiled)
    comp = np.zeros(3)
    f0 = split(3, 2e-3, 0.0, K, B, A, THICK, comp)[1]
    f_in = split(3, 2e-3, +0.005, K, B, A, THICK, comp)[1]
    f_out = split(3, 2e-3, -0.005, K, B, A, THICK, comp)[1]
    assert f_out < f0 < f_in


def test_reuss_layer_bound_keeps_force_transmitted(compiled):
    """A fast press drives the stiff epidermis's Reuss compression negative: it is held at 0
    and the force is the stress through the remaining layers, which still grows with depth."""
    split = kernel(kn.reuss_split, compiled)
    comp = np.zeros(3)
    f1 = split(3, 2e-3, 0.05, K, B, A, THICK, comp)[1]
    assert comp[0] == 0.0
    f2 = split(3, 3e-3, 0.05, K, B, A, THICK, comp)[1]
    assert f2 > f1 > 0


def test_layer_bounds_and_count(compiled, default_cfg):
    lb = kernel(kn.layer_bounds, compiled)
    count = kernel(kn.count_affected, compiled)
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
    prop_fn = kernel(kn.modal_propagator, compiled)
    lam = np.array([[0.0032, 10.0, 300.0, 2999.0, 3000.0, 3001.0]])
    out = np.zeros((4, *lam.shape))
    prop_fn(lam, np.array([gamma]), dt, out)
    np.testing.assert_allclose(out, ref.propagator_expm(lam, np.array([gamma]), dt), rtol=1e-7, atol=1e-10)
    np.testing.assert_allclose(out, ref.propagator_ref(lam, np.array([gamma]), dt), rtol=1e-7, atol=1e-10)


def test_sine_table(compiled):
    fn = kernel(kn.sine_table, compiled)
    out = np.zeros(31)
    fn(0.37, 30, out)
    np.testing.assert_allclose(out, np.sin(np.arange(31) * 0.37), atol=1e-12)


def test_layer_field_matches_reference(compiled, rng):
    field = kernel(kn.layer_field, compiled)
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
    point = kernel(kn.layer_point_displacement, compiled)
    mode_m = np.array([1, 3, 1, 3], dtype=np.int64)
    mode_n = np.array([1, 1, 3, 3], dtype=np.int64)
    q = rng.normal(size=4)
    bx, by = np.zeros(4), np.zeros(4)
    for x, y in [(0.01, -0.005), (0.0, 0.0), (0.2, 0.0)]:
        expect = ref.layer_field_ref(q, 0.001, 0.002, mode_m, mode_n, 0.06, 0.06, np.array([x]), np.array([y]))[0, 0]
        assert point(q, 0.001, 0.002, mode_m, mode_n, 0.06, 0.06, x, y, bx, by) == pytest.approx(expect, abs=1e-14)


def test_assemble_heights(compiled, rng):
    fn = kernel(kn.assemble_heights, compiled)
    disp = rng.normal(size=(3, 4, 5))
    rest = np.abs(rng.normal(size=(3, 4, 5)))
    out = np.zeros_like(disp)
    fn(disp, rest, out)
    np.testing.assert_allclose(out, ref.assemble_heights_ref(disp, rest))
    np.testing.assert_allclose(out[0], -rest[0] - disp.sum(axis=0))  # surface moves by the total
    np.testing.assert_allclose(out[2], -rest[2] - disp[2])  # fat top moves by the fat only


def test_step_kernel_matches_numpy_model(default_cfg):
    """The whole compiled (paper-form) step against the NumPy model over a press-drag-release path."""
    from skin_sim_node.model import SkinModel

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
