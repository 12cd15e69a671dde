"""Model-level behaviour: shape coefficients, convergence, release, eq 9, edges, classification."""

import math

import numpy as np
import pytest
import scipy.sparse as sp
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st
from scipy.sparse.linalg import spsolve

from msgs_schema.tissue import TOOL_RADIUS_M
from skin_sim_lab.oracles import physics
from skin_sim_node.model import DEGENERATE_RETURN_S, SkinModel, classify, config_from_flat, preset
from skin_sim_node.model.calibration import PAPER_MODULI_PA, WALL_STRAIN, flat_punch_stiffness_n_per_m
from skin_sim_node.model.config import ConfigError, default_flat
from skin_sim_node.model.layered_law import DT_FLOOR_S, compression_law
from skin_sim_node.model.modal import disk_load_coefficients, shape_coefficients


def paper_form(cfg):
    """The paper's form on the given tissue, with the Sneddon k the default tissue had before the layered form."""
    k = {f"layers.{n}.stiffness_n_per_m": flat_punch_stiffness_n_per_m(e, TOOL_RADIUS_M) for n, e in PAPER_MODULI_PA.items()}
    return cfg.replace(form="paper", **k)


@pytest.fixture(params=["layered", "paper"])
def model(request, default_cfg):
    """Both forms: the behaviours tested with this fixture hold for each."""
    return SkinModel(default_cfg if request.param == "layered" else paper_form(default_cfg))


@pytest.fixture
def paper_model(default_cfg):
    return SkinModel(paper_form(default_cfg))


def static_membrane_fd(a, b, r0, n=241, foundation_length_m=0.0):
    """Finite-difference solution of -lap(w) + w / l^2 = disk indicator on the patch, fixed edges (l = 0: none)."""
    h = a / (n + 1)
    x = (np.arange(n) + 1) * h
    y = (np.arange(n) + 1) * (b / (n + 1))
    X, Y = np.meshgrid(x, y, indexing="ij")
    p = (((X - a / 2) ** 2 + (Y - b / 2) ** 2) <= r0**2).astype(float)
    lap1 = sp.diags([-1.0, 2.0, -1.0], [-1, 0, 1], shape=(n, n)) / h**2
    eye = sp.identity(n)
    L = sp.kron(lap1, eye) + sp.kron(eye, lap1)
    if foundation_length_m > 0:
        L = L + sp.identity(n * n) / foundation_length_m**2
    w = spsolve(L.tocsc(), p.ravel()).reshape(n, n)
    return x, y, w, p


def series(coef, x, y, a, b):
    m = np.arange(1, coef.shape[0] + 1)
    n = np.arange(1, coef.shape[1] + 1)
    sx = np.sin(np.outer(m, x) * np.pi / a)
    sy = np.sin(np.outer(n, y) * np.pi / b)
    return sx.T @ coef @ sy


def test_disk_load_coefficients_match_quadrature_of_eq3():
    """Closed-form load coefficients against Gauss quadrature of eq 3 over the disk."""
    a = b = 0.06
    r0 = 0.0025
    gr, gw = np.polynomial.legendre.leggauss(40)
    r = (gr + 1) * r0 / 2
    wr = gw * r0 / 2
    th = np.linspace(0, 2 * np.pi, 256, endpoint=False)
    R, TH = np.meshgrid(r, th, indexing="ij")
    X = a / 2 + R * np.cos(TH)
    Y = b / 2 + R * np.sin(TH)
    weight = (wr[:, None] * R) * (2 * np.pi / th.size)
    closed = disk_load_coefficients(9, 9, a, b, r0)
    for m in range(1, 10):
        for n in range(1, 10):
            load = 4 / (a * b) * np.sum(weight * np.sin(m * np.pi * X / a) * np.sin(n * np.pi * Y / b))
            kappa2 = np.pi**2 * ((m / a) ** 2 + (n / b) ** 2)
            assert closed[m - 1, n - 1] == pytest.approx(load / kappa2, rel=1e-9, abs=1e-16)


def test_b_mn_against_quadrature_of_static_shape():
    """Eq 3 applied numerically to the FD static deflection gives the closed-form W_mn."""
    a = b = 0.06
    r0 = 0.0025
    x, y, w, _ = static_membrane_fd(a, b, r0)
    h = x[1] - x[0]
    closed = disk_load_coefficients(5, 5, a, b, r0)
    for m, n in [(1, 1), (1, 3), (3, 3), (5, 1)]:
        quad = 4 / (a * b) * np.sum(w * np.outer(np.sin(m * np.pi * x / a), np.sin(n * np.pi * y / b))) * h * h
        assert quad == pytest.approx(closed[m - 1, n - 1], rel=0.02)


def test_series_converges_to_static_membrane_solution():
    a = b = 0.06
    r0 = 0.0025
    x, y, w, _ = static_membrane_fd(a, b, r0)
    w_fd = w / w[len(x) // 2, len(y) // 2]
    errors = []
    for modes in (1, 3, 9, 21, 41):
        beta = shape_coefficients(modes, modes, a, b, r0)
        errors.append(np.abs(series(beta, x, y, a, b) - w_fd).max())
    assert all(e1 > e2 for e1, e2 in zip(errors, errors[1:])), errors
    assert errors[-1] < 0.02 and errors[0] > 0.3


def test_foundation_shape_converges_to_fd_solution_and_is_local():
    """With a foundation (docs/model.md section 3) the series is the static solution of
    -T lap(w) + (T / l^2) w = p, and the dent decays over about l instead of spreading over the patch."""
    a = b = 0.06
    r0, ell = 0.0025, 1.63e-3
    x, y, w, _ = static_membrane_fd(a, b, r0, n=479, foundation_length_m=ell)  # 0.125 mm cells
    w_fd = w / w[len(x) // 2, len(y) // 2]
    errors = []
    for modes in (9, 21, 41, 61):
        beta = shape_coefficients(modes, modes, a, b, r0, foundation_length_m=ell)
        errors.append(np.abs(series(beta, x, y, a, b) - w_fd).max())
    assert all(e1 > e2 for e1, e2 in zip(errors, errors[1:])), errors
    assert errors[-1] < 0.02, errors
    i_c, i_far = len(x) // 2, int(np.argmin(np.abs(x - (a / 2 + r0 + 5 * ell))))  # 5 l outside the rim
    bare = static_membrane_fd(a, b, r0, n=479)[2]
    assert w_fd[i_far, i_c] < 0.02 and bare[i_far, i_c] / bare[i_c, i_c] > 0.3


def test_shape_is_unit_at_contact_and_only_odd_modes():
    beta = shape_coefficients(8, 8, 0.06, 0.06, 0.0025)
    assert series(beta, np.array([0.03]), np.array([0.03]), 0.06, 0.06)[0, 0] == pytest.approx(1.0)
    assert np.all(beta[1::2, :] == pytest.approx(0.0, abs=1e-18))
    assert np.all(beta[:, 1::2] == pytest.approx(0.0, abs=1e-18))


def test_classification_peaks_and_valleys(default_cfg):
    i_ed, i_df = default_cfg.interfaces
    peak = i_ed.mean_depth_m - i_ed.amplitude_m
    valley = i_ed.mean_depth_m + i_ed.amplitude_m
    vx = i_ed.wavelength_x_m / 2  # valley of the epidermis/dermis interface on the x axis
    # a depth between the peak and the valley reaches the dermis over a peak, not over a valley
    d = 0.5 * (peak + valley)
    assert classify(default_cfg, 0.0, 0.0, d).n_affected == 2
    assert classify(default_cfg, vx, 0.0, d).n_affected == 1
    assert classify(default_cfg, 0.0, 0.0, 0.9 * peak).n_affected == 1
    assert classify(default_cfg, 0.0, 0.0, -1e-4).n_affected == 0
    df_peak = i_df.mean_depth_m - i_df.amplitude_m
    assert classify(default_cfg, 0.0, 0.0, df_peak * 1.001).n_affected == 3
    deep = classify(default_cfg, 0.0, 0.0, 1.0)
    assert deep.n_affected == 3 and deep.bottomed


def test_model_classification_agrees(paper_model, default_cfg):
    """Paper form: the Fig 3 engagement; the layered form engages every layer at first contact."""
    model = paper_model
    i_ed = default_cfg.interfaces[0]
    d = i_ed.mean_depth_m  # between peak and valley
    for x, expect in [(0.0, 2), (i_ed.wavelength_x_m / 2, 1)]:
        model.reset()
        model.step((x, 0.0, -d), (0, 0, 0), 1e-3)
        assert model.n_affected == expect == classify(default_cfg, x, 0.0, d).n_affected
    layered = SkinModel(default_cfg)
    layered.step((0.0, 0.0, -1e-6), (0, 0, 0), 1e-3)
    assert layered.n_affected == 3 and np.all(layered.compression_m > 0)


def test_bottom_is_flagged_and_clamped(paper_model, default_cfg):
    """Paper form: below the bottom the depth is clamped (docs/model.md; the layered form has a wall instead)."""
    from skin_sim_node.model import FLAG_BOTTOMED

    model = paper_model

    f = model.step((0.0, 0.0, -0.05), (0, 0, 0), 1e-3)
    assert model.flags & FLAG_BOTTOMED
    assert math.isfinite(f) and f > 0
    assert model.depth_m == pytest.approx(default_cfg.total_thickness_m)
    # a clamped state: deeper still gives the force at the bottom (no wall beyond it; docs/model.md)
    model.reset()
    f_bottom = model.step((0.0, 0.0, -default_cfg.total_thickness_m), (0, 0, 0), 1e-3)
    model.reset()
    assert model.step((0.0, 0.0, -1.0), (0, 0, 0), 1e-3) == pytest.approx(f_bottom)


def press_and_release(model, depth=3e-3, speed=0.02, dt=1e-3):
    t_press = depth / speed
    for i in range(int(t_press / dt) + 1):
        d = min(depth, (i + 1) * dt * speed)
        model.step((0.0, 0.0, -d), (0, 0, -speed), dt)
    model.step((0.0, 0.0, 0.02), (0, 0, 0.5), dt)  # lift off with the tissue still moving
    assert not model.in_contact


@pytest.mark.parametrize("dt", [1e-6, 1e-3, 5e-2])
def test_relaxation_energy_decays_monotonically(model, dt):
    """Free membranes lose energy monotonically (eq 2's damped modes). The elastic chain: with viscoelastic arms the
    layers are driven along their recovery first (test_viscoelastic.py), so the membranes' energy is not free."""
    cfg = physics.equilibrium(model.cfg)
    model = SkinModel(cfg)
    press_and_release(model)
    energies = [model.energy()]
    steps = 3000 if dt < 1e-3 else 2000
    for _ in range(steps):
        model.step((0.0, 0.0, 0.02), (0, 0, 0), dt)
        energies.append(model.energy())
    e = np.array(energies)
    assert np.all(np.isfinite(e))
    assert np.all(np.diff(e) <= 1e-12 * e[0])
    if dt == 5e-2:  # 100 s later the tissue is at rest
        assert e[-1] < 1e-6 * e[0]
        assert abs(model.surface_displacement_at(0.0, 0.0)) < 1e-6


def test_tissue_returns_to_rest(model):
    press_and_release(model)
    for _ in range(20000):
        model.step((0.0, 0.0, 0.02), (0, 0, 0), 1e-3)
    grid = model.build_grid()
    assert np.abs(grid.displacement_m[1:]).max() < 1e-6  # dermis and fat back within a micron


def test_recontact_uses_deformed_surface(model):
    press_and_release(model, depth=3e-3)
    model.step((0.0, 0.0, 0.02), (0, 0, 0), 1e-3)  # 2 ms after the lift (layered: the dent halves every ~1 ms)
    surf = model.surface_displacement_at(0.0, 0.0)
    assert surf > 0.5e-3  # still deep in the dent
    # a tool above the dented surface but below z = 0 does not touch
    model.step((0.0, 0.0, -0.25 * surf), (0, 0, 0), 1e-3)
    assert not model.in_contact and model.force_n == 0.0
    # lowering it to the dented surface touches it
    s = model.surface_displacement_at(0.0, 0.0)
    model.step((0.0, 0.0, -(s + 1e-5)), (0, 0, 0), 1e-3)
    assert model.in_contact and model.force_n > 0


def test_unilateral_contact_never_pulls(model):
    for _ in range(100):
        model.step((0.0, 0.0, -2e-3), (0, 0, 0), 1e-3)
    # fast retraction, 1.5 mm in one tick: faster than the tissue recovers (layered: the chain relaxed with zero
    # force is longer than the new depth; paper: the common-velocity stress is negative)
    f = model.step((0.0, 0.0, -0.5e-3), (0, 0, 1.5), 1e-3)
    assert f == 0.0 and not model.in_contact


def test_edge_clipping(default_cfg):
    m = SkinModel(default_cfg)
    half = default_cfg.sheet_size_m[0] / 2
    x_edge = half - 0.003  # the 60 mm patch sticks 27 mm out of the sheet; the dent is cut 3 mm from the tool
    for _ in range(5):
        m.step((x_edge, 0.0, -2e-3), (0, 0, 0), 1e-3)
    g = m.build_grid()
    iy = int(np.argmin(np.abs(g.ys_m)))
    row = g.displacement_m.sum(axis=0)[iy]
    ix_peak = int(np.argmax(row))
    assert abs(g.xs_m[ix_peak] - x_edge) < 1.5 * (g.xs_m[1] - g.xs_m[0])
    assert row[-1] > 0.05 * row.max()  # cut off at the sheet edge, not decayed to zero
    centred = SkinModel(default_cfg)
    for _ in range(5):
        centred.step((0.0, 0.0, -2e-3), (0, 0, 0), 1e-3)
    full = centred.build_grid().displacement_m.sum()
    assert g.displacement_m.sum() < 0.95 * full  # incomplete deformation


def test_tool_off_sheet_has_no_contact(model, default_cfg):
    from skin_sim_node.model import FLAG_OFF_SHEET

    f = model.step((default_cfg.sheet_size_m[0], 0.0, -2e-3), (0, 0, 0), 1e-3)
    assert f == 0.0 and model.flags & FLAG_OFF_SHEET


@pytest.mark.parametrize("t", [0.0, 10.0, 250.0, 490.87, 981.7, 1500.0])
def test_paper_preset_reproduces_eq9(paper_cfg, t):
    """u(x,y,t) = 6.11e-6 cos(0.0032 t) sin(pi x / 0.06) sin(pi y / 0.06)  (eq 9)."""
    m = SkinModel(paper_cfg)
    assert m.basis.n_modes == 1 and m.basis.lam[0, 0] == pytest.approx(0.0032)
    depth = 6.11e-6
    m.step((0.0, 0.0, -depth), (0, 0, 0), 1e-3)
    assert m.n_affected == 1 and m.compression_m[0] == pytest.approx(depth)
    m.step((0.0, 0.0, 0.01), (0, 0, 0), t)  # release, then evolve for t seconds
    g = m.build_grid()
    X, Y = np.meshgrid(g.xs_m + 0.03, g.ys_m + 0.03)  # eq 9's patch coordinates
    inside = (X > 0) & (X < 0.06) & (Y > 0) & (Y < 0.06)
    eq9 = 6.11e-6 * np.cos(0.0032 * t) * np.sin(np.pi * X / 0.06) * np.sin(np.pi * Y / 0.06)
    np.testing.assert_allclose(g.displacement_m[0][inside], eq9[inside], atol=1e-15, rtol=1e-9)
    for px, py in [(0.03, 0.03), (0.015, 0.04), (0.05, 0.01)]:
        expect = 6.11e-6 * math.cos(0.0032 * t) * math.sin(math.pi * px / 0.06) * math.sin(math.pi * py / 0.06)
        assert m.surface_displacement_at(px - 0.03, py - 0.03) == pytest.approx(expect, rel=1e-9, abs=1e-18)


def test_degenerate_layers_and_slowest_return(paper_cfg, default_cfg):
    """A layer whose fundamental needs more than DEGENERATE_RETURN_S for a quarter period is degenerate (eq 9's)."""
    paper = SkinModel(paper_cfg)
    assert paper.degenerate_layers == ("epidermis", "dermis", "fat")
    assert paper.slowest_return_s == pytest.approx(math.pi / (2 * 0.0032)) and paper.slowest_return_s > DEGENERATE_RETURN_S
    default = SkinModel(default_cfg)
    assert default.degenerate_layers == () and 0 < default.slowest_return_s < DEGENERATE_RETURN_S
    assert default._tick == default._form.tick  # no state copied per tick without a degenerate layer


@pytest.mark.parametrize("how", ["lift", "release"])
def test_degenerate_layer_is_released_from_rest_by_the_model(paper_cfg, how):
    """Released moving at 0.2 m/s (by the lift or by release()), a degenerate layer restarts from its driven shape at
    rest: its surface follows eq 9's 6.11 um cos(0.0032 t) instead of flying to v / lambda = 62 m."""
    m = SkinModel(paper_cfg)
    depth = 6.11e-6
    n = 30
    for i in range(n):
        m.step((0.0, 0.0, -depth * (i + 1) / n), (0.0, 0.0, -0.2), depth / n / 0.2)
    assert m.driven[0] and m.v[0, 0] != 0.0
    q_driven = m.q.copy()
    if how == "release":
        m.release()
        m.step((0.0, 0.0, -0.5 * depth), (0.0, 0.0, 0.0), 0.1)  # above the dent: no re-contact, the layer relaxes
    else:
        m.step((0.0, 0.0, 5e-3), (0.0, 0.0, 0.0), 0.1)
    lam = 0.0032
    np.testing.assert_allclose(m.q, q_driven * math.cos(lam * 0.1), rtol=1e-12)
    np.testing.assert_allclose(m.v, -q_driven * lam * math.sin(lam * 0.1), rtol=1e-9)
    for _ in range(99):
        m.step((0.0, 0.0, 5e-3), (0.0, 0.0, 0.0), 0.1)
    assert m.surface_displacement_at(0.0, 0.0) == pytest.approx(depth * math.cos(lam * 10.0), rel=1e-6)


layer_values = st.fixed_dictionaries(
    {
        "thickness_m": st.floats(5e-5, 5e-3),
        "stiffness_n_per_m": st.floats(1.0, 1e5),
        "damping_n_s_per_m": st.floats(0.0, 50.0),
        "area_m2": st.floats(1e-6, 1e-4),
        "density_kg_per_m3": st.floats(800.0, 1300.0),
        "tension_n_per_m": st.floats(1e-3, 50.0),
    }
)


@settings(max_examples=60, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(
    layers=st.lists(layer_values, min_size=3, max_size=3),
    amp_frac=st.floats(0.0, 0.45),
    modes=st.integers(1, 12),
    form=st.sampled_from(["layered", "paper"]),
    sphere=st.booleans(),
    path=st.lists(
        st.tuples(
            st.floats(-0.07, 0.07),
            st.floats(-0.07, 0.07),
            st.floats(-0.02, 0.005),
            st.floats(-2.0, 2.0),
            st.sampled_from([1e-6, 1e-3, 5e-3, 0.05]),
        ),
        min_size=1,
        max_size=25,
    ),
)
def test_property_force_and_grid_finite_and_bounded(layers, amp_frac, modes, form, sphere, path):
    flat = default_flat()
    flat.update({"grid.nx": 24, "grid.ny": 24, "modes.m": modes, "modes.n": modes, "form": form})
    flat["tool.shape"] = "sphere" if sphere else "flat"
    for name, vals in zip(("epidermis", "dermis", "fat"), layers):
        for key, val in vals.items():
            flat[f"layers.{name}.{key}"] = val
    h = [v["thickness_m"] for v in layers]
    flat["interfaces.epidermis_dermis.amplitude_m"] = amp_frac * min(h[0], h[1])
    flat["interfaces.dermis_fat.amplitude_m"] = amp_frac * min(h[1], h[2])
    cfg = config_from_flat(flat)
    m = SkinModel(cfg)
    k = np.array([la.stiffness_n_per_m for la in cfg.layers])
    b = np.array([la.damping_n_s_per_m for la in cfg.layers])
    a = np.array([la.area_m2 for la in cfg.layers])
    n_exp = np.array([la.stiffening for la in cfg.layers])
    total = sum(h)
    for x, y, z, vz, dt in path:
        # the layered chain starts from its compressions, or at first contact from the layers' displacements
        c_old = max(np.abs(m.compression_m).sum(), sum(abs(m.layer_displacement_at(i, x, y)) for i in range(3)))
        f = m.step((x, y, z), (0.0, 0.0, vz), dt)
        if form == "paper":
            # a layer under the tool is at most 1 + 2 * 0.45 times its mean thickness (two cartons of amplitude <= 0.45 h)
            bound = a[0] * np.max((k * np.array(h) * 1.9 + b * abs(vz)) / a) * (1 + 1e-9)
        else:
            # series chain: the local thicknesses sum to H, the compressions to d, so some layer has strain <= d/H;
            # every layer carries the same force: F <= max_i [G0 k_i h_i phi(d/H) + b_i/dt (d + |c_old|) + arms_i], with
            # G0 = 1 + g1 + g2 the viscoelastic arms' instantaneous factor, and arms_i their carried-in force, <= 0
            # unless a layer starts in tension: then <= (g1 + g2) k_i |c_old| / (0.1 h_i) * h_i (local thickness >= 0.1 h)
            d = max(-z, 0.0)
            ve = cfg.viscoelastic
            g_sum = ve.g1 + ve.g2
            bound = 0.0
            for i in range(3):
                ph, _ = compression_law(d / total, n_exp[i], WALL_STRAIN)
                arms = g_sum * k[i] * c_old * 10.0
                bound = max(bound, (1.0 + g_sum) * k[i] * h[i] * ph + b[i] / max(dt, DT_FLOOR_S) * (d + c_old) + arms)
            bound = bound * (1 + 1e-9) + 1e-12
        assert math.isfinite(f) and 0.0 <= f <= bound
    g = m.build_grid()
    assert np.all(np.isfinite(g.heights_m))
    # paper form: the depth is clamped at the bottom; layered form: the bottom is a finite wall, so a tool far below
    # a thin stack compresses the layers past their thickness (a 15.6 mm press into 0.18 mm: 5.2 mm per layer), and
    # what bounds the grid is the tool's depth (the compressions sum to it)
    deepest = max(max(-z for _, _, z, _, _ in path), 0.0)
    assert np.abs(g.displacement_m).max() <= 20 * max(cfg.total_thickness_m, deepest)


@pytest.mark.parametrize(
    "change, message",
    [
        ({"layers.dermis.stiffness_n_per_m": -5.0}, "must be >"),
        ({"layers.fat.thickness_m": 0.0}, "must be >"),
        ({"interfaces.epidermis_dermis.amplitude_m": 80e-6}, "interfaces cross"),
        ({"interfaces.dermis_fat.amplitude_m": 2e-3}, "interfaces cross"),
        ({"patch.size_x_m": 0.2}, "larger than the sheet"),
        ({"modes.m": 0}, "must be >="),
        ({"layers.dermis.area_m2": float("nan")}, "finite"),
        ({"no.such.param": 1.0}, "unknown"),
        ({"grid.nx": "many"}, "expected an integer"),
    ],
)
def test_config_validation_errors(change, message):
    flat = default_flat()
    flat.update(change)
    with pytest.raises(ConfigError, match=message):
        config_from_flat(flat)


def test_yaml_presets_match_schema(default_cfg):
    assert default_cfg.as_flat() == default_flat()


def test_contract_defaults_are_the_calibration_formulas_bit_for_bit():
    """Issue 28: the contract holds literal defaults; the model's calibration (fitted constants and formulas) gives
    exactly those literals, and the needle's lateral bed reads the live layers' moduli."""
    from msgs_schema.tissue import LAYER_PARAMETER_DEFAULTS, STIFFENING_EXPONENT
    from skin_sim_node.model import calibration as cal

    assert cal.layer_parameter_defaults() == LAYER_PARAMETER_DEFAULTS  # == on floats: bit for bit
    assert cal.FITTED_STIFFENING_EXPONENT == STIFFENING_EXPONENT
    cfg = preset("default")
    assert cal.youngs_moduli_pa(cfg) == [v[1] for v in cal.LAYER_SOURCES.values()]  # exact at the defaults
    stiffer = cfg.replace(**{"layers.dermis.stiffness_n_per_m": 2 * cfg.layers[1].stiffness_n_per_m})
    assert cal.youngs_moduli_pa(stiffer)[1] == pytest.approx(2 * cal.LAYER_SOURCES["dermis"][1], rel=1e-15)


def test_needle_lateral_bed_follows_a_live_stiffness_change():
    from skin_sim_node.model.layout import NL_MODULUS
    from skin_sim_node.model.needle import NeedleModel

    cfg = preset("needle")
    stiffer = cfg.replace(**{"layers.fat.stiffness_n_per_m": 3 * cfg.layers[2].stiffness_n_per_m})
    a, b = NeedleModel(cfg).nlp[NL_MODULUS], NeedleModel(stiffer).nlp[NL_MODULUS]
    assert b[2] == pytest.approx(3 * a[2], rel=1e-15) and b[0] == a[0] and b[1] == a[1]


def test_contract_tangential_stiffness_is_the_calibration_formula():
    """Issue 30's k_t default (a literal in the contract) is the contact-mechanics formula of the calibration."""
    from msgs_schema.tissue import TANGENTIAL_STIFFNESS_N_PER_M
    from skin_sim_node.model import calibration as cal

    assert TANGENTIAL_STIFFNESS_N_PER_M == cal.tangential_stiffness_n_per_m()
