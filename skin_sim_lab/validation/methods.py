"""Adapters: run each method on a scenario, score it against the FEM, time one update.

Every method returns, for a :class:`~.scenarios.Scenario`, the static force at each depth of
the scenario's ramp and the downward surface displacement at its deepest point, sampled at
the FEM's surface sample points. Timing is one run on this machine, per update, i.e. the work
a 1 kHz haptic tick does: the model's ``step`` plus its output grid; an explicit solver's
sub-steps for 1 ms at its stability limit; the FEM's assembly and solve.
"""

from __future__ import annotations

import math
import time
from dataclasses import dataclass

import numpy as np
from scipy.interpolate import RegularGridInterpolator

from skin_sim_lab.solvers import (
    LeapfrogSolver,
    MassSpringSolver,
    Membrane,
    leapfrog_dt_limit_s,
    mass_spring_dt_limit_s,
    static_indentation,
)
from skin_sim_node.model import SkinModel, TissueConfig, preset

from .fem import FemResult
from .scenarios import Scenario

TICK_S = 1e-3  # haptic update period


@dataclass
class Outcome:
    """A method's answer on one scenario."""

    forces_n: np.ndarray  # at scenario.depths_m
    field_m: np.ndarray  # downward surface displacement at the max depth, on the FEM samples


def _on_samples(xs, ys, field, fem: FemResult) -> np.ndarray:
    """Bilinear interpolation of a (ny, nx) field onto the FEM's sample grid (0 outside)."""
    interp = RegularGridInterpolator((ys, xs), field, bounds_error=False, fill_value=0.0)
    X, Y = np.meshgrid(fem.sample_x_m, fem.sample_y_m)
    return interp(np.stack([Y.ravel(), X.ravel()], axis=1)).reshape(X.shape)


def model_config(modes: int, grid_n: int, base: TissueConfig | None = None, adaptive: bool = False) -> TissueConfig:
    """``base`` (default preset) with a ``grid_n``-square output grid and either a fixed ``modes x modes``
    (``lod.adaptive_modes`` off, so the count is what the label says) or the adaptive mode count."""
    base = base or preset("default")
    return base.replace(
        **{"modes.m": modes, "modes.n": modes, "grid.nx": grid_n, "grid.ny": grid_n, "lod.adaptive_modes": adaptive}
    )


STATIC_DT_S = 1e3
"""Step of the layered form's static solve: its series chain is backward Euler in each layer's own rate, so one
step of ``dt`` from rest leaves a damper force ``b_i c_i / dt``; at 1000 s that is under 1e-6 of the spring force
for every default layer (``b / k`` <= 4 ms), i.e. the dampers have relaxed (checked against a 1 mm/s press and 2 s
hold, :func:`skin_sim_lab.oracles.physics.quasi_static_force`, to 1e-6). The membranes' modal step is exact for any
``dt`` and is then at its static shape."""


def static_dt_s(cfg: TissueConfig) -> float:
    """The step that gives the static answer of ``cfg``'s form: :data:`STATIC_DT_S` (layered), one tick (paper: its
    springs take the tool's velocity, 0 here, so the tick does not matter for the force)."""
    return STATIC_DT_S if cfg.form == "layered" else TICK_S


def static_force_n(model: SkinModel, x: float, y: float, depth_m: float) -> float:
    """The model's static reaction at one depth (a press held still: xdot = 0, dampers and viscoelastic arms relaxed:
    a contact restart, ``SkinModel.step(restart=True)``, so the equilibrium law exactly)."""
    model.reset()
    return model.step((x, y, -depth_m), (0.0, 0.0, 0.0), static_dt_s(model.cfg), restart=True)


class ModalMethod:
    """The skin model (``SkinModel``) at ``modes x modes`` terms and a ``grid_n`` output grid."""

    kind = "modal model"

    def __init__(
        self, modes: int, grid_n: int = 120, cfg: TissueConfig | None = None, label: str | None = None, adaptive: bool = False
    ):
        self.cfg = model_config(modes, grid_n, cfg, adaptive)
        self.model = SkinModel(self.cfg)
        tol_um = self.cfg.lod.tolerance_m * 1e6
        default = f"modal adaptive ({tol_um:g} um), grid {grid_n}" if adaptive else f"modal {modes}x{modes}, grid {grid_n}"
        self.label = label or default

    def run(self, sc: Scenario, fem: FemResult) -> Outcome:
        """Static forces at the scenario's depths and the surface field at the deepest, from the skin model."""
        x, y = sc.contact_xy_m
        forces = np.array([static_force_n(self.model, x, y, d) for d in sc.depths_m])
        g = self.model.build_grid()
        surface = g.displacement_m.sum(axis=0)
        return Outcome(forces, _on_samples(g.xs_m, g.ys_m, surface, fem))

    def seconds_per_update(self, ticks: int = 300) -> float:
        """Mean wall time of ``step`` + ``build_grid`` for a tool pressing and dragging at 1 kHz."""
        m = self.model
        m.reset()
        m.step((0.0, 0.0, -1e-3), (0.0, 0.0, 0.0), TICK_S)
        m.build_grid()  # compile / warm
        t0 = time.perf_counter()
        for i in range(ticks):
            m.step((1e-5 * i, 0.0, -2e-3), (0.01, 0.0, 0.0), TICK_S)
            m.build_grid()
        return (time.perf_counter() - t0) / ticks


def skin_membrane(cfg: TissueConfig, tension_n_per_m: float | None = None, foundation_n_per_m3: float = 0.0) -> Membrane:
    """One membrane for the whole skin over the model's patch: summed areal density and tension."""
    a, b = cfg.patch_size_m
    rho_a = sum(la.areal_density_kg_per_m2 for la in cfg.layers)
    t = sum(la.tension_n_per_m for la in cfg.layers) if tension_n_per_m is None else tension_n_per_m
    return Membrane(
        size_x_m=a, size_y_m=b, areal_density_kg_per_m2=rho_a, tension_n_per_m=t, foundation_n_per_m3=foundation_n_per_m3
    )


class GridMethod:
    """Mass-spring (Kelvin-Voigt) grid or explicit FD of the one-membrane skin, ``n x n`` nodes.

    Both have the same static operator (the 5-point membrane plus foundation), so their static
    answers coincide (``static_indentation``); they differ in cost per 1 ms tick (sub-steps at
    the stability limit) and in dynamics (see the release chart).
    """

    def __init__(self, kind: str, n: int, mem: Membrane, cfg: TissueConfig, label: str | None = None):
        self.kind, self.n, self.mem, self.cfg = kind, n, mem, cfg
        self.label = label or f"{kind} {n}x{n}"

    def run(self, sc: Scenario, fem: FemResult) -> Outcome:
        """Static forces (linear: scaled from unit depth) and the surface field at the deepest, on the grid."""
        r0 = self.cfg.tool_radius_m
        f1, u1 = static_indentation(self.mem, self.n, self.n, 1.0, (0.0, 0.0), r0)  # linear: unit depth
        forces = f1 * sc.depths_m
        g = LeapfrogSolver(self.mem, self.n, self.n)
        xs, ys = g.xs_m + sc.contact_xy_m[0], g.ys_m + sc.contact_xy_m[1]
        return Outcome(forces, _on_samples(xs, ys, u1 * sc.max_depth_m, fem))

    def seconds_per_update(self, ticks: int = 20) -> float:
        """Wall time of one 1 kHz tick (s): the substeps the method's stability limit needs."""
        n = self.n
        if self.kind == "mass-spring":
            s, lim = MassSpringSolver(self.mem, n, n), mass_spring_dt_limit_s(self.mem, n, n)
        else:
            s, lim = LeapfrogSolver(self.mem, n, n), leapfrog_dt_limit_s(self.mem, n, n)
        sub = max(1, math.ceil(TICK_S / (0.9 * lim)))
        load = np.zeros((n, n))
        s.advance(TICK_S / sub, 1, load)  # compile / warm
        t0 = time.perf_counter()
        for _ in range(ticks):
            s.advance(TICK_S / sub, sub, load)
        return (time.perf_counter() - t0) / ticks


class FemMethod:
    """The FEM itself at a coarser mesh: scored against the finest; time = one full solve."""

    kind = "FEM"

    def __init__(self, results: dict[str, FemResult], label: str, level: int):
        self.results, self.label, self.level = results, label, level

    def run(self, sc: Scenario, fem: FemResult) -> Outcome:
        """This mesh's forces and surface field."""
        r = self.results[sc.name]
        return Outcome(r.stiffness_n_per_m * sc.depths_m, r.surface_per_depth * sc.max_depth_m)

    def seconds_per_update(self) -> float:
        """Mean wall time of one solve (s)."""
        return float(np.mean([r.solve_s for r in self.results.values()]))


class AllLayersVariant(ModalMethod):
    """Prototype of a changed model form (not the model): every layer under the tool takes part from first contact.

    The paper's form engages a layer only once the tip passes its top (Fig 3) and lets the
    deepest engaged layer saturate, which makes the static force jump at each interface
    (``docs/model.md``). In a continuum every layer under the tool is compressed at any depth,
    so this variant uses the Reuss series of all three layers, ``F = d / sum(1 / k_i)``, with no
    engagement and no saturation, and the (calibrated) model's own surface shape.
    """

    kind = "variant"

    def __init__(self, modes: int, grid_n: int, cfg: TissueConfig, series_stiffness_n_per_m: float, label: str):
        super().__init__(modes, grid_n, cfg, label)
        self.k_series = series_stiffness_n_per_m

    def run(self, sc: Scenario, fem: FemResult) -> Outcome:
        """The modal field with the all-layers series spring's force."""
        o = super().run(sc, fem)
        return Outcome(self.k_series * sc.depths_m, o.field_m)
