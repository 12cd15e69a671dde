"""Large-deformation reference (issue 11 item 3): neo-Hookean kernel, closed form, small-strain check, cache."""

from __future__ import annotations

import numpy as np
import pytest
from scipy.optimize import brentq

from skin_sim_lab.validation import hyperelastic as h
from skin_sim_lab.validation.large_deformation import SMALL_STRAIN_DEPTH_M, SMALL_STRAIN_TOL
from skin_sim_lab.validation.references import AXI_REFERENCE_LEVEL, axisym
from skin_sim_node.model import preset
from skin_sim_node.model.calibration import LAYER_SOURCES as LAYER_DEFAULTS


def test_neo_hookean_tangent_is_the_derivative_of_the_stress():
    rng = np.random.default_rng(3)
    H = 0.2 * rng.standard_normal((5, 4))
    lam, mu = 2.0e5, 7.0e3
    P, A, J = h.neo_hookean(H, lam, mu)
    assert np.all(J > 0)
    eps = 1e-7
    for b in range(5):
        dH = np.zeros_like(H)
        dH[b] = eps
        fd = (h.neo_hookean(H + dH, lam, mu)[0] - h.neo_hookean(H - dH, lam, mu)[0]) / (2 * eps)
        np.testing.assert_allclose(A[:, b], fd, rtol=1e-5, atol=1e-6 * mu)


def test_neo_hookean_is_stress_free_at_rest_and_linear_elastic_at_small_strain():
    H0 = np.zeros((5, 1))
    lam, mu = 3.0, 1.0
    P, A, _ = h.neo_hookean(H0, lam, mu)
    assert np.allclose(P, 0.0)
    # sigma_rr for a pure radial strain e: (lam + 2 mu) e; hoop: lam e
    e = 1e-8
    P, _, _ = h.neo_hookean(np.array([[e], [0], [0], [0], [0]]), lam, mu)
    assert P[0, 0] == pytest.approx((lam + 2 * mu) * e, rel=1e-6)
    assert P[4, 0] == pytest.approx(lam * e, rel=1e-6)


def test_layer_moduli_are_read_from_the_config():
    cfg = preset("default")
    assert h.layer_moduli_pa(cfg) == pytest.approx([v[1] for v in LAYER_DEFAULTS.values()], rel=1e-12)
    k = cfg.as_flat()["layers.dermis.stiffness_n_per_m"]
    stiffer = cfg.replace(**{"layers.dermis.stiffness_n_per_m": 2 * k})
    assert h.layer_moduli_pa(stiffer)[1] == pytest.approx(2 * LAYER_DEFAULTS["dermis"][1], rel=1e-12)
    s = h.setup_from_config(stiffer, level=0)
    assert s.moduli_pa[1] == pytest.approx(2 * LAYER_DEFAULTS["dermis"][1])
    assert s.tool_radius_m == cfg.tool_radius_m
    assert s.thickness_m == tuple(la.thickness_m for la in cfg.layers)


def test_confined_layered_column_matches_the_closed_form():
    # the punch covers the whole top of a roller-sided column: uniaxial strain in every layer, the
    # same first Piola stress P_zz(l) = mu (l - 1/l) + lam ln(l) / l in each (series), sum h_i (1 - l_i) = depth
    base = h.setup_from_config(level=-1)
    r0 = 1e-3
    s = h.replace(base, tool_radius_m=r0, extent_m=r0, n_tool=2, nz=(1, 2, 3), max_depth_m=1.5e-3, n_steps=6)
    res = h.solve(s, progress=False)
    lam_mu = [h._lame(e, s.poisson) for e in s.moduli_pa]

    def stretch(p, lam, mu):
        return brentq(lambda lo: mu * (lo - 1 / lo) + lam * np.log(lo) / lo - p, 1e-3, 1.0)

    for d, f in zip(res.depths_m, res.forces_n):

        def mismatch(p, d=d):
            return sum(hi * (1 - stretch(-p, la, mu)) for hi, (la, mu) in zip(s.thickness_m, lam_mu)) - d

        p = brentq(mismatch, 1e-6, 1e7)
        assert f == pytest.approx(p * np.pi * r0**2, rel=1e-6)
    assert res.forces_n[-1] / res.depths_m[-1] > 1.5 * res.forces_n[0] / res.depths_m[0]  # strain stiffening


def _small_strain_ratios():
    s = h.setup_from_config(level=-1, max_depth_m=SMALL_STRAIN_DEPTH_M, n_steps=4)
    nh = h.solve(s, progress=False)
    lin = h.solve(h.replace(s, law="linear"), progress=False)
    d = np.array([SMALL_STRAIN_DEPTH_M / 4, SMALL_STRAIN_DEPTH_M])
    return nh.force_n(d) / lin.force_n(d)


def test_small_strain_nonlinear_matches_linear_on_a_fresh_coarse_solve():
    """The neo-Hookean solve tends to the linear one as the depth goes to 0, at first order in the depth.

    With the default moduli (dermis 20 kPa the softest layer) the first-order geometric term is 1.7 % at 0.1 mm,
    so the issue's 1 % holds below about 0.06 mm; checked at 25 um (0.35 %), and the deviation shrinks with the depth."""
    r_quarter, r_full = _small_strain_ratios()
    assert 1.0 < r_quarter < 1.0 + SMALL_STRAIN_TOL
    assert 0 < r_quarter - 1 < (r_full - 1) / 3  # shrinks at least in proportion to the depth (4.8x for 4x here)


def test_reference_small_strain_check_and_stiffening_from_the_cache():
    nh, lin = axisym(progress=False), axisym(law="linear", progress=False)
    assert nh.setup.n_tool == h.setup_from_config(level=AXI_REFERENCE_LEVEL).n_tool
    ratio = nh.force_n(SMALL_STRAIN_DEPTH_M) / lin.force_n(SMALL_STRAIN_DEPTH_M)
    # the converged mesh has the coarse mesh's first-order small-strain term (0.1 mm: 1.7 %, first order in depth)
    assert ratio - 1 == pytest.approx(_small_strain_ratios()[1] - 1, rel=0.1)
    f = nh.force_n(np.array([1e-3, 2e-3, 3e-3]))
    assert np.all(np.diff(f / np.array([1e-3, 2e-3, 3e-3])) > 0)  # secant stiffness grows with depth
    # the punch face is held at the depth; the surface far away barely moves
    assert nh.field_down_at(3e-3, 0.0) == pytest.approx(3e-3, rel=1e-6)
    assert abs(nh.field_down_at(3e-3, 25e-3)) < 0.05 * 3e-3


def test_cache_roundtrip(tmp_path):
    s = h.setup_from_config(level=-1, max_depth_m=0.5e-3, n_steps=2)
    first = h.reference(s, cache_dir=tmp_path, progress=False)
    assert (tmp_path / f"{s.key()}.npz").exists()
    again = h.reference(s, cache_dir=tmp_path, progress=False)
    np.testing.assert_allclose(again.forces_n, first.forces_n, rtol=1e-12)
    assert again.profile_depths_m.tolist() == pytest.approx([0.1e-3, 0.5e-3])
    assert h.replace(s, law="linear").key() != s.key()
