"""Which solve is "the reference": mesh levels of the linear 3D FEM and of the large-deformation FEM.

Shared by the charts and the calibration (both read the same converged solves from the caches);
it imports neither, so ``charts -> calibrate -> references`` runs one way.
"""

from __future__ import annotations

from dataclasses import replace

from skin_sim_node.model import TissueConfig

from . import hyperelastic, hyperelastic3d
from .fem import FemSetup, mesh_levels, reference
from .scenarios import BY_NAME

FINEST_LEVEL = 1  # the converged linear 3D reference (convergence study: docs/validation/convergence.md)
# The near-edge problem is a half model (twice the DOFs); its level 1 did not fit the time on a
# shared 2-core machine, so its reference is level 0 (its own -1 -> 0 change is in convergence.md).
FINEST_OVERRIDE = {"edge-3layer": 0}

AXI_LEVELS = (-1, 0, 1, 2, 3)  # the axisymmetric large-deformation convergence study
AXI_REFERENCE_LEVEL = 3
"""The axisymmetric neo-Hookean reference mesh, the finest of the study: the force at 3 mm changes by
0.32 % from level 2 to level 3 (docs/validation/large_deformation.md); ~100 s per fresh solve here,
read from the cache otherwise."""


def fem_for(sc, level: int, progress: bool = True):
    """The linear 3D FEM of scenario ``sc`` at mesh ``level`` (cached)."""
    return reference(sc.fem_setup(mesh_levels(level, FemSetup())), progress=progress)


def finest_level(sc) -> int:
    """The finest FEM mesh level of scenario ``sc``: its override, else :data:`FINEST_LEVEL`."""
    return FINEST_OVERRIDE.get(sc.name, FINEST_LEVEL)


def converged_fem(sc, progress: bool = True):
    """The converged linear FEM reference of a scenario (the finest mesh level)."""
    return fem_for(sc, finest_level(sc), progress)


def axisym(
    cfg: TissueConfig | None = None,
    level: int = AXI_REFERENCE_LEVEL,
    law: str = "neo-hookean",
    progress: bool = True,
    fresh: bool = False,
) -> hyperelastic.AxiResult:
    """The axisymmetric flat-layer punch solve of ``cfg`` (default preset) to 3 mm (cached)."""
    s = hyperelastic.setup_from_config(cfg, level)
    return hyperelastic.reference(replace(s, law=law), progress=progress, fresh=fresh)


THREE_D_LEVEL = -2
"""Mesh level of the 3D neo-Hookean solves (about 9k DOFs quarter model, 18k half model): what a
Newton solve to 3 mm fits in a few minutes here. The linear 3D FEM at this level is within 0.6 %
of its finest level (docs/validation/convergence.md)."""
THREE_D_SCENARIOS = ("peak-3layer", "valley-3layer", "edge-3layer")


def nonlinear_3d(sc, cfg: TissueConfig | None = None, progress: bool = True, fresh: bool = False):
    """The 3D egg-carton neo-Hookean solve of scenario ``sc`` at :data:`THREE_D_LEVEL` (cached)."""
    return hyperelastic3d.reference(hyperelastic3d.setup_for(sc, cfg, THREE_D_LEVEL), progress=progress, fresh=fresh)


def linear_3d(sc, cfg: TissueConfig | None = None, progress: bool = True):
    """The linear 3D FEM on the same mesh as :func:`nonlinear_3d` (cached)."""
    return reference(hyperelastic3d.setup_for(sc, cfg, THREE_D_LEVEL).fem, progress=progress)


def nonlinear_references(progress: bool = True) -> dict:
    """The converged 3D neo-Hookean solves of the default preset (cached), by scenario name: the reference of the
    issue-11 accuracy aims (:mod:`.accuracy`) and of ``skin-sim calibrate``."""
    return {n: nonlinear_3d(BY_NAME[n], None, progress=progress) for n in THREE_D_SCENARIOS}
