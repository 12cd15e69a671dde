"""Two flat punches on one skin (issue 32): the model against the committed 3D neo-Hookean solves; no FEM solve here."""

from __future__ import annotations

import pytest

from skin_sim_lab.validation import two_punch as tp

CFG = tp.load_tissue_config(tp.CONFIG)


@pytest.fixture(scope="module")
def rows():
    rs = tp.rows(CFG, progress=False, missing_ok=True)
    if rs is None:
        pytest.skip("a two-punch FEM solve is not in docs/validation/hyper_cache: run `skin-sim two-punch` (about an hour)")
    return rs


@pytest.fixture(scope="module")
def checks():
    c = tp.checks(CFG, progress=False, missing_ok=True)
    if c is None:
        pytest.skip("the centred or 10 mm single-punch solve is not cached: run `skin-sim two-punch`")
    return c


def test_the_reference_is_consistent(rows, checks):
    by = {(r.distance_m, r.depth_m): r for r in rows}
    for depth in tp.DEPTHS_M:
        # overlapping punches (4 mm) share the dimple: each needs less force than alone
        assert by[4e-3, depth].fem_pair_n < by[4e-3, depth].fem_single_n
        # the single punch at x = 2 mm and at x = 3 mm stand on mirror images of the egg carton (cos(0.8 pi) =
        # cos(1.2 pi), both on rete-ridge peaks): one force, from two meshes, within 1 %
        assert by[4e-3, depth].fem_single_n == pytest.approx(by[6e-3, depth].fem_single_n, rel=0.01)
        # 20 mm apart the punches barely feel each other in the reference too
        assert abs(by[20e-3, depth].fem_fraction) < tp.MIN_INTERACTION_FRACTION
        # the block is wide enough: the single punch 10 mm off centre is the centred one within 2 % (mesh change too)
        assert checks.off_centre_n[depth] == pytest.approx(checks.centred_n[depth], rel=0.02)
    # the reference's surface heaves up beyond the punch (a thin near-incompressible layer on a rigid base)
    assert checks.fem_profile[10e-3] < 0 < checks.fem_profile[4e-3]


@pytest.mark.xfail(
    strict=True,
    reason="issue 32: the model's coupling misses the FEM's at 4-10 mm (docs/validation/two_punch.md): its dimple "
    "decays monotonically, the FEM's surface heaves up 5-15 mm from a punch, so the FEM's pair is stiffer than its "
    "single at 6 and 10 mm where the model's is softer",
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
    assert rc == (0 if all(r.ok for r in rows) else 1)
