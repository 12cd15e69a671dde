"""Two flat punches on one skin (issue 32): the model against the committed 3D neo-Hookean solves; no FEM solve here."""

from __future__ import annotations

import itertools
from dataclasses import replace

import numpy as np
import pytest

from skin_sim_lab.validation import two_punch as tp

CFG = tp.load_tissue_config(tp.CONFIG)


def cached(value, missing: str):
    """``value`` (a result read from the committed FEM solves), or skip the test naming the ``missing`` solve."""
    if value is None:
        pytest.skip(f"{missing}: run `skin-sim two-punch` (about 40 min for every solve with the fem extra)")
    return value


@pytest.fixture(scope="module")
def rows():
    return cached(tp.rows(CFG, progress=False, missing_ok=True), "a two-punch FEM solve is not in docs/validation/hyper_cache")


@pytest.fixture(scope="module")
def checks():
    return cached(tp.checks(CFG, progress=False, missing_ok=True), "the centred or 10 mm single-punch solve is not cached")


def test_the_reference_is_consistent(rows, checks):
    by = {(r.distance_m, r.depth_m): r for r in rows}
    for depth in tp.DEPTHS_M:
        # overlapping punches (4 mm) share the dimple: each needs less force than alone
        assert by[4e-3, depth].fem_pair_n < by[4e-3, depth].fem_single_n
        # the single punch at x = 2 mm and at x = 3 mm stand on mirror images of the egg carton (cos(0.8 pi) =
        # cos(1.2 pi), both on rete-ridge peaks): one force, from two meshes, within 0.3 % (0.05 / 0.22 % at 1 / 2 mm;
        # 0.6-0.8 % apart at level -2 when the 4 mm single stood on the mirror of the pair's mesh, its disk's edge on a
        # staircase beyond x = 0)
        assert by[4e-3, depth].fem_single_n == pytest.approx(by[6e-3, depth].fem_single_n, rel=0.003)
        # 20 mm apart the punches barely feel each other in the reference too
        assert abs(by[20e-3, depth].fem_fraction) < tp.MIN_INTERACTION_FRACTION
        # the block is wide enough: the single punch 10 mm off centre is the centred one within 2 % (mesh change too)
        assert checks.off_centre_n[depth] == pytest.approx(checks.centred_n[depth], rel=0.02)
    # the reference's surface heaves up beyond the punch (a thin near-incompressible layer on a rigid base)
    assert checks.fem_profile[10e-3] < 0 < checks.fem_profile[4e-3]


@pytest.mark.parametrize("level", [-2, -1])
def test_the_single_of_an_overlapping_pair_has_a_mesh_conforming_to_its_disk(level):
    """The single punch of the 4 mm pair crosses x = 0; the pair's mirrored mesh conforms to the union of the two disks,
    so it gets its own: every top node at the rim on the circle, none just outside, every element's volume positive,
    the whole half block covered. The pair's quarter mesh is unchanged (x = 0 a mesh plane)."""
    from skfem import Basis, ElementHex1

    from skin_sim_lab.validation.fem import FemSetup, build_offset_mesh, mesh_levels

    base = replace(mesh_levels(level, FemSetup()), tissue=tp.fem_base(CFG).tissue)
    r0, a, w = base.tissue[2], 2e-3, base.half_width_m
    mesh = build_offset_mesh(base, a, mirror=True)
    p = mesh.p
    top = np.abs(p[2]) < 1e-12
    r = np.hypot(p[0][top] - a, p[1][top])
    h = r0 / base.n_tool
    assert np.sum(np.abs(r - r0) < 1e-12) == 4 * base.n_tool + 1  # the half ring: two nodes per element edge
    assert not np.any((r > r0 + 1e-12) & (r < r0 + 0.5 * h))  # no node just outside the rim (a staircase)
    assert p[0].min() == -w and p[0].max() == w and p[1].min() == 0 and p[1].max() == pytest.approx(w)
    corners = np.array(list(itertools.product([0.0, 1.0], repeat=3))).T
    quarter = build_offset_mesh(base, a, mirror=False)
    orientation = np.sign(quarter._mapping().detDF(corners))
    assert abs(orientation.sum()) == orientation.size  # the pair's mesh: one orientation at every corner
    det = mesh._mapping().detDF(corners)  # the Jacobian's sign at every element's 8 corners: none folded
    assert np.all(np.sign(det) == orientation.flat[0])
    vol = np.asarray(Basis(mesh, ElementHex1()).dx).sum(axis=1)  # |det J|: the block covered once
    assert vol.sum() == pytest.approx(2 * w * w * -p[2].min(), rel=1e-9)
    assert quarter.p[0].min() == 0.0  # the pair's quarter keeps x = 0 as its symmetry plane


@pytest.mark.xfail(
    strict=True,
    reason="issue 32: 6 and 10 mm pass, and 4 mm 1 mm deep with the eased overlap hold; 4 mm 2 mm deep interacts 21 % "
    "over the FEM's (aim 20 %; +19 % against level 0), and at 20 mm the thin-layer heave's tail leaves +0.7 % where "
    "the FEM has +0.0 % (the table's absolute rule is 0.4 %; docs/two_hands.md)",
)
def test_the_model_meets_the_aims(rows):
    failed = [f"{r.distance_m * 1e3:g} mm, {r.depth_m * 1e3:g} mm" for r in rows if not r.ok]
    assert not failed, "issue 32 aims missed at " + "; ".join(failed) + "\n" + tp.table(rows)


def test_the_far_pair_is_two_single_punches(rows):
    far = [r for r in rows if r.far_ok is not None]
    assert far and all(r.far_ok for r in far)


def test_the_command_table_matches(rows, checks, capsys, tmp_path):
    rc = tp.main(["--out", str(tmp_path)])
    out = capsys.readouterr().out
    assert tp.table(rows) in out
    assert tp.checks_text(checks) in out
    page = (tmp_path / "two_punch.md").read_text()
    assert tp.table(rows) in page
    for section in ("## What the reference implies for the coupling", "## Where the heave would come from"):
        assert section in page
    assert rc == (0 if all(r.ok for r in rows) else 1)


# --- what the reference implies for the coupling, and the volume term (lab analysis; the model is unchanged) ---------


@pytest.fixture(scope="module")
def implied(rows):
    imps = cached(
        tp.implied(CFG, rows, progress=False, missing_ok=True),
        "a two-punch single-punch FEM solve is not in docs/validation/hyper_cache",
    )
    return {(m.distance_m, m.depth_m): m for m in imps}


@pytest.fixture(scope="module")
def profiles():
    return cached(tp.foundation_profiles(CFG, progress=False, missing_ok=True), "the centred single-punch solve is not cached")


@pytest.mark.parametrize("name", list(tp.DISK_WEIGHTS))
def test_disk_average_of_known_fields(name):
    """``<f> = int f W dA / int W dA``, ``W = (1 - s^2/a^2)^alpha``: a linear field averages to its value at the centre
    (every weight is even in the angle), and ``s^2`` to ``a^2 <t> = a^2 / (alpha + 2)`` (``t = s^2/a^2``,
    ``int_0^1 t (1 - t)^alpha dt / int_0^1 (1 - t)^alpha dt = B(2, alpha + 1) / B(1, alpha + 1)``): 1/2, 1/3 and 2/3
    of ``a^2`` for the uniform, parabolic and rigid-punch weights."""
    alpha = tp.DISK_WEIGHTS[name]
    a, cx, cy = 2.5e-3, -3e-3, 1e-3
    assert tp.disk_average(lambda x, y: 0.3 + 200 * x - 50 * y, (cx, cy), a, alpha) == pytest.approx(
        0.3 + 200 * cx - 50 * cy, rel=1e-12
    )
    quad = tp.disk_average(lambda x, y: (x - cx) ** 2 + (y - cy) ** 2, (cx, cy), a, alpha)
    assert quad == pytest.approx(a**2 / (alpha + 2), rel=1e-12)
    # x^2 = (cx + s cos)^2: cx^2 + <s^2> / 2
    assert tp.disk_averages(lambda x, y: x**2, (cx, cy), a)[name] == pytest.approx(cx**2 + a**2 / (alpha + 2) / 2, rel=1e-12)


def test_the_implied_coupling(implied):
    """``F_single_model(depth - w) = F_pair_FEM``: the FEM's pair needs the surface under a punch lowered where the
    disks overlap (4 mm) and raised where the reference heaves (6, 10 mm); matching the interaction
    (``F_single_model(depth - w) / F_single_model(depth) = F_pair_FEM / F_single_FEM``), the raising at 6 and 10 mm is
    the FEM's single-punch field averaged over the other's disk (parabolic weight ``1 - s^2/a^2``) within 0.01 of the
    depth, and at 4 mm the disk averages are over three times the lowering needed."""
    for depth in tp.DEPTHS_M:
        four, six, ten = (implied[d, depth] for d in tp.IMPLIED_DISTANCES_M)
        for m in (four, six, ten):
            # the model's single error (0.4-3.7 %) over the force's growth with depth (about 1.4): up to 0.026
            assert m.lowering == pytest.approx(m.lowering_ratio, abs=0.03)
        assert 0.05 < four.lowering_ratio < 0.09
        assert -0.06 < six.lowering_ratio < -0.03
        assert -0.06 < ten.lowering_ratio < -0.04
    # the earlier attempt's figures: the FEM's own single-punch curve at 1 mm, +0.075, -0.043, -0.050 (level -2, the
    # 4 mm single on the pair's mirrored mesh); at level -1 with the 4 mm single on its own mesh the same within 0.001
    earlier = dict(zip(tp.IMPLIED_DISTANCES_M, (0.075, -0.043, -0.050)))
    for d, w in earlier.items():
        assert implied[d, 1e-3].fem_curve == pytest.approx(w, abs=0.002)
    deep = {d: implied[d, tp.MAX_DEPTH_M] for d in tp.IMPLIED_DISTANCES_M}
    for d in (6e-3, 10e-3):
        assert deep[d].disk["parabolic"] == pytest.approx(deep[d].lowering_ratio, abs=0.01)
    assert min(deep[4e-3].disk.values()) > 3 * deep[4e-3].lowering_ratio > 0


def test_the_volume_term_heaves():
    """``L^4 Lap^2 w + w = 0``, ``L^4 = T h^3 / (3 mu)`` (T the membranes' tensions, h the tissue, mu the Reuss mean
    shear modulus): L = 2.77 mm from the default config; outside a punch ``A ker(r/L) + B kei(r/L)`` changes sign (the
    heave); the rigid punch's heave holds the volume it displaces (``int w dA = -pi a^2 depth`` outside the disk), the
    uniform pressure has its centre at the depth; with the model's Winkler term too (``- (L^4 / l^2) Lap w``) the radial
    wavenumbers ``L^4 s^2 - (L^4 / l^2) s + 1 = 0`` are real below ``l = L / sqrt(2)`` (no oscillation) but the surface
    still rises: the displaced volume stays outside the punch, so the two decaying modes have opposite signs."""
    ell, a = tp.volume_length_m(CFG), CFG.tool_radius_m
    assert ell == pytest.approx(2.77e-3, abs=0.005e-3)
    assert tp.layered_volume_length_m(CFG) == pytest.approx(ell, rel=0.03)
    r = np.linspace(a, 60e-3, 60001)
    for edge in tp.VOLUME_EDGES:
        w = tp.volume_profile(r, ell, a, edge)
        assert w[np.searchsorted(r, 4e-3)] > 0 > w[np.searchsorted(r, 8e-3)]
        assert np.all(np.abs(w[r > 40e-3]) < 1e-3)
    rigid = tp.volume_profile(r, ell, a, "rigid")
    assert rigid[0] == pytest.approx(1.0)
    assert np.trapezoid(rigid * 2 * np.pi * r, r) == pytest.approx(-np.pi * a**2, rel=0.01)
    assert float(tp.volume_profile(0.0, ell, a, "uniform")) == pytest.approx(1.0)
    # the earlier attempt's volume term (no Winkler term) is the uniform pressure
    earlier = (0.133, -0.049, -0.079, -0.060, 0.002)
    assert tp.volume_profile(np.array(tp.PROFILE_RADII_M), ell, a, "uniform") == pytest.approx(earlier, abs=0.001)
    limit = tp.oscillation_needs_foundation_length_m(ell)
    model_l = CFG.as_flat()["patch.foundation_length_m"]
    for foundation, oscillates in ((model_l, False), (1.1 * limit, True)):
        roots = np.roots([ell**4, -(ell**4) / foundation**2, 1.0])
        assert bool(np.any(np.abs(roots.imag) > 0)) == oscillates
        both = tp.combined_profile(r, ell, foundation, a)
        assert both[0] == pytest.approx(1.0)
        assert both[np.searchsorted(r, 4e-3)] > 0 > both[np.searchsorted(r, 8e-3)]  # a heave either way
        assert np.trapezoid(both * 2 * np.pi * r, r) == pytest.approx(-np.pi * a**2, rel=0.01)
    # a long Winkler length is the volume term alone; the model's l gives the reviewer's hand solution
    assert tp.combined_profile(r, ell, 1.0, a) == pytest.approx(rigid, abs=1e-6)
    assert tp.combined_profile(np.array([4e-3, 6e-3, 8e-3, 10e-3]), ell, model_l, a) == pytest.approx(
        (0.178, -0.060, -0.076, -0.056), abs=0.001
    )


def test_the_volume_term_against_the_fem(profiles):
    """The volume term's heave against the FEM's single punch at 2 mm: it rises above rest within 0.5 mm of where the
    FEM's does, and its lowest point is within 1.5 mm of the FEM's (whose trough is flat within 0.005 of the depth
    from 6.5 to 8.5 mm); the model's profile never rises."""
    fem_rise, (fem_low, _) = profiles.rise_m["FEM"], profiles.lowest["FEM"]
    for name in (*(f"volume, {edge}" for edge in tp.VOLUME_EDGES), tp.COMBINED):
        assert profiles.rise_m[name] == pytest.approx(fem_rise, abs=0.5e-3)
        assert profiles.lowest[name][0] == pytest.approx(fem_low, abs=1.5e-3)
    assert profiles.rise_m["model"] is None


def test_the_reference_one_mesh_level_finer_moves_the_rows_little(rows):
    """Where the rows are solved one mesh level finer (``two_punch.FINE_LEVEL``, cached), the FEM's interaction over
    its single force moves by at most 0.003 and its single force by at most 1.5 %. 0.003 is a quarter of the aim's band
    on the smallest interaction the relative rule scores (20 % of 0.058 at 6 mm, 2 mm): the reference's mesh is fine
    against the aims, and a verdict that changes between the levels sits inside it (4 mm, 2 mm: docs/two_hands.md;
    measured moves 0.0006-0.0021 at 4 and 6 mm)."""
    fine = tp.fine_rows(CFG)
    if not fine:
        pytest.skip("no two-punch row is cached one mesh level finer")
    ref = {(r.distance_m, r.depth_m): r for r in rows}
    for f in fine:
        r = ref[f.distance_m, f.depth_m]
        assert abs(f.fem_fraction - r.fem_fraction) <= 0.003, (f.distance_m, f.depth_m, r.fem_fraction, f.fem_fraction)
        assert f.fem_single_n == pytest.approx(r.fem_single_n, rel=0.015)
    text = tp.mesh_convergence_text(rows, fine)
    assert text.count("\n| ") == len(fine)  # one line per row below the header and its separator
