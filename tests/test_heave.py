"""The heave kernel (skin_sim_node.model.heave) against slow references, and its use in the two-tool coupling."""

from __future__ import annotations

import numpy as np
import pytest
from scipy import integrate

from skin_sim_node.model import heave as hv
from skin_sim_node.model import preset
from skin_sim_node.tools import DOWN, ToolPose, make_tool
from skin_sim_node.tools.hands import SharedSkin


@pytest.fixture(scope="module")
def cfg():
    return preset("default")


def test_the_volume_length_is_the_thin_layer_formula(cfg):
    t, h, mu = hv.volume_parameters(cfg)
    assert t == pytest.approx(sum(la.tension_n_per_m for la in cfg.layers))
    assert h == pytest.approx(sum(la.thickness_m for la in cfg.layers))
    assert hv.volume_length_m(cfg) == pytest.approx((t * h**3 / (3 * mu)) ** 0.25)
    assert hv.volume_length_m(cfg) == pytest.approx(2.77e-3, abs=0.01e-3)  # docs/two_hands.md


@pytest.mark.parametrize("foundation_m", [1.63e-3, 3e-3])  # below and above L / sqrt(2): real and complex roots
@pytest.mark.parametrize("radius_m", [0.5e-3, 2.5e-3, 5e-3])
def test_the_punch_profile_holds_the_displaced_volume(cfg, foundation_m, radius_m):
    """w = depth on the disk, and the surface outside it holds minus the punch's volume (incompressible layer)."""
    ell = hv.volume_length_m(cfg)

    def w(r):
        return float(hv.combined_profile(r, ell, foundation_m, radius_m))

    assert w(radius_m) == pytest.approx(1.0, rel=1e-9)
    outside, _ = integrate.quad(lambda r: 2 * np.pi * r * w(r), radius_m, 0.2, limit=400)
    assert outside == pytest.approx(-np.pi * radius_m**2, rel=1e-6)
    assert min(w(r) for r in np.linspace(radius_m, 30e-3, 300)) < 0.0  # it rises beside the punch


def test_the_disk_average_against_a_polar_grid(cfg):
    """The Gauss-Jacobi / trapezoid average against a fine midpoint sum in polar coordinates."""

    def field(x, y):
        return np.exp(-((x - 1e-3) ** 2 + 0.5 * y**2) / 4e-6) + x * 1e2

    a, centre = 2.5e-3, (0.5e-3, -0.3e-3)
    got = hv.disk_average(field, centre, a, 1.0, hv.DISK_RADIAL_NODES, hv.DISK_ANGLE_NODES)
    n = 2000
    s = (np.arange(n) + 0.5) / n * a
    th = (np.arange(n) + 0.5) / n * 2 * np.pi
    ss, tt = np.meshgrid(s, th, indexing="ij")
    wgt = (1 - ss**2 / a**2) * ss
    ref = np.sum(field(centre[0] + ss * np.cos(tt), centre[1] + ss * np.sin(tt)) * wgt) / np.sum(wgt)
    assert got == pytest.approx(ref, rel=1e-5)


def test_the_coupling_table_heaves_where_the_reference_does(cfg):
    """Lowered at 4 mm, raised 6-10 mm out (the 3D reference's single punch: raised from 5.3 mm, lowest about 7.5 mm),
    nothing far out; a receiver of radius 0 reads the profile itself."""
    a = cfg.tool_radius_m
    s, g = hv.coupling_table(cfg, a, a)
    at = {mm: float(np.interp(mm * 1e-3, s, g)) for mm in (4, 6, 8, 10, 44)}
    assert at[4] > 0.0 > at[6] and at[8] < at[10] < 0.0 and abs(at[44]) < 1e-4
    s0, g0 = hv.coupling_table(cfg, a, 0.0)
    ell = hv.volume_length_m(cfg)
    np.testing.assert_allclose(g0[:-1], hv.combined_profile(s0[:-1], ell, cfg.foundation_length_m, a), atol=1e-6)


def test_a_punch_lowers_a_needle_by_its_depth_times_the_profile(cfg):
    """The coupling reads a flat tool's own depth at its centre, through the pair's load maps (the needle untouched:
    ``Psi_needle'(0) Psi_punch(e)``, :mod:`skin_sim_node.tools.reciprocal`), times the pair's kernel at the other
    tool's place: the mean of the punch's profile at the needle's point and the needle's footprint's profile over the
    punch's disk."""
    ncfg = preset("needle")
    skin = SharedSkin([make_tool(ncfg), make_tool(cfg)])
    needle, punch = skin.hands
    for k in range(200):
        punch.step(ToolPose((7e-3, 0.0, -2e-3 * min(k, 100) / 100), (0.0, 0.0, 0.0), DOWN, 1e-3, k == 0))
    depth = punch.tissue.surface_displacement_at(7e-3, 0.0)
    s, g = hv.coupling_table(cfg, cfg.tool_radius_m, 0.0)
    _, g_back = hv.coupling_table(ncfg, 0.5 * ncfg.needle_outer_diameter_m, cfg.tool_radius_m)
    lowering = needle.load_map.lowering(0.0, punch.load_map, depth)
    assert lowering > depth  # an untouched needle's chain is softer than the pressed punch's: Betti gives it more
    want = lowering * float(np.interp(7e-3, s, 0.5 * (g + g_back)))
    assert want < 0.0  # 7 mm out: raised
    assert skin.others_displacement_at(0, 0.0, 0.0) == pytest.approx(want, rel=1e-12)
    assert skin.others_displacement_at(1, 7e-3, 0.0) == 0.0  # the needle has not touched


def test_the_paper_form_couples_through_its_own_fields(cfg):
    """The paper form's membranes carry almost no tension (L far below MIN_LENGTH_M): no kernel, the other tool's own
    field is read, as before the heave."""
    paper = preset("paper")
    assert hv.volume_length_m(paper) < hv.MIN_LENGTH_M <= hv.volume_length_m(cfg)
    assert not hv.uses_kernel(paper) and hv.uses_kernel(cfg)
    skin = SharedSkin([make_tool(paper), make_tool(paper)])
    a, b = skin.hands
    for k in range(100):
        b.step(ToolPose((4e-3, 0.0, -1e-3 * min(k, 50) / 50), (0.0, 0.0, 0.0), DOWN, 1e-3, k == 0))
    assert skin.others_displacement_at(0, 3e-3, 0.0) == b.tissue.surface_displacement_at(3e-3, 0.0) > 0.0


def test_a_place_that_is_not_finite_gives_nan_and_far_away_nothing(cfg):
    skin = SharedSkin([make_tool(cfg), make_tool(cfg)])
    a, b = skin.hands
    for k in range(50):
        b.step(ToolPose((6e-3, 0.0, -1e-3 * min(k, 25) / 25), (0.0, 0.0, 0.0), DOWN, 1e-3, k == 0))
    assert np.isnan(skin.others_displacement_at(0, float("nan"), 0.0))
    assert skin.others_displacement_at(0, float("inf"), 0.0) == 0.0
    assert skin.others_displacement_at(0, 6e-3 + 50e-3, 0.0) == 0.0  # past the kernel's 45 mm
