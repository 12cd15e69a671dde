"""``skin-sim chart`` writes to out/ unless told ``--docs``, and says what it wrote."""

from __future__ import annotations

import os
import subprocess
import sys
from pathlib import Path

REPO = Path(__file__).resolve().parents[1]


def run(cwd, *argv):
    env = dict(os.environ, PYTHONPATH=str(REPO) + os.pathsep + os.environ.get("PYTHONPATH", ""))
    return subprocess.run(
        [sys.executable, "-m", "skin_sim_node.cli", "chart", *argv], cwd=cwd, env=env, capture_output=True, text=True, timeout=600
    )


def test_chart_writes_to_out_and_leaves_the_tracked_docs_alone(tmp_path):
    docs = REPO / "docs" / "figures"
    before = {p.name: p.stat().st_mtime_ns for p in docs.iterdir()}
    p = run(tmp_path, "model")
    assert p.returncode == 0, p.stdout + p.stderr
    written = sorted(q.name for q in (tmp_path / "out" / "chart" / "model").iterdir())
    assert written == ["fig4_cross_sections.png", "force_depth_release.png"]
    assert p.stdout.splitlines()[0].startswith("skin-sim chart model: writing to out/chart/model, not the tracked docs")
    assert p.stdout.strip().splitlines()[-1] == (
        "skin-sim chart model: wrote 2 file(s) in out/chart/model: fig4_cross_sections.png, force_depth_release.png"
    )
    assert {q.name: q.stat().st_mtime_ns for q in docs.iterdir()} == before


def test_chart_docs_and_out_together_is_an_error(tmp_path):
    p = run(tmp_path, "model", "--docs", "--out", str(tmp_path / "x"))
    assert p.returncode == 2 and "give --docs or --out, not both" in p.stderr
    assert not (tmp_path / "x").exists()


def test_force_path_draws_to_out_unless_told_docs(tmp_path):
    """``skin-sim force-path`` draws its chart under out/ by default; ``--docs`` with ``--chart`` is refused."""
    from skin_sim_lab.perf import force_path

    assert not force_path.OUT_CHART.is_absolute() and force_path.OUT_CHART.parts[0] == "out"
    assert force_path.DOCS_CHART == REPO / "docs" / "figures" / "force_path_rate.png"
    env = dict(os.environ, PYTHONPATH=str(REPO) + os.pathsep + os.environ.get("PYTHONPATH", ""))
    p = subprocess.run(
        [sys.executable, "-m", "skin_sim_node.cli", "force-path", "--docs", "--chart", str(tmp_path / "x.png")],
        cwd=tmp_path,
        env=env,
        capture_output=True,
        text=True,
        timeout=600,
    )
    assert p.returncode == 2 and "give --docs or --chart, not both" in p.stderr
    assert not (tmp_path / "x.png").exists()
