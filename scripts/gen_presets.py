"""Regenerate config/default.yaml, paper.yaml, isotropic.yaml, needle.yaml, two_hands.yaml and docs/parameters.md
from the schema.

The presets are written twice: ``config/`` at the top, where the README and the command lines point, and
``skin_sim_node/config/``, the package data that :func:`skin_sim_node.model.config.preset` reads in an install.

default: every schema default (the layered form). paper: the paper's form (Fig 3 engagement, common
velocity), one mode, no damping, LOD levers off, the Sneddon flat-punch k of the moduli it always had,
and each layer's tension set so that c = 0.0032 * 0.06 / (pi sqrt 2) m/s, i.e. lambda_11 = 0.0032 rad/s
as in eq 9; isotropic (the paper's own membrane too). isotropic: the default with no tension lines
(``anisotropy.ratio = 1``), the model as calibrated against the isotropic neo-Hookean references. needle: the
default under a 21 G needle (``tool.shape`` 'needle'). two_hands: the needle preset with a second hand, a
fingertip pad anchoring beside it (issue 32).
"""

import math
from pathlib import Path

from msgs_schema.parameters import ALL_PARAMETERS, NODE_NAME, TISSUE_PREFIX, tissue_part
from msgs_schema.tissue import LAYER_NAMES, TOOL_RADIUS_M
from skin_sim_node.model.calibration import PAPER_MODULI_PA, flat_punch_stiffness_n_per_m
from skin_sim_node.model.config import config_from_flat, dump_yaml

ROOT = Path(__file__).resolve().parents[1]
CONFIG = ROOT / "config"
PACKAGE_CONFIG = ROOT / "skin_sim_node" / "config"
DOCS = ROOT / "docs" / "parameters.md"


def _bounds(spec) -> str:
    """The bounds column: ``lo < x <= hi`` (``<=`` below for an inclusive minimum), ``-`` when unbounded."""
    lo = "" if spec.min is None else f"{spec.min:g} {'<' if spec.min_exclusive else '<='} "
    hi = "" if spec.max is None else f" <= {spec.max:g}"
    return f"{lo}x{hi}" if (lo or hi) else "-"


def write_parameter_doc(path: Path = DOCS) -> None:
    """One table row per parameter: the schema is the single source, this page is generated.

    Parameters
    ----------
    path : Path
    """
    rows = [
        "# Parameters of skin_sim_node",
        "",
        "Generated from `msgs_schema/parameters.py` and `msgs_schema/tissue.py` by",
        "`python scripts/gen_presets.py`; do not edit by hand. Defaults are `config/default.yaml`.",
        "",
        "Every name in a parameter file (nested keys are dotted: `tissue: layers: dermis: stiffness_n_per_m`) and every",
        "`-p name:=value` is checked against this table before the node starts: an unknown name stops it with one line",
        "naming the closest valid one (`unknown parameter 'max_forse_n' (did you mean 'max_force_n'?)`), a value of the",
        "wrong type or out of its bounds with one line giving the bound; exit code 2, no traceback. A live",
        "`set_parameters` call is refused with the same reason. An integer given for a float parameter is that float.",
        "The device commands (`skin-sim bridge`, `device`, `mock-tool`) check their own parameters (`--help` lists",
        "them) the same way.",
        "",
        "| name | type | default | unit | bounds | description |",
        "|---|---|---|---|---|---|",
    ]
    for spec in ALL_PARAMETERS:
        default = f"{spec.default:.6g}" if isinstance(spec.default, float) else str(spec.default)
        desc = spec.description.replace("|", "\\|")
        rows.append(f"| `{spec.name}` | {spec.type.__name__} | {default} | {spec.unit} | {_bounds(spec)} | {desc} |")
    path.write_text("\n".join(rows) + "\n")


PRESETS = ("default.yaml", "paper.yaml", "isotropic.yaml", "needle.yaml", "two_hands.yaml")
"""The preset files written (``config/`` and the package copies)."""
PRESET_KEY = "/**/" + NODE_NAME
"""The presets' top key: the node in any namespace (rcl's ``**`` wildcard). A bare ``skin_sim_node:`` matches only
``/skin_sim_node``, so a node started under ``-r __ns:=/s1`` (``skin-sim scale``'s sessions) silently ran without it."""


def main(config_dir: Path = CONFIG, doc_path: Path = DOCS, package_config_dir: Path = PACKAGE_CONFIG):
    """Write :data:`PRESETS` into ``config_dir`` and ``package_config_dir``, and the parameter
    reference to ``doc_path``.

    Parameters
    ----------
    config_dir : Path
    doc_path : Path
    package_config_dir : Path
        The packaged copy of the presets.
    """
    default = {s.name: s.default for s in ALL_PARAMETERS}
    dump_yaml(default, config_dir / "default.yaml", PRESET_KEY)
    paper = dict(default)
    paper[TISSUE_PREFIX + "form"] = "paper"
    paper[TISSUE_PREFIX + "modes.m"] = 1
    paper[TISSUE_PREFIX + "modes.n"] = 1
    paper[TISSUE_PREFIX + "patch.foundation_length_m"] = 0.0  # the paper's bare membrane (eq 1)
    paper[TISSUE_PREFIX + "anisotropy.ratio"] = 1.0  # the paper's isotropic membrane
    # eq 9 is one fixed mode, undamped, 6.11 um deep (below lod.tolerance_m): no level-of-detail shortcuts
    for lever in ("adaptive_modes", "affected_layers", "idle"):
        paper[f"{TISSUE_PREFIX}lod.{lever}"] = False
    c = 0.0032 * 0.06 / (math.pi * math.sqrt(2))
    for n in LAYER_NAMES:
        p = f"{TISSUE_PREFIX}layers.{n}."
        paper[p + "damping_n_s_per_m"] = 0.0
        paper[p + "stiffness_n_per_m"] = flat_punch_stiffness_n_per_m(PAPER_MODULI_PA[n], TOOL_RADIUS_M)
        paper[p + "tension_n_per_m"] = paper[p + "density_kg_per_m3"] * paper[p + "thickness_m"] * c**2
    config_from_flat(tissue_part(paper, TISSUE_PREFIX))
    dump_yaml(paper, config_dir / "paper.yaml", PRESET_KEY)
    isotropic = dict(default)
    isotropic[TISSUE_PREFIX + "anisotropy.ratio"] = 1.0  # no tension lines
    config_from_flat(tissue_part(isotropic, TISSUE_PREFIX))
    dump_yaml(isotropic, config_dir / "isotropic.yaml", PRESET_KEY)
    needle = dict(default)
    needle[TISSUE_PREFIX + "tool.shape"] = "needle"  # the default tissue under a 21 G needle (issue 22)
    config_from_flat(tissue_part(needle, TISSUE_PREFIX))
    dump_yaml(needle, config_dir / "needle.yaml", PRESET_KEY)
    # two hands (issue 32): the needle in the right hand, a fingertip (a flat pad, second_tool_radius_m) in the left
    # anchoring beside the entry; each hand's topics under its namespace (right/tool/pose, left/tool/pose, ...)
    two_hands = dict(needle) | {"hand_ns": "right", "second_hand_ns": "left", "second_tool_shape": "flat"}
    dump_yaml(two_hands, config_dir / "two_hands.yaml", PRESET_KEY)
    package_config_dir.mkdir(parents=True, exist_ok=True)
    for name in PRESETS:
        (package_config_dir / name).write_text((config_dir / name).read_text())
    write_parameter_doc(doc_path)
    print("wrote", *(config_dir / n for n in PRESETS), f"(copies: {package_config_dir})", doc_path)


if __name__ == "__main__":
    main()
