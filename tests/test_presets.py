"""The committed presets and parameter reference are exactly what the schema generates."""

import runpy
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]


def test_presets_and_parameter_doc_are_generated_from_the_schema(tmp_path):
    gen = runpy.run_path(str(ROOT / "scripts" / "gen_presets.py"))
    gen["main"](config_dir=tmp_path, doc_path=tmp_path / "parameters.md")
    for name in ("default.yaml", "paper.yaml"):
        assert (tmp_path / name).read_text() == (ROOT / "config" / name).read_text(), f"config/{name} is stale"
    assert (tmp_path / "parameters.md").read_text() == (ROOT / "docs" / "parameters.md").read_text(), (
        "docs/parameters.md is stale: run python scripts/gen_presets.py"
    )
