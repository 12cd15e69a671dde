"""Issue 5 validation module: FEM closed form, FEM cache, calibration recovery, Table II stats."""

from __future__ import annotations

import numpy as np
import pytest
from scipy import stats

from skin_sim_lab.validation import calibrate, fem, metrics
from skin_sim_lab.validation.scenarios import SUITE, paper_ramp_n
from skin_sim_lab.validation.stats import ROWS, table_ii, table_markdown
from skin_sim_node.model import preset


def test_fem_layered_column_matches_series_springs():
    # three default layers, flat interfaces, uniform pressure: p * sum(h_i / M_i)
    settle, closed = fem.layered_column(fem.FemSetup(), pressure_pa=1000.0)
    assert closed > 0
    assert settle == pytest.approx(closed, rel=0.01)


def test_fem_punch_small_mesh_cache_roundtrip(tmp_path):
    setup = fem.FemSetup(n_tool=2, n_out=2, nz=(1, 1, 1))
    first = fem.reference(setup, cache_dir=tmp_path, progress=False)
    assert (tmp_path / f"{setup.key()}.npz").exists()
    again = fem.reference(setup, cache_dir=tmp_path, progress=False)
    assert again.stiffness_n_per_m == pytest.approx(first.stiffness_n_per_m, rel=1e-12)
    # a flat punch pushes the tissue down: positive stiffness, unit displacement under the tool
    assert first.stiffness_n_per_m > 0
    assert first.surface_per_depth[0, 0] == pytest.approx(1.0, abs=1e-6)
    # the tool's own stiffness is bounded by Sneddon's half-space value of the stiffest layer
    assert first.stiffness_n_per_m < 2 * 1.5e6 * 2.5e-3 / (1 - 0.48**2)
    other = fem.FemSetup(n_tool=2, n_out=2, nz=(1, 1, 1), contact_xy_m=(2.5e-3, 0.0))
    assert other.key() != setup.key()


def test_axis_nodes_hit_tool_radius_and_extent():
    s = fem.axis_nodes(2.5e-3, 4, 0.03, 6)
    assert s[4] == pytest.approx(2.5e-3)
    assert s[-1] == pytest.approx(0.03)
    assert np.all(np.diff(s) > 0)


@pytest.mark.parametrize("form", ["layered", "paper"])
def test_calibration_recovers_known_parameters(form):
    """Synthetic data from known springs, stiffening exponent (layered form only) and foundation length: the fit
    recovers them.

    Layered form: the epidermis spring is not fitted (its compliance is 0.1 % of the chain's); it keeps its value."""
    base = preset("default").replace(form=form, **{"modes.m": 5, "modes.n": 5, "lod.adaptive_modes": False})
    names = calibrate.fitted_springs(base)
    truth_k = (200.0, 60.0) if form == "layered" else (6000.0, 200.0, 25.0)
    truth_n = 1.2
    changes = dict(zip(names, truth_k), **{calibrate.FOUNDATION_NAME: 4e-3})
    if form == "layered":
        changes.update(dict.fromkeys(calibrate.N_NAMES, truth_n))
    truth = base.replace(**changes)
    depths = np.concatenate([[10e-6, 20e-6, 30e-6], np.linspace(0.1e-3, 3e-3, 12)])
    xy = np.stack([np.linspace(0, 0.02, 15), np.linspace(0, 0.01, 15)], 1)
    data = calibrate.IndentData(0.0, 0.0, depths, np.zeros(depths.size), xy, np.zeros(15))
    data.forces_n, data.field_down_m = calibrate.model_response(truth, data)
    res = calibrate.fit([data], base)
    assert len(names) == (2 if form == "layered" else 3)
    for name, want in zip(names, truth_k):
        assert res.params[name] == pytest.approx(want, rel=0.01)
    assert res.params[calibrate.FOUNDATION_NAME] == pytest.approx(4e-3, rel=0.01)
    if form == "layered":
        assert res.params[calibrate.STIFFENING_NAME] == pytest.approx(truth_n, rel=0.01)
    else:
        assert calibrate.STIFFENING_NAME not in res.params
    assert res.residual_rms < 1e-6 < res.residual_rms_start


def test_calibration_reads_csv(tmp_path):
    p = tmp_path / "m.csv"
    p.write_text("x,y,depth,force\n0,0,0.002,0.2\n0,0,0.001,0.1\n0.01,0,0.001,0.3\n")
    sets = calibrate.read_csv(p)
    assert len(sets) == 2
    assert sets[0].depths_m.tolist() == [0.001, 0.002]


def test_table_ii_matches_scipy_on_fixed_data():
    rng = np.random.default_rng(5)
    a = rng.normal(-0.055, 0.032, 100)
    b = a + rng.normal(0.0, 0.005, 100)
    t = table_ii(a, b)
    ref = stats.ttest_ind(a, b, equal_var=True)
    assert t["t Stat"] == pytest.approx(ref.statistic, rel=1e-12)
    assert t["P(T<=t) two-tail"] == pytest.approx(ref.pvalue, rel=1e-12)
    assert t["P(T<=t) one-tail"] == pytest.approx(ref.pvalue / 2, rel=1e-9)
    assert t["df"] == 198
    assert t["Pooled Variance"] == pytest.approx((np.var(a, ddof=1) + np.var(b, ddof=1)) / 2, rel=1e-12)
    # the paper's Table II critical values for df = 198
    assert t["t Critical one-tail"] == pytest.approx(1.652586, abs=1e-6)
    assert t["t Critical two-tail"] == pytest.approx(1.972017, abs=1e-6)
    md = table_markdown(t)
    assert all(r in md for r in ROWS)


def test_metrics_and_suite():
    assert metrics.force_depth_error([1.1, 2.2], [1.0, 2.0]) == pytest.approx(0.1)
    assert metrics.field_error(np.ones(4) * 0.1, np.zeros(4), 1.0) == pytest.approx(0.1)
    assert {s.name for s in SUITE} >= {"peak-1layer", "peak-2layer", "peak-3layer", "valley-3layer", "edge-3layer"}
    ramp = paper_ramp_n()
    assert ramp.size == 100 and ramp.max() == pytest.approx(5.0) and ramp[-1] == 0.0


# --- calibrate: bad input gives one line and exit 2 (issue 15 item 2) ---------------------------------------------
@pytest.mark.parametrize(
    ("text", "needle"),
    [
        (None, "no such file"),
        ("", "empty file"),
        ("x,y,force\n0,0,0.1\n", "missing column(s) depth"),
        ("x,y,depth,force\n0,0,0.001,abc\n", "line 2: column 'force' is not a number: 'abc'"),
        ("x,y,depth,force\n0,0,0.001,nan\n", "not finite"),
        ("x,y,depth,force\n", "no data rows"),
        ("x,y,depth,force\n0,0,1.0,0.1\n0,0,2.0,0.3\n", "millimetres"),
        ("x,y,depth,force\n0,0,0.001,80\n", "outside 0..50 N"),
        ("x,y,depth,force\n0,0,-0.001,0.1\n", "<= 0"),
        ("x,y,depth,force\n5,0,0.001,0.1\n", "off the"),
    ],
)
def test_calibrate_bad_csv_is_one_line_exit_2(tmp_path, capsys, text, needle):
    p = tmp_path / "m.csv"
    if text is not None:
        p.write_text(text)
    with pytest.raises(calibrate.CalibrationInputError) as exc:
        calibrate.read_csv(p)
    assert needle in str(exc.value)
    rc = calibrate.main(["--csv", str(p), "--out", str(tmp_path / "o.yaml")])
    err = capsys.readouterr().err
    assert rc == 2
    assert needle in err and len(err.strip().splitlines()) == 1 and "Traceback" not in err
    assert not (tmp_path / "o.yaml").exists()


def test_calibrate_help_states_units(capsys):
    with pytest.raises(SystemExit):
        calibrate.main(["--help"])
    out = capsys.readouterr().out
    assert "metres (m)" in out and "newtons (N)" in out


def test_calibration_modules_import_one_way():
    # calibrate must not import charts (issue 13: the cycle was hidden by an import inside a function)
    import ast
    import inspect

    tree = ast.parse(inspect.getsource(calibrate))
    imported = {n.module for n in ast.walk(tree) if isinstance(n, ast.ImportFrom)}
    assert "charts" not in imported and not any(m and m.endswith(".charts") for m in imported)
    funcs = [f for f in ast.walk(tree) if isinstance(f, ast.FunctionDef)]
    inner = [n for f in funcs for n in ast.walk(f) if isinstance(n, ast.Import | ast.ImportFrom)]
    assert inner == []
