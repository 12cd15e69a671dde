"""The committed presets and parameter reference are exactly what the schema generates."""

import runpy
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]


def test_presets_and_parameter_doc_are_generated_from_the_schema(tmp_path):
    gen = runpy.run_path(str(ROOT / "scripts" / "gen_presets.py"))
    gen["main"](config_dir=tmp_path, doc_path=tmp_path / "parameters.md", package_config_dir=tmp_path / "package")
    for name in gen["PRESETS"]:
        assert (tmp_path / name).read_text() == (ROOT / "config" / name).read_text(), f"config/{name} is stale"
        assert (tmp_path / "package" / name).read_text() == (ROOT / "skin_sim_node" / "config" / name).read_text(), (
            f"skin_sim_node/config/{name} is stale: run python scripts/gen_presets.py"
        )
    assert (tmp_path / "parameters.md").read_text() == (ROOT / "docs" / "parameters.md").read_text(), (
        "docs/parameters.md is stale: run python scripts/gen_presets.py"
    )


def test_parameters_are_validated_in_the_contract_and_built_in_the_model():
    """The contract validates (node and tissue values), the model core only builds a config from checked values."""
    import ast

    from msgs_schema.parameters import ALL_PARAMETERS, NodeParams, check_tissue, tissue_part, validate_parameters
    from skin_sim_node.model import config, config_from_flat

    flat = {s.name: s.default for s in ALL_PARAMETERS} | {"watchdog_s": 0.2, "tissue.modes.m": 9}
    node, tissue = validate_parameters(flat)
    assert isinstance(node, NodeParams) and node.watchdog_s == 0.2 and tissue == check_tissue(tissue_part(flat))
    assert config.build_config(tissue) == config_from_flat(tissue_part(flat)) and config.build_config(tissue).modes[0] == 9
    assert not hasattr(config, "validate_all")
    node_level = {"NodeParams", "node_params_from_flat", "validate_parameters", "session_params", "SessionParams"}
    for path in (ROOT / "skin_sim_node" / "model").glob("*.py"):
        for n in ast.walk(ast.parse(path.read_text())):
            if isinstance(n, ast.ImportFrom) and n.module and n.module.startswith("msgs_schema"):
                assert not node_level & {a.name for a in n.names}, f"{path.name} builds node parameters"


def test_one_spec_table_keyword_bounds_and_one_name_each():
    """One SPEC_BY_NAME, bounds only by keyword, one NODE_NAME and one list of layer names in the contract."""
    import re

    import pytest

    import msgs_schema.tissue as tissue
    from msgs_schema.parameters import SPEC_BY_NAME
    from msgs_schema.spec import ConfigError, ParamSpec

    assert not hasattr(tissue, "SPEC_BY_NAME") and SPEC_BY_NAME["tissue.modes.m"].min == 1
    with pytest.raises(TypeError):
        ParamSpec("x", float, 1.0, "m", "a length", 0.0, None, False)  # a positional bound is refused
    spec = ParamSpec("x", float, 1.0, "m", "a length", min=0.0, min_exclusive=False)
    assert spec.check(0) == 0.0 and isinstance(spec.check(0), float)
    with pytest.raises(ConfigError, match=r"^y = -1.0 m: must be >= 0.0$"):
        spec.check(-1.0, label="y")
    sources = [p for d in ("skin_sim_node", "msgs_schema", "scripts") for p in (ROOT / d).rglob("*.py")]
    text = {p: p.read_text() for p in sources}
    assert [p.name for p, t in text.items() if re.search(r'^NODE_NAME = "skin_sim_node"', t, re.M)] == ["parameters.py"]
    assert [p.name for p, t in text.items() if '("epidermis", "dermis", "fat")' in t] == ["tissue.py"]
