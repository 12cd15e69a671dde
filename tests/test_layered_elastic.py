"""skin_sim_lab/validation/layered_elastic.py: the layered block's linear surface response against closed forms and
the linear 3D FEM."""

import numpy as np
import pytest

from skin_sim_lab.validation import fem
from skin_sim_lab.validation import layered_elastic as le
from skin_sim_lab.validation.hyperelastic import layer_moduli_pa
from skin_sim_lab.validation.references import FINEST_LEVEL
from skin_sim_node.model import preset

CFG = preset("default")


def test_a_thick_layer_is_a_half_space_and_a_thin_one_a_lubricated_compressible_film():
    e, nu = 20e3, 0.48
    mu = e / (2 * (1 + nu))
    k = np.array([1e3, 1e4, 1e5])
    half = (1 - nu) / (mu * k)
    np.testing.assert_allclose(le.surface_compliance(k, ((1.0, e),), nu), half, rtol=1e-9)
    # thin, nearly incompressible: the layer's flux (h^3 / (3 mu)) k^2 (lubrication) plus its own compression h / M,
    # M = lam + 2 mu (confined); at k h = 0.05-0.1 the flux term is 80-94 % of C, so this checks its coefficient
    nu = 0.4999
    mu = e / (2 * (1 + nu))
    lam = 2 * mu * nu / (1 - 2 * nu)
    h = 5e-3
    k = np.array([10.0, 20.0])  # higher orders in k h: 0.4-1.7 %
    thin = k**2 * h**3 / (3 * mu) + h / (lam + 2 * mu)
    np.testing.assert_allclose(le.surface_compliance(k, ((h, e),), nu), thin, rtol=0.03)


def test_a_rigid_punch_on_a_half_space_has_sneddons_stiffness_and_surface():
    e, nu, a = 20e3, 0.48, 2.5e-3
    p = le.rigid_punch(((0.5, e),), a, nu)  # 200 radii deep: a half-space to the punch
    assert p.stiffness_n_per_m == pytest.approx(2 * e * a / (1 - nu**2), rel=0.015)
    r = np.array([1.5, 2.0, 4.0]) * a
    np.testing.assert_allclose(p.profile(r), 2 / np.pi * np.arcsin(a / r), atol=0.01)
    np.testing.assert_allclose(p.profile([0.0, 0.5 * a]), 1.0, atol=0.01)  # flat under the punch


def test_the_layers_agree_with_the_linear_3d_fem():
    """The project's linear FEM (egg-carton interfaces, mesh level FINEST_LEVEL, cached under docs/validation) against
    the exact flat-layered solution: the two solve one problem but for the interfaces' corrugation."""
    p = le.rigid_punch(le.layers(CFG), CFG.tool_radius_m)
    setup = fem.mesh_levels(FINEST_LEVEL, fem.FemSetup(moduli_pa=layer_moduli_pa(CFG), tissue=fem._geometry_key(CFG)))
    res = fem.reference(setup, progress=False)
    assert p.stiffness_n_per_m == pytest.approx(res.stiffness_n_per_m, rel=0.02)
    r = np.array([4, 6, 8, 10, 13, 20]) * 1e-3
    row = res.surface_per_depth[int(np.argmin(np.abs(res.sample_y_m)))]
    np.testing.assert_allclose(p.profile(r), np.interp(r, res.sample_x_m, row), atol=0.004)
    # the heave: the surface rises above rest beside the punch, in both
    assert p.profile([7e-3])[0] < -0.04 and np.interp(7e-3, res.sample_x_m, row) < -0.04


def test_the_pair_solve_meets_first_order_apart_and_halves_the_force_of_coincident_punches():
    stack = le.layers(CFG)
    a = CFG.tool_radius_m
    p = le.rigid_punch(stack, a)
    # apart, the full solve and Betti's first order agree (coarse cells: the check's own grid is 0.1 mm)
    assert le.rigid_pair_interaction(stack, a, 10e-3, cell_m=0.2e-3) == pytest.approx(-p.coupling(p, 10e-3)[0], abs=0.003)
    # nearly coincident: one footprint shared by two punches, each carries half of it; 0.2 mm apart the union is 5 %
    # larger in area than one disk, 2-3 % stiffer (a flat punch's force grows about as its radius)
    assert -0.5 < le.rigid_pair_interaction(stack, a, 0.2e-3, cell_m=0.2e-3) < -0.47
    # overlapping 4 mm apart: softer than single, as the FEM's pair
    assert -0.1 < le.rigid_pair_interaction(stack, a, 4e-3, cell_m=0.2e-3) < -0.08
