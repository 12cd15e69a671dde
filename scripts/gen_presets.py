"""Regenerate config/default.yaml and config/paper.yaml from the parameter schema.

default: every schema default. paper: one mode, no damping, LOD levers off, and each layer's tension set
so that c = 0.0032 * 0.06 / (pi sqrt 2) m/s, i.e. lambda_11 = 0.0032 rad/s as in eq 9.
"""

import math
from pathlib import Path

from msgs_schema.parameters import ALL_PARAMETERS, TISSUE_PREFIX
from skin_sim_node.model.config import LAYER_NAMES, config_from_flat, dump_yaml, tissue_part

CONFIG = Path(__file__).resolve().parents[1] / "config"


def main():
    default = {s.name: s.default for s in ALL_PARAMETERS}
    dump_yaml(default, CONFIG / "default.yaml")
    paper = dict(default)
    paper[TISSUE_PREFIX + "modes.m"] = 1
    paper[TISSUE_PREFIX + "modes.n"] = 1
    # eq 9 is one fixed mode, undamped, 6.11 um deep (below lod.tolerance_m): no level-of-detail shortcuts
    for lever in ("adaptive_modes", "affected_layers", "idle"):
        paper[f"{TISSUE_PREFIX}lod.{lever}"] = False
    c = 0.0032 * 0.06 / (math.pi * math.sqrt(2))
    for n in LAYER_NAMES:
        p = f"{TISSUE_PREFIX}layers.{n}."
        paper[p + "damping_n_s_per_m"] = 0.0
        paper[p + "tension_n_per_m"] = paper[p + "density_kg_per_m3"] * paper[p + "thickness_m"] * c**2
    config_from_flat(tissue_part(paper, TISSUE_PREFIX))
    dump_yaml(paper, CONFIG / "paper.yaml")
    print("wrote", CONFIG / "default.yaml", CONFIG / "paper.yaml")


if __name__ == "__main__":
    main()
