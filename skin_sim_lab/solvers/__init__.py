"""Baseline solvers of one layer's membrane PDE, for the accuracy and stability comparisons.

The haptic model itself is :class:`skin_sim_node.model.SkinModel`; these solve the same layer
PDE (eq 1, damped) by other methods so their speed, accuracy and stability can be charted
against it. See :mod:`.membrane` for the PDE and units.
"""

from .explicit import LeapfrogSolver, MassSpringSolver
from .implicit import SCHEMES, ImplicitSolver
from .membrane import (
    Membrane,
    disk_mask,
    grid_spec,
    leapfrog_dt_limit_s,
    mass_spring_dt_limit_s,
    membrane_from_layer,
    static_indentation,
)
from .modal import ModalSolver

__all__ = [
    "SCHEMES",
    "ImplicitSolver",
    "LeapfrogSolver",
    "MassSpringSolver",
    "Membrane",
    "ModalSolver",
    "disk_mask",
    "grid_spec",
    "leapfrog_dt_limit_s",
    "mass_spring_dt_limit_s",
    "membrane_from_layer",
    "static_indentation",
]
