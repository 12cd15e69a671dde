"""Tension lines (issue 20, item 4): the anisotropic membrane, the patch turned onto the lines, and what they change.

``T_x = T sqrt(r)`` along the lines and ``T_y = T / sqrt(r)`` across (``anisotropy.ratio = r``), the patch's first side
along ``anisotropy.angle_rad``; the normal force sees only the geometric mean (docs/model.md, "Tension lines").
"""

import math
from pathlib import Path

import numpy as np
import pytest
import scipy.sparse as sps
import scipy.sparse.linalg as spla
import yaml
from conftest import kernel

from msgs_schema.tissue import ANISOTROPY_RATIO
from skin_sim_lab.oracles import reference as ref
from skin_sim_lab.validation import tension_lines as tl
from skin_sim_node.model import SkinModel, preset
from skin_sim_node.model import grid as gk
from skin_sim_node.model import modal_kernels as mk
from skin_sim_node.model.modal import membrane_wavenumber2, modal_basis, shape_coefficients

ROOT = Path(__file__).resolve().parents[1]
DATA = yaml.safe_load((ROOT / "docs" / "data" / "tension_lines.yaml").read_text())


@pytest.fixture(scope="module")
def cfg():
    return preset("default")


def test_default_ratio_and_tension_are_the_cited_data(cfg):
    """The default ratio is Lakhani's linear moduli along / across; the membranes' geometric-mean sum is in Flynn's
    in-vivo forearm band."""
    lak = DATA["lakhani_2021"]["linear_modulus_mpa"]
    assert cfg.anisotropy_ratio == ANISOTROPY_RATIO == pytest.approx(lak["max"] / lak["min"], abs=0.005)
    band = DATA["flynn_2011"]["max_tension_n_per_m"]
    total = sum(la.tension_n_per_m for la in cfg.layers)
    assert band["anterior_lower_forearm"] <= total <= band["anterior_upper_forearm"]
    iso = preset("isotropic")
    assert iso.anisotropy_ratio == 1.0 and iso.replace(**{"anisotropy.ratio": cfg.anisotropy_ratio}) == cfg
    assert preset("paper").anisotropy_ratio == 1.0


def test_modal_frequencies_follow_the_anisotropic_wave_operator(cfg):
    """``lambda_mn^2 = (T_x kx^2 + T_y ky^2 + T / l^2) / rho_A`` with the geometric mean ``T`` in the foundation."""
    b = modal_basis(cfg)
    a_side, b_side = cfg.patch_size_m
    sr = math.sqrt(cfg.anisotropy_ratio)
    kx, ky = b.mode_m * math.pi / a_side, b.mode_n * math.pi / b_side
    for li, layer in enumerate(cfg.layers):
        t, rho = layer.tension_n_per_m, layer.areal_density_kg_per_m2
        want = (t * sr * kx**2 + t / sr * ky**2 + t / cfg.foundation_length_m**2) / rho
        np.testing.assert_allclose(b.lam[li] ** 2, want, rtol=1e-12)
    # ratio 1: the isotropic expression, bit for bit
    iso = modal_basis(preset("isotropic"))
    kappa = np.sqrt(np.pi**2 * ((b.mode_m / a_side) ** 2 + (b.mode_n / b_side) ** 2) + 1 / cfg.foundation_length_m**2)
    np.testing.assert_array_equal(iso.lam, np.array([la.wave_speed_m_per_s * kappa for la in cfg.layers]))
    assert membrane_wavenumber2(3, 5, a_side, b_side, 1.0) == np.pi**2 * (1.0 * (3 / a_side) ** 2 + (5 / b_side) ** 2 / 1.0)


def test_static_shape_converges_to_the_anisotropic_fd_solution():
    """The series shape (eq 3 with T_x, T_y and the foundation) against a finite-difference solve of
    ``-(T_x u_xx + T_y u_yy) + (T / l^2) u = p`` on the patch (a 2.5 mm disk load, 0.1 mm cells)."""
    a = b = 0.02
    r0, ell, ratio = 2.5e-3, 1.63e-3, 1.79
    n = 199
    h = a / (n + 1)
    x = -a / 2 + h * np.arange(1, n + 1)
    X, Y = np.meshgrid(x, x)
    d2 = sps.diags([np.ones(n - 1), -2 * np.ones(n), np.ones(n - 1)], [-1, 0, 1]) / h**2
    eye = sps.identity(n)
    sr = math.sqrt(ratio)
    op = -(sr * sps.kron(eye, d2) + sps.kron(d2, eye) / sr) + sps.identity(n * n) / ell**2  # rows y, columns x
    load = (X**2 + Y**2 <= r0**2).astype(float).ravel()
    u_fd = spla.spsolve(op.tocsc(), load).reshape(n, n)
    u_fd /= u_fd[n // 2, n // 2]
    modes = 59
    beta = shape_coefficients(modes, modes, a, b, r0, foundation_length_m=ell, ratio=ratio)
    m = np.arange(1, modes + 1)
    sx = np.sin(np.outer(m, X[0] + a / 2) * np.pi / a)
    sy = np.sin(np.outer(m, x + b / 2) * np.pi / b)
    u_series = sy.T @ beta.T @ sx
    assert np.abs(u_series - u_fd).max() < 0.02
    # elongated along the lines (x): the dent reaches further along x than along y
    assert u_fd[n // 2, n // 2 + 40] > 1.2 * u_fd[n // 2 + 40, n // 2]


def test_turned_point_and_grid_match_reference(compiled, rng):
    """The turned patch: point and grid kernels against eq 2 summed in the turned frame; the box covers the patch."""
    point = kernel(mk.layer_point_displacement_rot, compiled)
    field = kernel(gk.layer_field_box_rot, compiled)
    box = kernel(gk.patch_box, compiled)
    a, b = 0.03, 0.02
    mode_m = np.array([1, 1, 3, 3, 5], dtype=np.int64)
    mode_n = np.array([1, 3, 1, 3, 5], dtype=np.int64)
    q = rng.normal(size=5) * 1e-3
    xs = np.linspace(-0.05, 0.05, 101)
    ys = np.linspace(-0.04, 0.04, 81)
    m_used, n_used = np.unique(mode_m), np.unique(mode_n)
    for angle in (0.0, 0.4, -1.1, math.pi / 2):
        c, s = math.cos(angle), math.sin(angle)
        cx, cy = 0.004, -0.003
        want = ref.layer_field_ref(q, cx, cy, mode_m, mode_n, a, b, xs, ys, angle)
        out = np.full((ys.size, xs.size), np.nan)
        ix0, ix1, iy0, iy1 = box(xs, ys, cx, cy, a, b, c, s)
        out[:, :] = 0.0
        field(
            q, cx, cy, mode_m, mode_n, m_used, n_used, a, b, c, s, xs, ys, ix0, ix1, iy0, iy1,
            np.zeros((5, 5)), np.zeros((6, xs.size)), np.zeros((6, ys.size)), np.zeros((6, xs.size)), out,
        )  # fmt: skip
        np.testing.assert_allclose(out, want, rtol=1e-10, atol=1e-17)
        inside = np.argwhere(want != 0.0)
        assert inside[:, 0].min() >= iy0 and inside[:, 0].max() < iy1
        assert inside[:, 1].min() >= ix0 and inside[:, 1].max() < ix1
        sbx, sby = np.zeros(6), np.zeros(6)
        for iy, ix in rng.integers(0, [ys.size, xs.size], size=(30, 2)):
            u = point(q, cx, cy, mode_m, mode_n, a, b, c, s, xs[ix], ys[iy], sbx, sby)
            assert u == pytest.approx(want[iy, ix], rel=1e-10, abs=1e-17)
    # angle 0: the unturned kernels, exactly
    plain = kernel(mk.layer_point_displacement, compiled)(q, 0.004, -0.003, mode_m, mode_n, a, b, 0.011, 0.002, sbx, sby)
    assert point(q, 0.004, -0.003, mode_m, mode_n, a, b, 1.0, 0.0, 0.011, 0.002, sbx, sby) == plain


def test_turned_model_is_the_unturned_one_rotated_about_the_tool(cfg):
    """Lines at 35 degrees: the dent is the 0-degree dent turned about the tool, and the force is the same."""
    theta = math.radians(35.0)
    m0 = SkinModel(cfg)
    m1 = SkinModel(cfg.replace(**{"anisotropy.angle_rad": theta}))
    x0, y0 = 0.007, -0.004
    for i in range(40):
        z = -1.5e-3 * min(1.0, (i + 1) / 20)
        f0 = m0.step((x0, y0, z), (0.0, 0.0, 0.0), 1e-3)
        f1 = m1.step((x0, y0, z), (0.0, 0.0, 0.0), 1e-3)
        assert f1 == f0
    c, s = math.cos(theta), math.sin(theta)
    for px, py in np.random.default_rng(5).uniform(-6e-3, 6e-3, size=(40, 2)):
        back = (c * px + s * py, -s * px + c * py)  # the point in the lines' frame
        assert m1.surface_displacement_at(x0 + px, y0 + py) == pytest.approx(
            m0.surface_displacement_at(x0 + back[0], y0 + back[1]), rel=1e-9, abs=1e-15
        )


def test_turned_patch_grid_patch_only_equals_whole_sheet_and_clips_at_the_edge(cfg):
    """Patch-only grid work with a turned patch gives the whole-sheet field, also where the patch passes the edge;
    the edge footprint does not depend on the angle."""
    turned = cfg.replace(**{"anisotropy.angle_rad": 0.6})
    hx = 0.5 * cfg.sheet_size_m[0]
    for x0 in (0.0, hx - 0.01, hx + 0.001):
        fields, forces = [], []
        for patch_only in (True, False):
            m = SkinModel(turned.replace(**{"lod.patch_only": patch_only}))
            for i in range(30):
                forces.append(m.step((x0, 0.002, -1e-3 * min(1.0, (i + 1) / 15)), (0.0, 0.0, 0.0), 1e-3))
            m.build_grid()
            fields.append(m.build_grid().heights_m.copy())  # twice: the second clears the first's box
        np.testing.assert_array_equal(fields[0], fields[1])
        plain = SkinModel(cfg)
        for i in range(30):
            f = plain.step((x0, 0.002, -1e-3 * min(1.0, (i + 1) / 15)), (0.0, 0.0, 0.0), 1e-3)
        assert forces[-1] == f  # the footprint and the chain do not see the lines


def test_normal_force_sees_only_the_geometric_mean(cfg):
    """A press gives the same force with and without the lines (Delafargue and Ulm 2004, eq 22: the indentation
    modulus normal to the lines is the geometric mean, the calibrated modulus)."""
    iso = preset("isotropic")
    for shape in ("flat", "sphere"):
        a = SkinModel(cfg.replace(**{"tool.shape": shape}))
        b = SkinModel(iso.replace(**{"tool.shape": shape}))
        for i in range(60):
            z = -2e-3 * min(1.0, (i + 1) / 30)
            assert a.step((0.001, 0.002, z), (0, 0, -0.07), 1e-3) == b.step((0.001, 0.002, z), (0, 0, -0.07), 1e-3)


def test_dent_is_elongated_along_the_lines(cfg):
    """The dent of a 2 mm press (0.25 mm grid): longer along the lines, round without them, and it turns with them."""
    d = tl.dent(cfg)
    iso = tl.dent(preset("isotropic"))
    assert iso.aspect == pytest.approx(1.0, abs=1e-9) and iso.moment_aspect == pytest.approx(1.0, abs=1e-9)
    # far from the tool the decay lengths differ by r^(1/2); near it the disk load rounds the dent
    assert 1.05 < d.aspect < math.sqrt(cfg.anisotropy_ratio) and 1.05 < d.moment_aspect < math.sqrt(cfg.anisotropy_ratio)
    assert d.half_width_along_m > iso.half_width_along_m > d.half_width_across_m
    turned = tl.dent(cfg.replace(**{"anisotropy.angle_rad": math.pi / 2}))  # the lines along y
    assert turned.aspect == pytest.approx(d.aspect, rel=1e-6)
    stronger = tl.dent(cfg.replace(**{"anisotropy.ratio": 3.0}))
    assert stronger.aspect > d.aspect


def test_drag_along_and_across_the_lines(cfg):
    """What the model cannot produce: a stroke started from rest drags the same along and across the lines (the
    normal force does not see the lines, the contact normal is fixed at first contact, friction is isotropic)."""
    fn_a, ft_a = tl.stroke_forces(cfg, across=False)
    fn_c, ft_c = tl.stroke_forces(cfg, across=True)
    assert fn_a > 0.1 and ft_a == pytest.approx(cfg.friction_coefficient * fn_a, rel=0.01)
    assert (fn_c, ft_c) == pytest.approx((fn_a, ft_a), rel=1e-9)


def test_report_prints_the_figures():
    text = tl.report(("default",))
    assert "aspect" in text and "drag along / across" in text and "anisotropy.ratio = 1.79" in text
