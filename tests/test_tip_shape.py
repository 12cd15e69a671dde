"""Issue 20, item 2: the round tip's contact law and its neo-Hookean sphere reference (read from the cache)."""

from __future__ import annotations

import math

import numpy as np
import pytest

from skin_sim_lab.validation import sphere as sph
from skin_sim_lab.validation.tip_check import flat_layers, model_curve
from skin_sim_node.model import layered_contact as lkc
from skin_sim_node.model import preset


@pytest.fixture(params=["compiled", "py_func"])
def geometry(request):
    return lkc.contact_geometry if request.param == "compiled" else lkc.contact_geometry.py_func


def _cached(setup):
    path = sph.CACHE_DIR / f"sphere-{setup.key()}.npz"
    if not path.exists():
        pytest.skip(f"sphere reference not cached ({path.name}): python -m skin_sim_lab.validation.sphere")
    return sph.reference(setup, progress=False)


def test_flat_punch_geometry_is_exactly_the_punch(geometry):
    for d in (1e-6, 1e-3, 2.5e-3, 3e-3, 1.0):
        assert geometry(d, 2.5e-3, False) == (2.5e-3, 1.0, 0.0, 0.0)


@pytest.mark.parametrize("radius", [1e-3, 2.5e-3, 5e-3])
def test_sphere_geometry_derivatives_match_finite_differences(geometry, radius):
    for d in np.concatenate([np.geomspace(1e-6, 0.99, 12) * radius, [1.01 * radius, 1.5 * radius, 3 * radius]]):
        a, s, ds, da = geometry(d, radius, True)
        h = 1e-7 * d
        ap, sp_, _, _ = geometry(d + h, radius, True)
        am, sm, _, _ = geometry(d - h, radius, True)
        assert ds == pytest.approx((sp_ - sm) / (2 * h), rel=1e-5, abs=1e-12)
        assert da == pytest.approx((ap - am) / (2 * h), rel=1e-5, abs=1e-12)
        assert 0.0 < s <= 1.0 and 0.0 < a <= radius


def test_sphere_scale_is_continuous_at_the_equator_and_grows(geometry):
    r = 2.5e-3
    lo = geometry(r * (1 - 1e-12), r, True)
    hi = geometry(r * (1 + 1e-12), r, True)
    assert lo[0] == pytest.approx(hi[0], rel=1e-9) and lo[1] == pytest.approx(hi[1], rel=1e-9)
    s = np.array([geometry(d, r, True)[1] for d in np.geomspace(1e-6, 30 * r, 80)])
    assert np.all(np.diff(s[s < 1.0]) > 0) and np.all(np.diff(s) >= 0) and s[-1] == 1.0  # grows to the punch's


def test_sphere_scale_reduces_to_hertz_on_a_half_space():
    """With only the half-space term of the punch law, ``s T`` is Hertz's ``4/3 E* sqrt(R) d^1.5`` when
    ``T = 2 E* R d`` (Sneddon's punch)."""
    e_star, r, d = 26e3, 2.5e-3, 0.1e-3
    c0, c1, c2, c3 = 0.0, 1.0, 0.0, 0.0
    a = math.sqrt(r * d)
    s = 2.0 * (0.5 * c0 + c1 * a / 3.0 + c2 * a * a / 4.0 + c3 * a**3 / 5.0) / (c0 + c1 * r + c2 * r * r + c3 * r**3)
    assert s * 2 * e_star * r * d == pytest.approx(4 / 3 * e_star * math.sqrt(r) * d**1.5, rel=1e-12)


def test_sphere_reference_contact_is_unilateral_and_converged():
    res = _cached(sph.sphere_setup())
    c = sph.contact_checks(res)
    assert c["min_force_n"] > 0  # compressive at every depth
    assert c["max_penetration_over_depth"] < 2e-3  # no node inside the sphere beyond the rounded kink
    assert c["free_surface_force_over_force"] < 1e-6  # no traction outside the contact
    assert np.all(np.diff(res.forces_n) > 0)


def test_sphere_reference_meets_hertz_on_a_half_space():
    """Linear law, one material, 40 mm deep: Hertz within the discretisation at 0.05-0.2 mm (a / H < 0.01)."""
    res = _cached(sph.homogeneous_setup())
    d = np.array([0.05e-3, 0.1e-3, 0.2e-3])
    ratio = res.force_n(d) / sph.hertz_force_n(d, res.setup.axi.tool_radius_m, res.setup.axi.moduli_pa[0])
    assert np.all(np.abs(ratio - 1) < 0.05)


def test_model_sphere_follows_the_reference():
    """The layered form's sphere (flat layers, the reference's geometry) within 10 % of the reference's force over
    0.1-3 mm, and its force exponent at small depth within 0.1 of the reference's."""
    res = _cached(sph.sphere_setup())
    cfg = flat_layers(preset("default").replace(**{"tool.shape": "sphere"}))
    f, _ = model_curve(cfg)
    fr = res.force_n(np.array(sph.CHECK_DEPTHS_M))
    err = f / fr - 1
    assert np.all(np.abs(err[1:]) < 0.10), err
    e_model = math.log(f[1] / f[0]) / math.log(2.0)
    e_ref = math.log(fr[1] / fr[0]) / math.log(2.0)
    assert abs(e_model - e_ref) < 0.1


def test_model_sphere_is_softer_than_the_punch_and_monotone():
    base = flat_layers(preset("default"))
    fs, ks = model_curve(base.replace(**{"tool.shape": "sphere"}))
    ff, _ = model_curve(base)
    assert np.all(fs < ff) and np.all(np.diff(fs) > 0) and np.all(ks > 0)


def test_flat_punch_stiffness_follows_the_reference():
    """Issue 20 item 3a: the default's quasi-static dF/dd within 10 % of the punch reference over 0.5-3 mm, its
    small-strain stiffness within 5 % of the reference's linear-law stiffness, its force within 5 % (origin)."""
    from skin_sim_lab.validation.fit_law import curve_slope
    from skin_sim_lab.validation.references import axisym
    from skin_sim_lab.validation.tip_check import SMALL_STRAIN_DEPTH_M

    ref = axisym(None, progress=False)
    lin = axisym(None, law="linear", progress=False)
    depths = (0.5e-3, 1e-3, 1.5e-3, 2e-3, 2.5e-3, 3e-3)
    f, k = model_curve(preset("default"), depths)
    kr = np.array([curve_slope(ref.depths_m, ref.forces_n, d) for d in depths])
    assert np.all(np.abs(k / kr - 1) < 0.10), k / kr
    assert np.all(np.abs(f / ref.force_n(np.array(depths)) - 1) < 0.05)
    k0 = model_curve(preset("default"), (SMALL_STRAIN_DEPTH_M,))[1][0]
    assert k0 == pytest.approx(float(lin.force_n(1e-3) / 1e-3), rel=0.05)


def test_fit_law_reproduces_the_defaults():
    """The committed fit script's chain at the schema defaults gives the same force as the model (same law, same
    thicknesses), so its printed fit is the source of the defaults."""
    from skin_sim_lab.validation.fit_law import Chain
    from skin_sim_node.model import calibration as schema

    ch = Chain()
    s = [schema.LOAD_SPREADING[la.name] for la in ch.cfg.layers]
    d = np.array([0.5e-3, 1e-3, 3e-3])
    f_chain = ch.forces(s, schema.FITTED_STIFFENING_EXPONENT, schema.WALL_STRAIN, d)
    f_model, _ = model_curve(preset("default"), tuple(d))
    np.testing.assert_allclose(f_chain, f_model, rtol=1e-5)  # the static step leaves dampers at ~1e-6 (STATIC_DT_S)
