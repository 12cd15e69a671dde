"""``skin-sim two-punch``: two flat punches on one skin (issue 32) against a 3D neo-Hookean FEM reference.

The model: :class:`~skin_sim_node.tools.hands.SharedSkin` of two flat punches of ``config/default.yaml`` (the
calibrated default), centres at ``x = -d/2`` and ``x = +d/2``, ``y = 0``, ramped together to one depth over 300 ticks at
1 kHz and held until its viscoelastic arms have relaxed (:func:`hold_ticks`, about 1.9 s): the FEM is quasi-static and
elastic, so the relaxed force is the one to compare. The force after the issue's 300-tick hold (the arms' force still
on it) is read from the same run and printed beside it. The single punch is one :func:`~skin_sim_node.tools.make_tool`
of the same config at ``x = +d/2``, the same ramp.

The reference: the 3D compressible neo-Hookean FEM of :mod:`.hyperelastic3d` (the egg-carton layered block of
:mod:`.fem`, its moduli read from the same config, mesh level :data:`REFERENCE_LEVEL`), with the punch off
the block's centre (:class:`~.hyperelastic3d.PunchLayout`): the pair as a quarter model (symmetry planes ``x = 0``,
``y = 0``, the punch at ``x = d/2``), the single punch as the half model on the mirror of the same mesh, so the
interaction ``pair - single`` is of one discretisation (except where the disks overlap: there the single has a mesh
conforming to its own disk). Solves are cached in ``docs/validation/hyper_cache``
(``3d-<hash>.npz``); ``--fresh`` solves again (an estimate of 40 min here with PARDISO, the ``fem`` extra; SuperLU took
10-43 min for each of the larger solves).

Two lab analyses follow the table (the model is not changed by them): what the reference implies for the coupling
(:func:`implied`: the surface lowering under a punch that the model's single-punch curve needs to give the FEM's pair
force, against the FEM's single-punch field averaged over the other punch's disk, :func:`disk_averages`), and where the
heave would come from (:func:`foundation_profiles`: a membrane over a thin incompressible layer on a rigid base, the
volume term of length :func:`volume_length_m`, against the FEM's and the model's profiles).

Writes ``docs/validation/two_punch.md``; exits 1 when an aim fails.
"""

from __future__ import annotations

import argparse
import shlex
import sys
import time
from dataclasses import dataclass, replace
from functools import lru_cache
from pathlib import Path

import numpy as np
from scipy import special
from scipy.interpolate import RegularGridInterpolator
from tqdm import tqdm

from skin_sim_node.model import TissueConfig, heave
from skin_sim_node.model.calibration import POISSON_RATIO
from skin_sim_node.model.config import load_tissue_config
from skin_sim_node.model.heave import combined_profile, volume_length_m, volume_parameters
from skin_sim_node.tools import DOWN, ToolPose, make_tool
from skin_sim_node.tools.hands import SharedSkin

from . import cache, layered_elastic
from .fem import FemSetup, _geometry_key, mesh_levels
from .hyperelastic import CACHE_DIR, layer_moduli_pa
from .hyperelastic3d import PunchLayout, Result3D, Setup3D, reference
from .references import FINEST_LEVEL, THREE_D_LEVEL

ROOT = Path(__file__).resolve().parents[2]
CONFIG = ROOT / "config" / "default.yaml"
"""The calibrated default tissue: the model's config, and the FEM's moduli and geometry (:func:`fem_base`)."""
OUT = ROOT / "docs" / "validation"

DISTANCES_M = (4e-3, 6e-3, 10e-3, 20e-3)
"""Centre distances of the two punches (issue 32): overlapping disks (4 mm < 2 r0 = 5 mm), a 1 mm gap, 2 and 6 punch
radii apart; at 20 mm the punches should no longer feel each other."""
DEPTHS_M = (1e-3, 2e-3)
"""Depths of both punches: into the dermis/fat interface band (1 mm) and well into the fat (2 mm), below the 3 mm where
the coarse 3D mesh's rim elements invert (:data:`~.hyperelastic3d.MIN_STEP_FRACTION`)."""
MAX_DEPTH_M = max(DEPTHS_M)
N_STEPS = 8
"""Load steps of the FEM march to :data:`MAX_DEPTH_M`: 0.25 mm each, so both depths are converged load stops (no
interpolation between stops) and each step is smaller than the 0.3 mm of the scenarios' 3D solves."""
FAR_CENTRE_X_M = 10e-3
"""The boundary check's off-centre punch: the single punch of the 20 mm pair, 20 mm from the block's side at 30 mm."""
PROFILE_RADII_M = (4e-3, 6e-3, 8e-3, 10e-3, 20e-3)
"""Radii of the surface-profile diagnostic: the centre distances, where one punch's dimple meets the other punch, and
8 mm, near the deepest point of the reference's heave (its surface rises between about 5 and 15 mm)."""

RAMP_TICKS = 300
"""Ticks of the model's depth ramp at 1 kHz (0.3 s, the issue's protocol), then :func:`hold_ticks` at depth."""
ISSUE_HOLD_TICKS = 300
"""The issue's probe read the force 300 ticks into the hold (0.3 s): with the slow arm's 0.28 s the arms still carry a
third of their force then (the model's single punch is 17 % above its relaxed force at 1 mm), so that reading is shown
but not scored."""
RELAX_TOL = 1e-3
"""The hold lasts until the slowest viscoelastic arm's force has decayed to this fraction of its value at the end of
the ramp (``tau ln(1 / RELAX_TOL)``): 0.1 %, a hundredth of the 10 % force aim."""
DT_S = 1e-3

FORCE_TOL = 0.10
"""Aim (issue 32): the model's force per punch, paired and single, within 10 % of the FEM's."""
INTERACTION_TOL = 0.20
"""Aim (issue 32): the model's interaction (pair - single) within 20 % of the FEM's."""
MIN_INTERACTION_FRACTION = 0.02
"""Below this FEM interaction (2 % of the single punch's force) a 20 % relative comparison compares discretisation
noise: the coarse mesh between punches 20 mm apart and the 1e-9 Newton tolerance leave the pair-minus-single difference
uncertain at a few tenths of a percent. There the aim is absolute: the model's interaction within 20 % of this floor
(0.4 % of the single force) of the FEM's."""
FAR_DISTANCE_M = 20e-3
FAR_TOL = 0.01
"""Aim (issue 32): at :data:`FAR_DISTANCE_M` the model's pair force equals its single-punch force within 1 %."""


REFERENCE_LEVEL = THREE_D_LEVEL + 1
"""Mesh level of the two-punch reference (:func:`~.fem.mesh_levels`): -1, one finer than the single punch's 3D
references (:data:`~.references.THREE_D_LEVEL`, 4 elements over the punch's radius instead of 3, 2 through the
epidermis instead of 1). The overlapping pair is what sets it: its interaction over the single force at the first load
stop (0.25 mm) is -0.083, -0.089 and -0.088 at levels -2, -1 and 0 (docs/two_hands.md, "Session 13"), so level -2 was
7 % short of the finer two, and level -1 is within 0.0011 of level 0; at 6 mm levels -2 and -1 agree within 0.002, and
-1 and 0 within 0.0021 (session 16; :data:`FINE_LEVEL`, the page's section one level finer)."""


def fem_base(cfg: TissueConfig, level: int = REFERENCE_LEVEL) -> FemSetup:
    """The FEM mesh and tissue of the reference: mesh ``level`` (:data:`REFERENCE_LEVEL`), moduli and geometry of
    ``cfg``."""
    return replace(mesh_levels(level, FemSetup()), moduli_pa=layer_moduli_pa(cfg), tissue=_geometry_key(cfg))


def fem_setup(cfg: TissueConfig, distance_m: float | None, partner: bool, level: int = REFERENCE_LEVEL) -> Setup3D:
    """The neo-Hookean solve of a punch at ``x = distance_m / 2`` (``partner``: with its mirror at ``-distance_m / 2``);
    ``distance_m`` None: one punch centred on the block (the existing scenarios' layout, quarter model)."""
    layout = None if distance_m is None else PunchLayout(distance_m / 2, partner)
    return Setup3D(fem_base(cfg, level), MAX_DEPTH_M, N_STEPS, layout)


def fem_solve(s3: Setup3D, fresh: bool = False, progress: bool = True, missing_ok: bool = False) -> Result3D | None:
    """The cached solve of ``s3`` (``docs/validation/hyper_cache``, or ``out/cache``); with ``missing_ok`` None when it
    is in neither cache instead of solving."""
    path = CACHE_DIR / f"3d-{s3.key()}.npz"
    if missing_ok and not fresh and not path.exists() and not cache.local_path(path).exists():
        return None
    return reference(s3, progress=progress, fresh=fresh)


def force_at(res: Result3D, depth_m: float) -> float:
    """One punch's force (N) at the load stop ``depth_m`` (both depths are stops: :data:`N_STEPS`)."""
    i = int(np.argmin(np.abs(res.depths_m - depth_m)))
    if abs(res.depths_m[i] - depth_m) > 1e-9:
        raise ValueError(f"{depth_m * 1e3:g} mm is not a converged load stop (deepest {res.depths_m[-1] * 1e3:.2f} mm)")
    return float(res.forces_n[i])


def profile_at(res: Result3D, radius_m: float) -> float:
    """Downward surface displacement (m) of a centred solve at the deepest stop, ``radius_m`` from the punch axis
    along +x (the Eulerian field sampled on the 0.5 mm grid, linear between samples)."""
    return float(np.interp(radius_m, res.sample_x_m, res.field_down_m[0]))


def hold_ticks(cfg: TissueConfig) -> int:
    """Ticks of the hold at depth: until the slowest viscoelastic arm of ``cfg`` is relaxed (:data:`RELAX_TOL`), at
    least :data:`ISSUE_HOLD_TICKS`."""
    flat = cfg.as_flat()
    taus = [v for k, v in flat.items() if k.startswith("viscoelastic.tau") and v]
    return max(ISSUE_HOLD_TICKS, int(np.ceil(max(taus, default=0.0) * np.log(1 / RELAX_TOL) / DT_S)))


def _press(tools, xs_m, depth_m: float, hold: int) -> tuple[list[float], list[float]]:
    """Ramp the tools at ``x = xs_m`` to ``depth_m`` and hold ``hold`` ticks; each one's upward force (N) at the last
    tick, and after :data:`ISSUE_HOLD_TICKS` of the hold."""
    f = [0.0] * len(tools)
    issue = list(f)
    for i in range(RAMP_TICKS + hold):
        d = depth_m * min(i, RAMP_TICKS) / RAMP_TICKS
        for k, (x, t) in enumerate(zip(xs_m, tools)):
            f[k] = float(t.step(ToolPose((x, 0.0, -d), (0.0, 0.0, 0.0), DOWN, DT_S, i == 0)).force_n[2])
        if i == RAMP_TICKS + ISSUE_HOLD_TICKS - 1:
            issue = list(f)
    return f, issue


@lru_cache(maxsize=64)
def model_pair_n(cfg: TissueConfig, distance_m: float, depth_m: float) -> tuple[tuple[float, float], tuple[float, float]]:
    """The model's force (N) on each punch of the pair (left, right): relaxed, and after the issue's hold."""
    sk = SharedSkin([make_tool(cfg), make_tool(cfg)])
    f, issue = _press(sk.hands, (-distance_m / 2, distance_m / 2), depth_m, hold_ticks(cfg))
    return tuple(f), tuple(issue)


def model_single(cfg: TissueConfig, centre_x_m: float, depth_m: float):
    """The model's single punch at ``(centre_x_m, 0)``: its relaxed force (N), its force after the issue's hold (N),
    and its tool (relaxed at the depth)."""
    tool = make_tool(cfg)
    (f,), (issue,) = _press([tool], (centre_x_m,), depth_m, hold_ticks(cfg))
    return f, issue, tool


@lru_cache(maxsize=64)
def model_single_n(cfg: TissueConfig, centre_x_m: float, depth_m: float) -> tuple[float, float]:
    """:func:`model_single`'s forces (memoised: the test and the command share them)."""
    f, issue, _ = model_single(cfg, centre_x_m, depth_m)
    return f, issue


@dataclass
class Row:
    """One centre distance and depth: forces per punch (N) of the FEM and the model, and the verdicts."""

    distance_m: float
    depth_m: float
    fem_pair_n: float
    fem_single_n: float
    model_pair_n: float
    model_pair_spread: float  # |left - right| / mean of the model's two punches (Gauss-Seidel order)
    model_single_n: float
    issue_pair_n: float  # the model's forces after the issue's 300-tick hold (not scored)
    issue_single_n: float

    @property
    def fem_interaction_n(self) -> float:
        return self.fem_pair_n - self.fem_single_n

    @property
    def model_interaction_n(self) -> float:
        return self.model_pair_n - self.model_single_n

    @property
    def fem_fraction(self) -> float:
        """FEM interaction over the FEM single force."""
        return self.fem_interaction_n / self.fem_single_n

    @property
    def model_fraction(self) -> float:
        """Model interaction over the model single force."""
        return self.model_interaction_n / self.model_single_n

    @property
    def force_errors(self) -> tuple[float, float]:
        """Relative error of the model's pair and single forces against the FEM's."""
        return self.model_pair_n / self.fem_pair_n - 1, self.model_single_n / self.fem_single_n - 1

    @property
    def force_ok(self) -> bool:
        return all(abs(e) <= FORCE_TOL for e in self.force_errors)

    @property
    def small_interaction(self) -> bool:
        """The FEM interaction is below :data:`MIN_INTERACTION_FRACTION` (the absolute rule applies)."""
        return abs(self.fem_fraction) < MIN_INTERACTION_FRACTION

    @property
    def interaction_error(self) -> float:
        """Model interaction against the FEM's, relative to the FEM's; with :attr:`small_interaction`, the difference
        of the fractions over :data:`MIN_INTERACTION_FRACTION`. The aim is ``|error| <= INTERACTION_TOL`` either way."""
        if self.small_interaction:
            return (self.model_fraction - self.fem_fraction) / MIN_INTERACTION_FRACTION
        return self.model_interaction_n / self.fem_interaction_n - 1

    @property
    def interaction_ok(self) -> bool:
        return abs(self.interaction_error) <= INTERACTION_TOL

    @property
    def far_ok(self) -> bool | None:
        """At :data:`FAR_DISTANCE_M`: the model's pair equals its single within :data:`FAR_TOL` (None elsewhere)."""
        if abs(self.distance_m - FAR_DISTANCE_M) > 1e-9:
            return None
        return abs(self.model_pair_n / self.model_single_n - 1) <= FAR_TOL

    @property
    def ok(self) -> bool:
        return self.force_ok and self.interaction_ok and self.far_ok is not False


def rows(
    cfg: TissueConfig,
    fresh: bool = False,
    progress: bool = True,
    missing_ok: bool = False,
    level: int = REFERENCE_LEVEL,
    distances_m: tuple[float, ...] = DISTANCES_M,
) -> list[Row] | None:
    """Every distance (of ``distances_m``) and depth: the FEM (cached, mesh ``level``) and the model. With
    ``missing_ok`` None when a solve is not cached."""
    setups = [(d, p) for d in distances_m for p in (True, False)]
    res = {}
    bar = tqdm(setups, desc=f"two-punch FEM (pair, single) per distance, level {level}", disable=not progress)
    for d, p in bar:
        bar.set_postfix(distance_mm=f"{d * 1e3:g}", punches="pair" if p else "single")
        r = fem_solve(fem_setup(cfg, d, p, level), fresh, progress, missing_ok)
        if r is None:
            return None
        res[d, p] = r
    out = []
    for d in tqdm(distances_m, desc="two-punch model", disable=not progress, leave=False):
        for depth in DEPTHS_M:
            (left, right), issue = model_pair_n(cfg, d, depth)
            single, issue_single = model_single_n(cfg, d / 2, depth)
            mean = 0.5 * (left + right)
            out.append(
                Row(
                    d,
                    depth,
                    force_at(res[d, True], depth),
                    force_at(res[d, False], depth),
                    mean,
                    abs(left - right) / mean,
                    single,
                    0.5 * sum(issue),
                    issue_single,
                )
            )
    return out


@dataclass
class Checks:
    """The boundary check and the surface-profile diagnostic (2 mm, the deepest stop of the centred solve)."""

    centred_n: dict[float, float]  # single punch centred on the block, by depth
    off_centre_n: dict[float, float]  # single punch at x = FAR_CENTRE_X_M (the 20 mm pair's single), by depth
    fem_profile: dict[float, float]  # u(r) / depth, centred FEM at MAX_DEPTH_M, by radius
    model_profile: dict[float, float]  # u(r) / depth, the model's single punch at MAX_DEPTH_M, by radius


def checks(cfg: TissueConfig, fresh: bool = False, progress: bool = True, missing_ok: bool = False) -> Checks | None:
    """The centred single punch against the off-centre one at :data:`FAR_CENTRE_X_M`, and the profiles."""
    centred = fem_solve(fem_setup(cfg, None, False), fresh, progress, missing_ok)
    off = fem_solve(fem_setup(cfg, 2 * FAR_CENTRE_X_M, False), fresh, progress, missing_ok)
    if centred is None or off is None:
        return None
    _, _, tool = model_single(cfg, 0.0, MAX_DEPTH_M)
    return Checks(
        {d: force_at(centred, d) for d in DEPTHS_M},
        {d: force_at(off, d) for d in DEPTHS_M},
        {r: profile_at(centred, r) / MAX_DEPTH_M for r in PROFILE_RADII_M},
        {r: tool.tissue.surface_displacement_at(r, 0.0) / MAX_DEPTH_M for r in PROFILE_RADII_M},
    )


def table(rs: list[Row]) -> str:
    """The results as a markdown table, one row per distance and depth."""
    lines = [
        "| d (mm) | depth (mm) | FEM pair (N) | FEM single (N) | FEM interaction (N) | FEM int. / single "
        "| model pair (N) | model single (N) | model interaction (N) | model int. / single | pair err | single err "
        "| interaction err | verdict |",
        "|---|---|---|---|---|---|---|---|---|---|---|---|---|---|",
    ]
    for r in rs:
        ep, es = r.force_errors
        rule = " (abs.)" if r.small_interaction else ""
        far = "" if r.far_ok is None else f"; pair = single {'ok' if r.far_ok else 'FAIL'}"
        lines.append(
            f"| {r.distance_m * 1e3:g} | {r.depth_m * 1e3:g} | {r.fem_pair_n:.4f} | {r.fem_single_n:.4f} "
            f"| {r.fem_interaction_n:+.4f} | {r.fem_fraction:+.3f} | {r.model_pair_n:.4f} | {r.model_single_n:.4f} "
            f"| {r.model_interaction_n:+.4f} | {r.model_fraction:+.3f} | {ep:+.1%} | {es:+.1%} "
            f"| {r.interaction_error:+.0%}{rule} | {'PASS' if r.ok else 'FAIL'}{far} |"
        )
    return "\n".join(lines)


def issue_table(rs: list[Row]) -> str:
    """The model's forces after the issue's 300-tick hold (viscoelastic arms still loaded; not scored)."""
    lines = [
        "| d (mm) | depth (mm) | model pair (N) | model single (N) | model int. / single | pair / relaxed pair |",
        "|---|---|---|---|---|---|",
    ]
    for r in rs:
        frac = r.issue_pair_n / r.issue_single_n - 1
        lines.append(
            f"| {r.distance_m * 1e3:g} | {r.depth_m * 1e3:g} | {r.issue_pair_n:.4f} | {r.issue_single_n:.4f} "
            f"| {frac:+.3f} | {r.issue_pair_n / r.model_pair_n:.3f} |"
        )
    return "\n".join(lines)


def checks_text(c: Checks) -> str:
    """The boundary check and the profile diagnostic as markdown."""
    lines = [
        "| depth (mm) | single, centred (N) | single at x = 10 mm (N) | difference |",
        "|---|---|---|---|",
    ]
    for d in DEPTHS_M:
        a, b = c.centred_n[d], c.off_centre_n[d]
        lines.append(f"| {d * 1e3:g} | {a:.4f} | {b:.4f} | {b / a - 1:+.2%} |")
    lines += [
        "",
        f"Surface profile of one punch at {MAX_DEPTH_M * 1e3:g} mm (downward displacement over depth, centred FEM "
        "along +x at the deformed positions; the model's `SkinModel.surface_displacement_at`):",
        "",
        "| r (mm) | FEM u/depth | model u/depth | model / FEM |",
        "|---|---|---|---|",
    ]
    for r in PROFILE_RADII_M:
        f, m = c.fem_profile[r], c.model_profile[r]
        ratio = f"{m / f:.2f}" if abs(f) > 1e-4 else "-"
        lines.append(f"| {r * 1e3:g} | {f:.4f} | {m:.4f} | {ratio} |")
    return "\n".join(lines)


# ---------------------------------------------------------------------------------------------------------------------
# What the reference implies for the coupling, and where the heave would come from (lab analysis; the model is unchanged)

IMPLIED_DISTANCES_M = (4e-3, 6e-3, 10e-3)
"""The distances whose rows fail (:data:`DISTANCES_M` without the far pair, which passes)."""
IMPLIED_DEPTH_M = tuple(round(0.1 * k, 1) * 1e-3 for k in range(6, 25))
"""Depths (0.6-2.4 mm every 0.1 mm) of the model's single-punch force-depth curve that :func:`implied` inverts: wide
enough for a lowering by 40 % of either depth (:data:`DEPTHS_M`) or a raising by 20 % of the deeper (the largest
needed is 0.07); between them the
curve is interpolated linearly in log force against log depth (the curve is close to a power law, ``F ~ d^1.4``)."""
DISK_WEIGHTS = {"uniform": 0.0, "parabolic": 1.0, "pressure": -0.5}
"""Weights of :func:`disk_averages`, the exponent ``alpha`` of ``(1 - s^2 / a^2)^alpha`` over the other punch's disk
(``s`` from its centre, ``a`` its radius): uniform; parabolic (a pressure vanishing at the rim: a soft pad); the rigid
flat punch's pressure on a half-space (``alpha = -1/2``, Boussinesq / Sneddon). By Betti's reciprocal theorem a rigid
punch's force change is, to first order in linear elasticity, the other's field averaged with this punch's contact
pressure; the exact identity takes the pressure under the pair, and on a 5.3 mm layer (``a / h`` about 0.5) at 2 mm
of a neo-Hookean tissue the half-space pressure is itself an approximation."""
DISK_RADIAL_NODES = 48
DISK_ANGLE_NODES = 96
"""Quadrature of :func:`disk_average`: Gauss-Jacobi in ``t = s^2 / a^2`` with the weight ``(1 - t)^alpha`` (exact for
a field polynomial of degree ``2 * 48 - 1`` in ``t``, the rigid punch's rim singularity in the weight, not sampled), and
the trapezoid rule in the angle (exact for trigonometric polynomials below degree 96)."""
HEAVE_FLOOR = 1e-3
"""A profile heaves where ``w / depth`` falls below ``-HEAVE_FLOOR`` (0.1 % of the depth; the FEM's heave is 9 %)."""
VOLUME_EDGES = ("rigid", "uniform")
COMBINED = "volume + Winkler, rigid"
"""The rigid punch on the volume term beside the model's own Winkler term (:func:`combined_profile`)."""
"""The two loadings of :func:`volume_profile`: a rigid flat punch (surface at the depth over the disk, the volume it
displaces carried out by the layer's flux at the rim) and a uniform pressure over the disk (centre at the depth)."""
FEATURE_RADII_M = tuple(np.round(np.arange(25, 301) * 1e-4, 6))
"""Radii (2.5-30 mm every 0.1 mm) where :func:`foundation_profiles` looks for the first rise above rest and the lowest
point (the FEM's own field is sampled every 0.5 mm and interpolated linearly)."""


def disk_average(field, centre_m: tuple[float, float], radius_m: float, alpha: float) -> float:
    """:func:`skin_sim_node.model.heave.disk_average` with :data:`DISK_RADIAL_NODES` and :data:`DISK_ANGLE_NODES`."""
    return heave.disk_average(field, centre_m, radius_m, alpha, DISK_RADIAL_NODES, DISK_ANGLE_NODES)


def disk_averages(field, centre_m: tuple[float, float], radius_m: float) -> dict[str, float]:
    """:func:`disk_average` of ``field`` with each of :data:`DISK_WEIGHTS`, by name."""
    return {name: disk_average(field, centre_m, radius_m, alpha) for name, alpha in DISK_WEIGHTS.items()}


def model_single_curve(cfg: TissueConfig, centre_x_m: float) -> np.ndarray:
    """The model's relaxed single-punch force (N) at ``(centre_x_m, 0)`` at each of :data:`IMPLIED_DEPTH_M`."""
    return np.array([model_single_n(cfg, centre_x_m, d)[0] for d in IMPLIED_DEPTH_M])


def invert_curve(depths_m, forces_n, force_n: float) -> float:
    """The depth (m) at which a rising force-depth curve reaches ``force_n`` (log-log interpolation, no
    extrapolation: a force outside the curve raises ``ValueError``)."""
    f = np.asarray(forces_n, float)
    if not f[0] <= force_n <= f[-1]:
        raise ValueError(f"{force_n:.4g} N is outside the curve's {f[0]:.4g}-{f[-1]:.4g} N")
    return float(np.exp(np.interp(np.log(force_n), np.log(f), np.log(np.asarray(depths_m, float)))))


@dataclass
class Implied:
    """What the FEM's pair force implies for the model's coupling at one distance and depth.

    ``lowering`` is the surface lowering ``w`` at the punch over the depth (+ lowered, - raised) with which the model's
    own single-punch curve gives the FEM's pair force, ``F_model(depth - w) = F_pair_FEM``. ``lowering_ratio`` removes
    the model's single-punch error: ``F_model(depth - w) / F_model(depth) = F_pair_FEM / F_single_FEM``, the ``w`` that
    gives the FEM's interaction. ``fem_curve`` inverts the FEM's own single-punch curve (its 0.25 mm load stops,
    linear between them, as :meth:`~.hyperelastic3d.Result3D.force_n`), None where the pair force lies beyond its
    deepest stop. The disk averages (the FEM's single-punch field, over the other punch's disk) exist at
    :data:`MAX_DEPTH_M` only, where the FEM keeps its surface field.
    """

    distance_m: float
    depth_m: float
    fem_ratio: float  # F_pair_FEM / F_single_FEM
    lowering: float
    lowering_ratio: float
    fem_curve: float | None
    at_centre: float | None  # the FEM single's u / depth at the other punch's centre (MAX_DEPTH_M)
    disk: dict[str, float] | None  # the FEM single's u / depth averaged over the other's disk, by DISK_WEIGHTS
    overlapping: bool  # the two disks overlap (d < 2 a)
    single_error: float  # the model's single punch against the FEM's, F_single_model / F_single_FEM - 1
    outside_lens: dict[str, float] | None = None  # overlapping disks: the disk averages over the part of the other's
    # disk outside this punch's own (the lens left out), by DISK_WEIGHTS


def fem_field(res: Result3D, depth_m: float):
    """The FEM's surface field over ``depth_m`` as a vectorised ``f(x_m, y_m)`` (global coordinates, mirrored across
    ``y = 0``; bilinear on the 0.5 mm samples), for :func:`disk_averages`."""
    interp = RegularGridInterpolator((res.sample_y_m, res.sample_x_m), res.field_down_m / depth_m)

    def f(x, y):
        return interp(np.stack(np.broadcast_arrays(np.abs(y), x), -1))

    return f


def disk_averages_outside(
    field, centre_m: tuple[float, float], radius_m: float, hole_centre_m: tuple[float, float], hole_radius_m: float
) -> dict[str, float]:
    """:func:`disk_averages` over the part of the disk outside a second disk (the hole), each weight renormalised
    over that part: ``int f W 1_out dA / int W 1_out dA`` (the indicator makes the integrand discontinuous, so the
    quadrature is accurate to about 1e-3 here, not to round-off)."""

    def outside(x, y):
        return np.hypot(x - hole_centre_m[0], y - hole_centre_m[1]) >= hole_radius_m

    out = {}
    for name, alpha in DISK_WEIGHTS.items():
        num = disk_average(lambda x, y: np.where(outside(x, y), field(x, y), 0.0), centre_m, radius_m, alpha)
        den = disk_average(lambda x, y: outside(x, y).astype(float), centre_m, radius_m, alpha)
        out[name] = num / den
    return out


def implied(
    cfg: TissueConfig, rs: list[Row], fresh: bool = False, progress: bool = True, missing_ok: bool = False
) -> list[Implied] | None:
    """:class:`Implied` for each row of :data:`IMPLIED_DISTANCES_M`.

    The lowering inverts the model's single punch at the pair's position ``x = d/2`` (:func:`model_single_curve`).
    The FEM's profile is the single-punch solve of the same distance (the punch at ``x = d/2`` on the pair's mirrored
    mesh, the solve ``F_single_FEM`` comes from), averaged over the other punch's disk, centred at ``x = -d/2``.
    With ``missing_ok`` None when a solve is not cached.
    """
    a = cfg.tool_radius_m
    out = []
    for d in IMPLIED_DISTANCES_M:
        single = fem_solve(fem_setup(cfg, d, False), fresh, progress, missing_ok)
        if single is None:
            return None
        curve = model_single_curve(cfg, d / 2)
        field = fem_field(single, MAX_DEPTH_M)
        for r in (r for r in rs if abs(r.distance_m - d) < 1e-9):
            ratio = r.fem_pair_n / r.fem_single_n
            low = 1 - invert_curve(IMPLIED_DEPTH_M, curve, r.fem_pair_n) / r.depth_m
            low_ratio = 1 - invert_curve(IMPLIED_DEPTH_M, curve, ratio * r.model_single_n) / r.depth_m
            stops, forces = np.r_[0.0, single.depths_m], np.r_[0.0, single.forces_n]
            fem_curve = 1 - float(np.interp(r.fem_pair_n, forces, stops)) / r.depth_m if r.fem_pair_n <= forces[-1] else None
            deepest = abs(r.depth_m - MAX_DEPTH_M) < 1e-12
            centre = (-d / 2, 0.0)
            out.append(
                Implied(
                    d,
                    r.depth_m,
                    ratio,
                    low,
                    low_ratio,
                    fem_curve,
                    float(np.squeeze(field(np.array(centre[0]), np.array(centre[1])))) if deepest else None,
                    disk_averages(field, centre, a) if deepest else None,
                    d < 2 * a,
                    r.force_errors[1],
                    disk_averages_outside(field, centre, a, (d / 2, 0.0), a) if deepest and d < 2 * a else None,
                )
            )
    return out


def implied_text(imps: list[Implied]) -> str:
    """:func:`implied` as a markdown table (fractions of the depth; + lowered, - raised)."""
    names = list(DISK_WEIGHTS)
    lines = [
        "| d (mm) | depth (mm) | FEM pair / single | w: model curve | w: interaction | w: FEM curve "
        "| FEM u at other centre | " + " | ".join(f"FEM u, {n} disk" for n in names) + " |",
        "|---|---|---|---|---|---|---|" + "---|" * len(names),
    ]

    def fmt(v):
        return "-" if v is None else f"{v:+.3f}"

    for m in imps:
        disk = [fmt(None if m.disk is None else m.disk[n]) for n in names]
        lines.append(
            f"| {m.distance_m * 1e3:g} | {m.depth_m * 1e3:g} | {m.fem_ratio:.3f} | {m.lowering:+.3f} "
            f"| {m.lowering_ratio:+.3f} | {fmt(m.fem_curve)} | {fmt(m.at_centre)} | " + " | ".join(disk) + " |"
        )
    return "\n".join(lines)


def implied_findings(imps: list[Implied]) -> str:
    """What :func:`implied` says: the coupling the model would need, against the FEM's own field."""
    deep = [m for m in imps if m.disk is not None]
    need = ", ".join(f"{m.distance_m * 1e3:g} mm {m.lowering_ratio:+.3f}" for m in deep)
    para = ", ".join(f"{m.distance_m * 1e3:g} mm {m.disk['parabolic']:+.3f}" for m in deep)
    best = ", ".join(
        f"{m.distance_m * 1e3:g} mm " + min(DISK_WEIGHTS, key=lambda n, m=m: abs(m.disk[n] - m.lowering_ratio))
        for m in deep
        if not m.overlapping
    )
    spread = max(abs(m.lowering - m.lowering_ratio) for m in imps)
    four = [m for m in deep if m.overlapping]
    times = [v / m.lowering_ratio for m in four for v in m.disk.values()] or [float("nan")]
    lo4, hi4 = min(times), max(times)
    lens = ", ".join(f"{v:+.3f} ({n})" for m in four if m.outside_lens for n, v in m.outside_lens.items()) or "-"
    return "\n".join(
        [
            f"- At {MAX_DEPTH_M * 1e3:g} mm the FEM's interaction needs the surface at the punch lowered by (over the "
            f"depth, - = raised) {need}; the FEM's own single-punch field averaged over the other's disk (parabolic "
            f"weight) is {para}. Closest weight where the disks are apart: {best}.",
            "- At 6 and 10 mm the needed raising is the FEM's heave averaged over the other punch's disk: a coupling "
            "through a disk average of a heaving field gives the sign and the size there. At 4 mm (disks overlapping) "
            f"the disk averages are {lo4:.1f}-{hi4:.1f} times the needed lowering: where the disks overlap, the other's "
            "part of the field is not free surface but a second rigid punch, and superposing two single-punch fields "
            f"overstates the shared dimple. Leaving the lens out does not mend it: over the rest of the disk the field "
            f"averages {lens}.",
            f"- Inverting the model's own curve at the FEM's pair force (w: model curve) instead of matching the "
            f"interaction differs by up to {spread:.3f} of the depth: the model's single punch is "
            f"{min(m.single_error for m in imps):+.1%} to {max(m.single_error for m in imps):+.1%} off the FEM's at "
            "these positions, and the force grows faster than the depth.",
        ]
    )


def layered_volume_length_m(cfg: TissueConfig, poisson: float = POISSON_RATIO) -> float:
    """:func:`volume_length_m` with the layered layer's own flux coefficient instead of ``h^3 / (3 mu)``.

    In a layer with its shear modulus varying with the depth ``zeta`` below the (shear-free) top, the shear stress is
    ``-zeta dp/dx`` and the flux ``q = -D dp/dx`` with ``D = int_0^h zeta^2 / mu(zeta) dzeta`` (``h^3 / (3 mu)`` when
    uniform); ``L^4 = T D``. The layers of ``cfg`` from the top, moduli as :func:`volume_parameters`.
    """
    t, _, _ = volume_parameters(cfg, poisson)
    coeff, top = 0.0, 0.0
    for la, e in zip(cfg.layers, layer_moduli_pa(cfg, poisson)):
        bottom = top + la.thickness_m
        coeff += (bottom**3 - top**3) / 3 * 2 * (1 + poisson) / e
        top = bottom
    return float((t * coeff) ** 0.25)


def volume_profile(radius_m, length_m: float, punch_radius_m: float, edge: str = "rigid") -> np.ndarray:
    """Surface lowering over the depth of one punch on the volume term (:func:`volume_length_m`), no Winkler term.

    Outside the disk ``w = A ker(r / L) + B kei(r / L)``, with ``Lap ker(r / L) = -kei(r / L) / L^2`` and
    ``Lap kei(r / L) = ker(r / L) / L^2``.

    - ``"rigid"``: the rigid flat punch. ``w = depth`` on the disk; at its rim ``w`` is continuous (the membrane's slope
      may jump: the rim carries a line force) and so are the layer's pressure (fixing the free constant of the
      pressure under the punch) and its flux, which carries the volume the punch displaces,
      ``2 pi a q(a) = pi a^2 depth``, i.e. ``L^4 d/dr Lap w (a) = -a depth / 2``: the heave holds that volume
      (``int w dA = 0`` over the whole surface).
    - ``"uniform"``: a uniform pressure over the disk instead, ``w = (1 / (2 pi T)) int p_load ker(|r - r'| / L) dA'``
      (the Green's function of ``L^4 Lap^2 + 1`` applied to ``-(h^3 / (3 mu)) Lap p_load``), by the addition theorem
      outside the disk ``w ~ Re[(2 pi a / k) I_1(k a) K_0(k r)]`` with ``k = e^{i pi / 4} / L``, inside
      ``Re[(2 pi / k^2)(1 - k a K_1(k a) I_0(k r))]``; scaled so that the centre is at the depth (the earlier attempt's
      volume term: the surface under the pad is not flat, its rim at about half the depth).

    Parameters
    ----------
    radius_m : array_like
        Distances from the punch's axis (m).
    length_m : float
        ``L`` (m).
    punch_radius_m : float
        The punch's radius ``a`` (m).
    edge : {"rigid", "uniform"}
        The loading.

    Returns
    -------
    numpy.ndarray
        ``w / depth`` (+ lowered, - raised).
    """
    r = np.asarray(radius_m, float)
    a, ell = punch_radius_m, length_m
    xa = a / ell
    if edge == "rigid":
        mat = [[special.ker(xa), special.kei(xa)], [-ell * special.keip(xa), ell * special.kerp(xa)]]
        c1, c2 = np.linalg.solve(mat, [1.0, -a / 2])
        outside = c1 * special.ker(r / ell) + c2 * special.kei(r / ell)
        return np.where(r <= a, 1.0, outside)
    if edge == "uniform":
        k = np.exp(1j * np.pi / 4) / ell
        ri = np.minimum(r, a)
        ro = np.maximum(r, a)
        inside = ((2 * np.pi / k**2) * (1 - k * a * special.kv(1, k * a) * special.iv(0, k * ri))).real
        outside = (2 * np.pi * a / k * special.iv(1, k * a) * special.kv(0, k * ro)).real
        centre = ((2 * np.pi / k**2) * (1 - k * a * special.kv(1, k * a))).real
        return np.where(r <= a, inside, outside) / centre
    raise ValueError(f"edge {edge!r}: one of {VOLUME_EDGES}")


def oscillation_needs_foundation_length_m(length_m: float) -> float:
    """The least Winkler length ``l`` for which the volume term's decay oscillates, ``L / sqrt(2)``.

    With the membranes' foundation ``-(T / l^2) w`` kept beside the volume term, the layer carries
    ``p = p_load + T Lap w - (T / l^2) w`` and outside the load ``L^4 Lap^2 w - (L^4 / l^2) Lap w + w = 0``. Its radial
    wavenumbers ``s = lambda^2`` solve ``L^4 s^2 - (L^4 / l^2) s + 1 = 0``: complex (a decaying oscillation) when
    ``l > L / sqrt(2)``, real below it. Either way the surface rises beside the punch: incompressibility blocks the
    ``k = 0`` mode (``int w dA = 0``), so the two decaying modes have opposite signs and their sum crosses zero
    (:func:`combined_profile`).
    """
    return length_m / np.sqrt(2)


@dataclass
class Profiles:
    """One punch's surface lowering over the depth (:data:`MAX_DEPTH_M`), by source: the FEM, the model, the volume
    term under each of :data:`VOLUME_EDGES`; and where each first rises above rest and where it is lowest."""

    length_m: float
    values: dict[str, dict[float, float]]  # source -> radius (PROFILE_RADII_M) -> w / depth
    rise_m: dict[str, float | None]  # source -> first radius beyond the punch where w < 0 (interpolated); None: never
    # (below -HEAVE_FLOOR: the model's modal field dips by 1e-4 of the depth at its patch's edge, 28 mm out)
    lowest: dict[str, tuple[float, float]]  # source -> (radius of the least w, the least w / depth)
    fem_radii_m: np.ndarray  # the FEM's field along +x, its samples
    fem_down: np.ndarray  # ... and w / depth there
    layer: tuple[float, float, float]  # the volume term's T (N/m), h (m), mu (Pa): volume_parameters
    foundation_length_m: float  # the model's Winkler length l (patch.foundation_length_m)
    layered_length_m: float  # L with the layered flux coefficient (layered_volume_length_m)

    def fem_fine(self, radius_m: float) -> float:
        """The FEM's w / depth at ``radius_m`` (linear between its 0.5 mm samples)."""
        return float(np.interp(radius_m, self.fem_radii_m, self.fem_down))


def _features(r, w) -> tuple[float | None, tuple[float, float]]:
    """First zero crossing from above (linear between samples; only where the profile then falls below
    ``-HEAVE_FLOOR``) and the minimum of a sampled profile."""
    r, w = np.asarray(r, float), np.asarray(w, float)
    neg = np.flatnonzero(w < -HEAVE_FLOOR)
    rise = None
    if neg.size and neg[0] > 0:
        i = neg[0]
        rise = float(r[i - 1] + (r[i] - r[i - 1]) * w[i - 1] / (w[i - 1] - w[i]))
    j = int(np.argmin(w))
    return rise, (float(r[j]), float(w[j]))


def foundation_profiles(
    cfg: TissueConfig, fresh: bool = False, progress: bool = True, missing_ok: bool = False
) -> Profiles | None:
    """The FEM's centred single punch, the model's (:func:`model_single`) and the volume term's profiles at
    :data:`MAX_DEPTH_M`, at :data:`PROFILE_RADII_M` and their features over :data:`FEATURE_RADII_M`."""
    centred = fem_solve(fem_setup(cfg, None, False), fresh, progress, missing_ok)
    if centred is None:
        return None
    _, _, tool = model_single(cfg, 0.0, MAX_DEPTH_M)
    ell, a = volume_length_m(cfg), cfg.tool_radius_m
    fine = np.asarray(FEATURE_RADII_M)
    fem_r, fem_w = centred.sample_x_m, centred.field_down_m[0] / MAX_DEPTH_M
    sources = {
        "FEM": lambda r: np.interp(r, fem_r, fem_w),
        "model": lambda r: np.array([tool.tissue.surface_displacement_at(float(x), 0.0) for x in np.atleast_1d(r)]) / MAX_DEPTH_M,
    }
    for edge in VOLUME_EDGES:
        sources[f"volume, {edge}"] = lambda r, edge=edge: volume_profile(r, ell, a, edge)
    foundation = float(cfg.as_flat().get("patch.foundation_length_m", float("nan")))
    if foundation > 0:
        sources[COMBINED] = lambda r: combined_profile(r, ell, foundation, a)
    values, rise, lowest = {}, {}, {}
    for name, f in sources.items():
        values[name] = {r: float(np.squeeze(f(r))) for r in PROFILE_RADII_M}
        rr = fem_r[fem_r >= a] if name == "FEM" else fine
        rise[name], lowest[name] = _features(rr, f(rr))
    return Profiles(ell, values, rise, lowest, fem_r, fem_w, volume_parameters(cfg), foundation, layered_volume_length_m(cfg))


def profiles_text(p: Profiles) -> str:
    """:func:`foundation_profiles` as markdown: the parameters, then one row per source."""
    t, h, mu = p.layer
    head = (
        f"Volume term: T = {t:.2f} N/m (the three membranes' tensions), h = {h * 1e3:.3f} mm (the whole tissue), "
        f"mu = {mu:.0f} Pa (Reuss mean of the layers' E / (2 (1 + nu)), nu = {POISSON_RATIO:g}): "
        f"L = (T h^3 / (3 mu))^(1/4) = {p.length_m * 1e3:.2f} mm."
    )
    lines = [
        head,
        "",
        "| w / depth (2 mm) | "
        + " | ".join(f"r = {r * 1e3:g} mm" for r in PROFILE_RADII_M)
        + " | rises above rest from (mm) | lowest at (mm) | lowest w / depth |",
        "|---|" + "---|" * (len(PROFILE_RADII_M) + 3),
    ]
    for name, vals in p.values.items():
        rise = p.rise_m[name]
        r_lo, w_lo = p.lowest[name]
        low = "- | -" if rise is None else f"{r_lo * 1e3:.1f} | {w_lo:+.3f}"
        lines.append(
            f"| {name} | "
            + " | ".join(f"{vals[r]:+.3f}" for r in PROFILE_RADII_M)
            + f" | {'never' if rise is None else f'{rise * 1e3:.1f}'} | {low} |"
        )
    return "\n".join(lines)


def volume_findings(p: Profiles) -> str:
    """What :func:`foundation_profiles` says about the heave's source."""
    fem, rig, uni = (p.values[k] for k in ("FEM", "volume, rigid", "volume, uniform"))
    _, h, _ = p.layer
    foundation = p.foundation_length_m
    flat = [r for r in FEATURE_RADII_M if p.fem_fine(r) < p.lowest["FEM"][1] + 0.005]
    return "\n".join(
        [
            f"- The volume term alone (no Winkler term) heaves where the FEM does: it rises above rest from "
            f"{p.rise_m['volume, rigid'] * 1e3:.1f} mm (rigid punch) or {p.rise_m['volume, uniform'] * 1e3:.1f} mm "
            f"(uniform pressure) against the FEM's {p.rise_m['FEM'] * 1e3:.1f} mm, lowest at "
            f"{p.lowest['volume, rigid'][0] * 1e3:.1f} / {p.lowest['volume, uniform'][0] * 1e3:.1f} mm against "
            f"{p.lowest['FEM'][0] * 1e3:.1f} mm (the FEM's trough is flat, within 0.005 of its least value from "
            f"{flat[0] * 1e3:.1f} to {flat[-1] * 1e3:.1f} mm). One length, "
            f"L = {p.length_m * 1e3:.2f} mm from the config's tensions and moduli, no fit (the layered flux "
            f"coefficient, `int zeta^2 / mu dzeta`, gives {p.layered_length_m * 1e3:.2f} mm; a top bonded against shear "
            f"would give h^3 / (12 mu), L / sqrt(2)).",
            f"- Sizes: the rigid punch's heave is {rig[8e-3] / fem[8e-3]:.1f} x the FEM's at 8 mm "
            f"({rig[8e-3]:+.3f} against {fem[8e-3]:+.3f}) and its dimple at 4 mm {rig[4e-3]:+.3f} against "
            f"{fem[4e-3]:+.3f}; the uniform pressure gives {uni[8e-3]:+.3f} at 8 mm and {uni[4e-3]:+.3f} at 4 mm; at "
            f"10 mm {rig[10e-3]:+.3f} (rigid) and {uni[10e-3]:+.3f} (uniform) against {fem[10e-3]:+.3f}. "
            "Thin-layer theory wants lateral lengths well above "
            f"h = {h * 1e3:.1f} mm and L is {p.length_m / h:.2f} h: the positions hold, the sizes are approximate.",
            f"- Kept beside the model's Winkler term (l = {foundation * 1e3:.2f} mm, below "
            f"L / sqrt(2) = {oscillation_needs_foundation_length_m(p.length_m) * 1e3:.2f} mm, so the decay does not "
            "oscillate) the volume term still heaves: incompressibility holds the displaced volume outside the punch, so "
            "the two decaying modes have opposite signs (`combined_profile`). The rigid punch on both rises above rest "
            f"from {p.rise_m[COMBINED] * 1e3:.1f} mm, lowest at {p.lowest[COMBINED][0] * 1e3:.1f} mm "
            f"({p.lowest[COMBINED][1]:+.3f}); at 4 / 6 / 8 / 10 mm "
            + " / ".join(f"{p.values[COMBINED][r]:+.3f}" for r in (4e-3, 6e-3, 8e-3, 10e-3))
            + " against the FEM's "
            + " / ".join(f"{fem[r]:+.3f}" for r in (4e-3, 6e-3, 8e-3, 10e-3))
            + ": closer to the FEM than either volume term alone, with no fit (the thin-layer limits above apply).",
        ]
    )


LINEAR_RADII_M = (3e-3, 4e-3, 6e-3, 8e-3, 10e-3, 13e-3, 20e-3)
"""Radii of the linear profiles (m): the rim's neighbourhood, the heave's trough and its tail."""


@dataclass
class Linear:
    """One punch and two punches in linear elasticity of the layers (:mod:`.layered_elastic`), beside the linear 3D
    FEM (:mod:`.fem`, :data:`~.references.FINEST_LEVEL`, its egg-carton interfaces), the neo-Hookean reference and the
    model's coupling kernel."""

    radius_m: float  # the punch's (the config's tool radius)
    stiffness_n_per_m: float  # the exact rigid punch's force per metre of depth
    fem_stiffness_n_per_m: float  # the linear FEM's
    profile: dict[float, float]  # radius -> w / depth, exact
    fem_profile: dict[float, float]  # ... the linear FEM's (its samples along +x, 0.5 mm apart, interpolated)
    hyper_profile: dict[float, float]  # ... the neo-Hookean FEM's at MAX_DEPTH_M
    coupling: dict[float, float]  # distance -> G, two equal rigid punches (first order)
    kernel: dict[float, float]  # distance -> the model's coupling table G (heave.coupling_table, one state)
    overlap: dict[float, float]  # distance (footprints overlapping) -> interaction / single, the full linear pair solve
    first_stop: dict[float, tuple[float, float]]  # distance -> (the reference's first load stop (m), its interaction /
    # single there: nearly linear, its single punch 1.06 x the linear 3D FEM's at 0.3 mm, large_deformation.md)


def linear_layers(cfg: TissueConfig, prof: Profiles, progress: bool = True) -> Linear:
    """:class:`Linear` for ``cfg`` (the linear FEM's cached solve; about 3 s here for the rest)."""
    from .fem import reference as linear_reference

    a = cfg.tool_radius_m
    stack = layered_elastic.layers(cfg)
    punch = layered_elastic.rigid_punch(stack, a)
    setup = replace(FemSetup(), moduli_pa=layer_moduli_pa(cfg), tissue=_geometry_key(cfg))
    res = linear_reference(mesh_levels(FINEST_LEVEL, setup), progress=progress)
    row = res.surface_per_depth[int(np.argmin(np.abs(res.sample_y_m)))]
    exact = punch.profile(LINEAR_RADII_M)
    hyper = {r: prof.fem_fine(r) for r in LINEAR_RADII_M}
    s_tab, g_tab = heave.coupling_table(cfg, a, a)
    close = [d for d in DISTANCES_M if d < 2 * a]
    overlap = {}
    for d in tqdm(close, desc="linear pair, overlapping footprints (2D solve)", disable=not progress, leave=False):
        overlap[d] = layered_elastic.rigid_pair_interaction(stack, a, d)
    first = {}
    for d in DISTANCES_M:
        pair, single = (fem_solve(fem_setup(cfg, d, partner), progress=progress) for partner in (True, False))
        first[d] = (float(pair.depths_m[0]), float(pair.forces_n[0] / single.forces_n[0] - 1))
    return Linear(
        a,
        punch.stiffness_n_per_m,
        res.stiffness_n_per_m,
        dict(zip(LINEAR_RADII_M, map(float, exact))),
        {r: float(np.interp(r, res.sample_x_m, row)) for r in LINEAR_RADII_M},
        hyper,
        dict(zip(DISTANCES_M, map(float, punch.coupling(punch, DISTANCES_M)))),
        {d: float(np.interp(d, s_tab, g_tab)) for d in DISTANCES_M},
        overlap,
        first,
    )


LINEAR_INTRO = """## Linear elasticity of the layers

The layers of the config in linear elasticity, solved exactly in the wavenumber (`skin_sim_lab/validation/
layered_elastic.py`: flat interfaces at their mean depths, bonded, on a rigid base, top free of shear; a rigid flat
punch by ring collocation): the regime of the linear 3D FEM, which it checks. Two equal rigid punches couple by
Betti's theorem, `G(s) = int C p_hat^2 J0(k s) k dk / p_hat(0)` (first order), and to first order the interaction over
the single force is `-G`. Where the disks overlap (4 mm) first order does not hold, and the pair is solved whole: the
union footprint on a 0.1 mm grid, the surface response by 2D FFT, the pressures by conjugate gradients
(`layered_elastic.rigid_pair_interaction`)."""


def linear_text(lin: Linear, rs: list[Row]) -> str:
    """:func:`linear_layers` as markdown: the stiffnesses, the profiles, the couplings against the reference's."""
    lines = [
        f"Rigid punch (r {lin.radius_m * 1e3:g} mm) at unit depth: exact {lin.stiffness_n_per_m:.1f} N/m, linear FEM "
        f"{lin.fem_stiffness_n_per_m:.1f} N/m ({lin.stiffness_n_per_m / lin.fem_stiffness_n_per_m - 1:+.1%}).",
        "",
        "| w / depth | " + " | ".join(f"r = {r * 1e3:g} mm" for r in LINEAR_RADII_M) + " |",
        "|---|" + "---|" * len(LINEAR_RADII_M),
    ]
    for name, vals in (
        ("linear, exact (layered)", lin.profile),
        ("linear FEM", lin.fem_profile),
        (f"neo-Hookean FEM at {MAX_DEPTH_M * 1e3:g} mm", lin.hyper_profile),
    ):
        lines.append(f"| {name} | " + " | ".join(f"{vals[r]:+.4f}" for r in LINEAR_RADII_M) + " |")
    lines += [
        "",
        "| d (mm) | linear: -G (interaction / single) | FEM interaction / single, 1 mm | 2 mm | the model's kernel, -G "
        "(before the overlap hold) "
        "| the model's interaction / single, 1 mm | 2 mm |",
        "|---|---|---|---|---|---|---|",
    ]
    for d in DISTANCES_M:
        at = [r for r in rs if r.distance_m == d]
        lin_txt = f"{lin.overlap[d]:+.4f} (pair solved)" if d in lin.overlap else f"{-lin.coupling[d]:+.4f}"
        lines.append(
            f"| {d * 1e3:g} | {lin_txt} | {at[0].fem_fraction:+.4f} | {at[1].fem_fraction:+.4f} | {-lin.kernel[d]:+.4f} "
            f"| {at[0].model_fraction:+.4f} | {at[1].model_fraction:+.4f} |"
        )
    return "\n".join(lines)


def linear_findings(lin: Linear, rs: list[Row]) -> str:
    """What :func:`linear_layers` says about the reference's regime and the coupling's kernel."""
    dev = {r: abs(lin.profile[r] - lin.fem_profile[r]) for r in LINEAR_RADII_M}
    near = min(LINEAR_RADII_M)
    one = {r.distance_m: r for r in rs if r.depth_m == min(DEPTHS_M)}
    two = {r.distance_m: r for r in rs if r.depth_m == max(DEPTHS_M)}
    hyper_1mm = one[FAR_DISTANCE_M].fem_single_n
    d_mid = (6e-3, 10e-3)
    return "\n".join(
        [
            f"- The exact solution and the linear FEM agree: stiffness within "
            f"{abs(lin.stiffness_n_per_m / lin.fem_stiffness_n_per_m - 1):.1%}, the surface within "
            f"{max(v for r, v in dev.items() if r > near):.4f} of the depth from {sorted(dev)[1] * 1e3:g} to "
            f"{max(dev) * 1e3:g} mm and {dev[near]:.4f} at {near * 1e3:g} mm, beside the rim, where the profile falls by "
            f"{(lin.profile[near] - lin.profile[sorted(dev)[1]]) / ((sorted(dev)[1] - near) * 1e3):.2f} of the depth per "
            "mm (the FEM's egg-carton interfaces against flat ones, its mesh, its sides at 30 mm).",
            f"- The neo-Hookean reference has left the linear regime at these depths: its single punch takes "
            f"{hyper_1mm:.3f} N at {min(DEPTHS_M) * 1e3:g} mm, the linear {lin.stiffness_n_per_m * min(DEPTHS_M):.3f} N "
            f"({hyper_1mm / (lin.stiffness_n_per_m * min(DEPTHS_M)) - 1:+.0%}); at 2 mm its dimple is wider "
            f"({lin.hyper_profile[4e-3]:+.3f} of the depth at 4 mm against {lin.profile[4e-3]:+.3f}) and its heave deeper "
            f"({lin.hyper_profile[10e-3]:+.3f} at 10 mm against {lin.profile[10e-3]:+.3f}).",
            "- About half of the heave the coupling needs is beyond linear elasticity: it gives the pair "
            + ", ".join(f"{-lin.coupling[d]:+.3f} at {d * 1e3:g} mm" for d in d_mid)
            + " of the single force; the reference "
            + ", ".join(f"{lin.first_stop[d][1]:+.3f}" for d in d_mid)
            + f" at its first load stop ({lin.first_stop[d_mid[0]][0] * 1e3:g} mm, nearly linear: the part there above "
            "the linear solution is its coarse mesh or its egg-carton interfaces, not separated here), "
            + ", ".join(f"{one[d].fem_fraction:+.3f}" for d in d_mid)
            + f" at {min(DEPTHS_M) * 1e3:g} mm, growing with the depth; the model "
            + ", ".join(f"{one[d].model_fraction:+.3f}" for d in d_mid)
            + " (its kernel "
            + ", ".join(f"{-lin.kernel[d]:+.3f}" for d in d_mid)
            + ", times its chain's tangent over secant stiffness). The thin-layer kernel (no fitted constant) lands near "
            "the reference there, but it is not the linear solution of these layers (thin-layer theory overstates a "
            "layer whose lengths are not well above its thickness); it stands for the reference's heave, which no "
            f"linear kernel of this tissue gives. At {FAR_DISTANCE_M * 1e3:g} mm (fractions of the single force) linear "
            f"elasticity gives {-lin.coupling[FAR_DISTANCE_M]:+.4f}, the reference {one[FAR_DISTANCE_M].fem_fraction:+.4f}, "
            f"the model's kernel {-lin.kernel[FAR_DISTANCE_M]:+.4f}: its tail is the thin layer's slow decay, not the "
            "tissue's.",
            *[
                f"- Overlapping at {d * 1e3:g} mm, the whole linear pair gives {v:+.4f} of the single force; the reference "
                f"{one[d].fem_fraction:+.4f} at {min(DEPTHS_M) * 1e3:g} mm, "
                f"{two[d].fem_fraction:+.4f} at {max(DEPTHS_M) * 1e3:g} mm and "
                f"{lin.first_stop[d][1]:+.4f} at its first load stop (nearly independent of the depth); "
                f"the model {one[d].model_fraction:+.4f}, "
                f"{two[d].model_fraction:+.4f}."
                for d, v in lin.overlap.items()
            ],
        ]
    )


def aims_text() -> str:
    """The aims and the verdict rules."""
    return (
        f"Aims (issue 32), per row: the model's force per punch, paired and single, within {FORCE_TOL:.0%} of the FEM's; "
        f"the model's interaction (pair - single) within {INTERACTION_TOL:.0%} of the FEM's (`interaction err` = model "
        f"/ FEM - 1); where the FEM interaction is below {MIN_INTERACTION_FRACTION:.0%} of the single force, marked "
        f"(abs.), the rule is absolute: the model's interaction fraction within {INTERACTION_TOL * MIN_INTERACTION_FRACTION:.1%} "
        f"of the single force of the FEM's (`interaction err` = difference of the fractions / {MIN_INTERACTION_FRACTION:.0%}); "
        f"at {FAR_DISTANCE_M * 1e3:g} mm the model's pair force equals its single force within {FAR_TOL:.0%}."
    )


METHOD = """## Method

**Model.** `SharedSkin([make_tool(cfg), make_tool(cfg)])` (`skin_sim_node/tools/hands.py`) of `config/default.yaml`
(flat punch, radius 2.5 mm, layered form, the calibrated default): punch centres at x = -d/2 and +d/2, y = 0, both
ramped to the depth over 300 ticks at 1 kHz and held until the slowest viscoelastic arm (0.28 s) has decayed to
0.1 % (1934 ticks): the reference is quasi-static and elastic, so the relaxed force is compared (after the issue's
300-tick hold the arms still add about 17 %, shown in the second table). The force is read at the last tick and
averaged over the two punches (the Gauss-Seidel order leaves them within the spread stated below the table). The
single punch is one `make_tool(cfg)` at x = +d/2 with the same ramp.

**Reference.** The 3D compressible neo-Hookean FEM of `skin_sim_lab/validation/hyperelastic3d.py` (Bonet & Wood
eq 6.27, Newton with the consistent tangent, load steps of 0.25 mm with halving), on the egg-carton layered block of
`skin_sim_lab/validation/fem.py`: moduli and geometry read from the same config, modulus per Gauss point by the
egg-carton interfaces at its global position (the pair is centred on an interface peak at x = 0, so x = 0 and y = 0
are symmetry planes of the material), bottom fixed, outer sides on rollers, 60 x 60 mm block. The punch is rigid and
flat, frictionless as in the existing reference (u_z = -depth on the surface nodes inside the disk at rest, in-plane
free). Pair: quarter model x, y >= 0 with the punch at x = d/2 (at 4 mm the disks overlap; in the quarter the union
is the one disk cut by x = 0, the force per punch is half the pair's total). Single: the half model y >= 0 on the
mirror image of the same mesh, the punch at x = +d/2 alone, so pair and single share one discretisation and their
difference is the interaction. Except at 4 mm: there the quarter's mesh conforms to the union of the two disks, and its
mirror image would end the single disk's sliver beyond x = 0 on a staircase of nodes (the single's force then moved
with the mesh level: 0.0856, 0.0894, 0.0862 N at 0.25 mm at levels -2, -1, 0); the single gets a mesh of its own,
conforming to its disk (`fem.py: _single_overlap_mesh`), and agrees with the 6 mm single (the same egg-carton site by
symmetry) within 0.22 %. Mesh: level -1 of the linear FEM (`two_punch.REFERENCE_LEVEL`: 4 elements over the punch
radius, 20-node serendipity hexes, 2 + 4 + 3 through the layers), the contact disk conforming
(`skin_sim_lab/validation/fem.py: build_offset_mesh`); the spacing of the punch band (0.625 mm) runs on to x = 0 for
d <= 10 mm, at 20 mm the 7.5 mm between the punch's rim and x = 0 are the band and 4 graded elements. Level -1, not
the -2 of the single punch's 3D references, because of the overlapping pair: its interaction over the single force is
-0.083 / -0.087 / -0.089 at 0.25 / 1 / 2 mm at level -2, -0.089 / -0.092 / -0.095 at -1 and -0.088 / -0.091 / -0.096
at 0 (66 588 and 101 724 DOFs, solved outside the table; docs/two_hands.md, "Session 13"); at 6 mm levels -2 and -1
agree within 0.002. The solves are cached in `docs/validation/hyper_cache/3d-<hash>.npz`.

**Valid for.** Quasi-static indentation (no rate, no viscoelasticity: the model's force is read after its hold), two
equal rigid flat punches at equal depths, frictionless contact, the default layered tissue and moduli, depths to 2 mm.
The mesh: 23k-35k DOFs a quarter (the pairs), 37k-70k a half (the singles), 19k the centred quarter; the linear FEM
at levels -2 to 1 is within 0.6 % of its finest level's stiffness (docs/validation/convergence.md); the
coarse band between the punches limits how small an interaction the reference resolves (the absolute rule below 2 %).
"""


def findings(rs: list[Row], c: Checks, prof: Profiles | None = None) -> str:
    """What the numbers say: the sign and size of each interaction, and the surface profile behind them (the coupling's
    kernel at :data:`FAR_DISTANCE_M` from ``prof``, :func:`foundation_profiles`, when given)."""
    lines = ["## Findings", ""]
    for depth in DEPTHS_M:
        sel = [r for r in rs if r.depth_m == depth]
        fem = ", ".join(f"{r.distance_m * 1e3:g} mm {r.fem_fraction:+.1%}" for r in sel)
        mod = ", ".join(f"{r.distance_m * 1e3:g} mm {r.model_fraction:+.1%}" for r in sel)
        lines.append(f"- {depth * 1e3:g} mm deep, interaction / single: FEM {fem}; model {mod}.")
    single = max(abs(r.force_errors[1]) for r in rs)
    lines.append(f"- The model's single punch is within {single:.1%} of the FEM's at every position and depth.")
    heave = [r for r in PROFILE_RADII_M if c.fem_profile[r] < 0]
    closest = min(r.distance_m for r in rs)  # the overlapping pair (4 mm, disks of 2.5 mm)
    overlap = ", ".join(
        f"{r.depth_m * 1e3:g} mm deep {r.interaction_error:+.0%} of the FEM's interaction" for r in rs if r.distance_m == closest
    )
    far = [r for r in rs if abs(r.distance_m - FAR_DISTANCE_M) < 1e-9]
    far_model = " / ".join(f"{r.model_fraction:+.1%}" for r in far)
    far_fem = " / ".join(f"{r.fem_fraction:+.1%}" for r in far)
    kernel_far = None if prof is None else prof.values.get(COMBINED, {}).get(FAR_DISTANCE_M)  # the coupling's profile
    tail = "" if kernel_far is None else f" ({kernel_far:+.4f} of the depth against {c.fem_profile[FAR_DISTANCE_M]:+.4f})"
    if heave:
        lo = min(c.fem_profile.values())
        lines += [
            f"- The reference's surface beside one punch rises above its rest height at "
            f"{', '.join(f'{r * 1e3:g}' for r in heave)} mm (least u/depth {lo:+.3f}): the 5.3 mm of nearly incompressible "
            "tissue (nu = 0.48) bonded to a rigid base pushes the volume under the punch up around it. A second punch in "
            "that ring presses skin that stands higher, so the FEM's pair needs more force than its single punch there "
            "(positive interaction). The model's own field (its membranes on their foundations, which the display "
            "draws) decays monotonically and never rises; the coupling between tools carries the heave instead "
            "(skin_sim_node.model.heave: the thin-layer volume term beside the membranes' Winkler term, no fitted "
            "constant, averaged over the receiving disk), so the model's interaction has the FEM's sign at 6 and 10 mm.",
            "- What still misses: at 4 mm the disks overlap; superposing one punch's field over the other's disk would "
            "lower it by +0.25 of the depth where the FEM's pair implies about a quarter of that (the section below: "
            "overlapping disks are one union-shaped contact, not two), and the coupling holds the kernel from where the "
            "disks touch, its slope eased over 0.5 mm (skin_sim_node.tools.hands.OVERLAP_EASE_M: +0.084 at 4 mm): "
            + overlap
            + f"; and at 20 mm the thin-layer heave decays more slowly than the FEM's{tail}, an interaction of "
            f"{far_model} against the FEM's {far_fem}: "
            f"within the issue's far-field {FAR_TOL:.0%}, outside this table's absolute rule "
            f"({INTERACTION_TOL * MIN_INTERACTION_FRACTION:.1%}).",
        ]
    return "\n".join(lines)


IMPLIED_INTRO = """## What the reference implies for the coupling

The model's coupling lowers the surface under one punch by the other's field, and each punch's chain presses
`depth - w` (`CoupledTool`). Here `w` is solved for from the FEM's forces: `w: model curve` from
`F_single_model(depth - w) = F_pair_FEM` (the model's relaxed single punch at x = d/2, 0.6-2.4 mm every 0.1 mm,
log-log interpolation), `w: interaction` from `F_single_model(depth - w) / F_single_model(depth) = F_pair_FEM /
F_single_FEM` (the FEM's interaction, free of the model's single-punch error), `w: FEM curve` from the FEM's own
single-punch curve (its 0.25 mm load stops; `-` where the pair force is beyond the deepest stop). Beside them the FEM's
single punch (the solve at x = d/2 on the pair's mesh) at the other punch's centre (x = -d/2) and averaged over the
other's disk (radius 2.5 mm) with the weights uniform, parabolic `1 - s^2/a^2` and the rigid punch's pressure
`1/sqrt(1 - s^2/a^2)` (Gauss-Jacobi in `s^2/a^2`). The FEM keeps its surface field at 2 mm only. Fractions of the
depth, + lowered, - raised."""

VOLUME_INTRO = """## Where the heave would come from

A membrane of tension T over a thin incompressible layer (thickness h, shear modulus mu) bonded to a rigid base: the
layer's pressure p drives a lateral flux `q = -(h^3/(3 mu)) grad p` (lubrication theory, top free of shear), which
lowers the surface by `w = -(h^3/(3 mu)) Lap p`; the membrane carries `p = p_load + T Lap w`. Outside the load
`L^4 Lap^2 w + w = 0`, `L^4 = T h^3/(3 mu)`, solved by `w = A ker(r/L) + B kei(r/L)` (Kelvin functions), which cross
zero: the heave. `rigid`: the surface at the depth over the disk, and at the rim the layer's flux carries out the
volume the punch displaces, `L^4 d/dr Lap w = -a depth/2` (no net volume). `uniform`: a uniform pressure over the disk
(the Green's function of `L^4 Lap^2 + 1` over the disk), the centre at the depth. No Winkler term in either. FEM and
model as in the profile check above (2 mm, the FEM's field every 0.5 mm)."""


FINE_LEVEL = REFERENCE_LEVEL + 1
"""One mesh level finer than the reference's (6 elements over the punch's radius): its solves, where cached, show how
far the reference's discretisation moves each row (:func:`fine_rows`, :func:`mesh_convergence_text`). A pair and its
single take 12-30 min each here with PARDISO, so the command reads them and never solves them."""

CONVERGENCE_INTRO = f"""## The reference one mesh level finer

The rows whose solves are cached at level {FINE_LEVEL} (finer over the punch's radius and through the layers;
`fem.mesh_levels`) beside the table's level {REFERENCE_LEVEL}: the FEM's interaction over its single force at both,
and the model's interaction error and verdict against each. A verdict that differs between the levels sits inside the
reference's own discretisation error."""


def fine_rows(cfg: TissueConfig) -> list[Row]:
    """:func:`rows` at :data:`FINE_LEVEL` for each distance whose pair and single are both cached (none solved)."""
    out: list[Row] = []
    for d in DISTANCES_M:
        got = rows(cfg, progress=False, missing_ok=True, level=FINE_LEVEL, distances_m=(d,))
        out += got or []
    return out


def mesh_convergence_text(rs: list[Row], fine: list[Row]) -> str:
    """The table's rows (``rs``, :data:`REFERENCE_LEVEL`) beside the same rows at :data:`FINE_LEVEL` (``fine``,
    :func:`fine_rows`), with the change of the FEM's interaction and single force between the two levels."""
    ref = {(r.distance_m, r.depth_m): r for r in rs}
    lines = [
        f"| d (mm) | depth (mm) | FEM int. / single, level {REFERENCE_LEVEL} | level {FINE_LEVEL} | change "
        f"| FEM single, level {REFERENCE_LEVEL} -> {FINE_LEVEL} | interaction err, level {REFERENCE_LEVEL} "
        f"| level {FINE_LEVEL} | verdict, level {REFERENCE_LEVEL} | level {FINE_LEVEL} |",
        "|---|---|---|---|---|---|---|---|---|---|",
    ]
    moved = []
    for f in fine:
        r = ref[f.distance_m, f.depth_m]
        lines.append(
            f"| {f.distance_m * 1e3:g} | {f.depth_m * 1e3:g} | {r.fem_fraction:+.4f} | {f.fem_fraction:+.4f} "
            f"| {f.fem_fraction - r.fem_fraction:+.4f} | {f.fem_single_n / r.fem_single_n - 1:+.2%} "
            f"| {r.interaction_error:+.1%}{' (abs.)' if r.small_interaction else ''} "
            f"| {f.interaction_error:+.1%}{' (abs.)' if f.small_interaction else ''} "
            f"| {'PASS' if r.ok else 'FAIL'} | {'PASS' if f.ok else 'FAIL'} |"
        )
        if r.ok != f.ok:
            moved.append(f"{f.distance_m * 1e3:g} mm, {f.depth_m * 1e3:g} mm")
    solved = sorted({f"{f.distance_m * 1e3:g}" for f in fine}, key=float)
    missing = [f"{d * 1e3:g}" for d in DISTANCES_M if f"{d * 1e3:g}" not in solved]
    lines += [
        "",
        f"Solved at level {FINE_LEVEL}: {', '.join(solved) or 'none'} mm"
        + (f" (not: {', '.join(missing)} mm)" if missing else "")
        + "; "
        + (f"verdicts that change with the mesh: {'; '.join(moved)}." if moved else "no verdict changes with the mesh."),
    ]
    return "\n".join(lines)


def markdown(
    rs: list[Row],
    c: Checks,
    command: str,
    imps: list[Implied] | None = None,
    prof: Profiles | None = None,
    lin: Linear | None = None,
    fine: list[Row] | None = None,
) -> str:
    """The page: the command, the table, the aims and verdicts, the reference one level finer (``fine``:
    :func:`fine_rows`), the checks, the findings, what the reference implies for the coupling (``imps``, :func:`implied`), where
    the heave would come from (``prof``, :func:`foundation_profiles`), and the method."""
    ok = all(r.ok for r in rs)
    spread = max(r.model_pair_spread for r in rs)
    return "\n".join(
        [
            "# Two flat punches on one skin (issue 32): model vs 3D neo-Hookean FEM",
            "",
            f"Written by `{command}` (`skin_sim_lab/validation/two_punch.py`).",
            "",
            "## Results",
            "",
            "Force per punch; `interaction` = pair - single; errors are the model's against the FEM's.",
            "",
            table(rs),
            "",
            aims_text(),
            "",
            f"Overall: **{'PASS' if ok else 'FAIL'}** ({sum(r.ok for r in rs)} of {len(rs)} rows pass). "
            f"Largest left/right spread of the model's pair: {spread:.2%}.",
            "",
            f"The model after the issue's {ISSUE_HOLD_TICKS}-tick hold (its viscoelastic arms still carry force; the "
            f"table above reads it relaxed, after {RAMP_TICKS} + hold ticks, hold = tau_max ln(1/{RELAX_TOL:g})):",
            "",
            issue_table(rs),
            "",
            *([CONVERGENCE_INTRO, "", mesh_convergence_text(rs, fine), ""] if fine else []),
            "## Checks",
            "",
            "Lateral boundary: the single punch centred on the block (quarter model, the existing mesh) against the "
            "single punch 10 mm off centre (the 20 mm pair's single, half model); the difference bounds the side's "
            "effect on the 20 mm rows together with the mesh change.",
            "",
            checks_text(c),
            "",
            findings(rs, c, prof),
            "",
            *([] if imps is None else [IMPLIED_INTRO, "", implied_text(imps), "", implied_findings(imps), ""]),
            *([] if prof is None else [VOLUME_INTRO, "", profiles_text(prof), "", volume_findings(prof), ""]),
            *([] if lin is None else [LINEAR_INTRO, "", linear_text(lin, rs), "", linear_findings(lin, rs), ""]),
            METHOD,
        ]
    )


def main(argv=None) -> int:
    """``skin-sim two-punch``: print the table, write ``docs/validation/two_punch.md``; 1 when an aim fails."""
    ap = argparse.ArgumentParser(prog="skin-sim two-punch", description=__doc__.split("\n")[0])
    ap.add_argument(
        "--fresh", action="store_true", help="solve the FEM again ignoring the caches (about 40 min with the fem extra's PARDISO)"
    )
    ap.add_argument("--out", default=str(OUT), help="folder of two_punch.md (under docs/: solves go to the tracked cache)")
    a = ap.parse_args(argv)
    out = Path(a.out)
    out.mkdir(parents=True, exist_ok=True)
    cache.WRITE_DOCS = out.resolve().is_relative_to(cache.DOCS)
    t0 = time.perf_counter()
    cfg = load_tissue_config(CONFIG)
    rs = rows(cfg, a.fresh)
    fine = fine_rows(cfg)  # read, never solved here
    c = checks(cfg, a.fresh)
    imps = implied(cfg, rs, a.fresh)
    prof = foundation_profiles(cfg, a.fresh)
    lin = linear_layers(cfg, prof)
    command = "skin-sim two-punch" + "".join(f" {shlex.quote(x)}" for x in (argv if argv is not None else sys.argv[1:]))
    text = markdown(rs, c, command, imps, prof, lin, fine)
    (out / "two_punch.md").write_text(text)
    print(table(rs))
    print()
    print(aims_text())
    print()
    print(issue_table(rs))
    print()
    if fine:
        print(mesh_convergence_text(rs, fine))
    else:
        print(f"(no row is cached one mesh level finer, level {FINE_LEVEL}: that section is left out)")
    print()
    print(checks_text(c))
    print()
    print(findings(rs, c, prof))
    print()
    print(implied_text(imps))
    print()
    print(implied_findings(imps))
    print()
    print(profiles_text(prof))
    print()
    print(volume_findings(prof))
    print()
    print(linear_text(lin, rs))
    print()
    print(linear_findings(lin, rs))
    ok = all(r.ok for r in rs)
    print(f"\noverall: {'PASS' if ok else 'FAIL'}  ({time.perf_counter() - t0:.0f} s; wrote {out / 'two_punch.md'})")
    return 0 if ok else 1
