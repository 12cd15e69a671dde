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


def test_a_solve_missing_from_a_tracked_cache_is_stored_under_out(tmp_path, monkeypatch):
    """Issue 29 item 4: ``skin-sim chart validation`` wrote 5 new files into docs/validation/fem_cache on a fresh clone.
    A solve that is not in a tracked cache now goes to out/cache (read back from there); the tracked cache only with
    --docs (``WRITE_DOCS``)."""
    import numpy as np

    from skin_sim_lab.validation import cache

    monkeypatch.chdir(tmp_path)
    tracked = cache.DOCS / "validation" / "fem_cache" / "issue29-not-a-real-setup.npz"
    solves = []

    def solve():
        solves.append(1)
        return 2.5

    def get():
        return cache.cached(tracked, False, solve, lambda z: float(z["k"]), lambda r: {"k": r})

    assert get() == 2.5 and get() == 2.5 and len(solves) == 1  # the second call reads the untracked copy
    assert not tracked.exists()
    assert float(np.load(tmp_path / "out" / "cache" / "fem_cache" / tracked.name)["k"]) == 2.5
    monkeypatch.setattr(cache, "WRITE_DOCS", True)
    try:
        assert cache.local_path(tracked) != tracked and cache.cached(tracked, True, solve, None, lambda r: {"k": r}) == 2.5
        assert tracked.exists()  # with --docs the tracked cache is written
    finally:
        tracked.unlink(missing_ok=True)


def test_prune_cache_without_docs_is_refused(tmp_path):
    p = run(tmp_path, "validation", "--prune-cache")
    assert p.returncode == 2 and p.stderr.strip().endswith("--prune-cache deletes tracked cache files: give --docs too"), p.stderr


def test_long_chart_says_its_stages_and_expected_duration(tmp_path, capsys):
    """Issue 29 item 4: chart validation ran past 7 minutes with no expected duration. Its stages print as they start;
    the expected duration is this machine's last complete run (none on a first run, and it says so)."""
    from skin_sim_lab.validation.charts import Progress, duration

    record = tmp_path / "times" / "all.json"
    first = Progress("chart validation", 2, record)
    first.step("one")
    first.step("two")
    first.done()
    out = capsys.readouterr().out.splitlines()
    assert out[0].startswith("chart validation: no complete run on this machine to estimate from")
    assert out[1].startswith("chart validation: stage 1 of 2: one (") and out[2].startswith(
        "chart validation: stage 2 of 2: two ("
    )
    assert out[3].startswith("chart validation: done in ")
    Progress("chart validation", 2, record)
    assert capsys.readouterr().out.startswith("chart validation: expected about ")
    Progress("chart validation", 3, record)  # another stage list: no estimate from it
    assert "no complete run" in capsys.readouterr().out
    assert duration(42.4) == "42 s" and duration(450.0) == "7.5 min"
