"""``skin-sim two-punch``: two flat punches on one skin (issue 32) against a 3D neo-Hookean FEM reference.

The model: :class:`~skin_sim_node.tools.hands.SharedSkin` of two flat punches of ``config/default.yaml`` (the
calibrated default), centres at ``x = -d/2`` and ``x = +d/2``, ``y = 0``, ramped together to one depth over 300 ticks at
1 kHz and held until its viscoelastic arms have relaxed (:func:`hold_ticks`, about 1.9 s): the FEM is quasi-static and
elastic, so the relaxed force is the one to compare. The force after the issue's 300-tick hold (the arms' force still
on it) is read from the same run and printed beside it. The single punch is one :func:`~skin_sim_node.tools.make_tool`
of the same config at ``x = +d/2``, the same ramp.

The reference: the 3D compressible neo-Hookean FEM of :mod:`.hyperelastic3d` (the egg-carton layered block of
:mod:`.fem`, its moduli read from the same config, mesh level :data:`~.references.THREE_D_LEVEL`), with the punch off
the block's centre (:class:`~.hyperelastic3d.PunchLayout`): the pair as a quarter model (symmetry planes ``x = 0``,
``y = 0``, the punch at ``x = d/2``), the single punch as the half model on the mirror of the same mesh, so the
interaction ``pair - single`` is of one discretisation. Solves are cached in ``docs/validation/hyper_cache``
(``3d-<hash>.npz``); ``--fresh`` solves again (about an hour here for all of them).

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
from tqdm import tqdm

from skin_sim_node.model import TissueConfig
from skin_sim_node.model.config import load_tissue_config
from skin_sim_node.tools import DOWN, ToolPose, make_tool
from skin_sim_node.tools.hands import SharedSkin

from . import cache
from .fem import FemSetup, _geometry_key, mesh_levels
from .hyperelastic import CACHE_DIR, layer_moduli_pa
from .hyperelastic3d import PunchLayout, Result3D, Setup3D, reference
from .references import THREE_D_LEVEL

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


def fem_base(cfg: TissueConfig) -> FemSetup:
    """The FEM mesh and tissue of the reference: level :data:`THREE_D_LEVEL`, moduli and geometry of ``cfg``."""
    return replace(mesh_levels(THREE_D_LEVEL, FemSetup()), moduli_pa=layer_moduli_pa(cfg), tissue=_geometry_key(cfg))


def fem_setup(cfg: TissueConfig, distance_m: float | None, partner: bool) -> Setup3D:
    """The neo-Hookean solve of a punch at ``x = distance_m / 2`` (``partner``: with its mirror at ``-distance_m / 2``);
    ``distance_m`` None: one punch centred on the block (the existing scenarios' layout, quarter model)."""
    layout = None if distance_m is None else PunchLayout(distance_m / 2, partner)
    return Setup3D(fem_base(cfg), MAX_DEPTH_M, N_STEPS, layout)


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


def rows(cfg: TissueConfig, fresh: bool = False, progress: bool = True, missing_ok: bool = False) -> list[Row] | None:
    """Every distance and depth: the FEM (cached) and the model. With ``missing_ok`` None when a solve is not cached."""
    setups = [(d, p) for d in DISTANCES_M for p in (True, False)]
    res = {}
    bar = tqdm(setups, desc="two-punch FEM (pair, single) per distance", disable=not progress)
    for d, p in bar:
        bar.set_postfix(distance_mm=f"{d * 1e3:g}", punches="pair" if p else "single")
        r = fem_solve(fem_setup(cfg, d, p), fresh, progress, missing_ok)
        if r is None:
            return None
        res[d, p] = r
    out = []
    for d in tqdm(DISTANCES_M, desc="two-punch model", disable=not progress, leave=False):
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
difference is the interaction. Mesh: level -2 of the linear FEM (3 elements over the punch radius, 20-node
serendipity hexes, 1 + 3 + 2 through the layers), the contact disk conforming
(`skin_sim_lab/validation/fem.py: build_offset_mesh`); the spacing of the punch band (0.83 mm) runs on to x = 0 for
d <= 10 mm, at 20 mm the 7.5 mm between the punch and x = 0 is graded (3 elements). The solves are cached in
`docs/validation/hyper_cache/3d-<hash>.npz`.

**Valid for.** Quasi-static indentation (no rate, no viscoelasticity: the model's force is read after its hold), two
equal rigid flat punches at equal depths, frictionless contact, the default layered tissue and moduli, depths to 2 mm.
The mesh is the coarse level of the existing 3D reference (about 13k DOFs a quarter, 25k-34k a half; the linear FEM at
this level is within 0.6 % of its finest level, docs/validation/convergence.md); the coarse band between the punches
limits how small an interaction the reference resolves (the absolute rule below 2 %).
"""


def findings(rs: list[Row], c: Checks) -> str:
    """What the numbers say: the sign and size of each interaction, and the surface profile behind them."""
    lines = ["## Findings", ""]
    for depth in DEPTHS_M:
        sel = [r for r in rs if r.depth_m == depth]
        fem = ", ".join(f"{r.distance_m * 1e3:g} mm {r.fem_fraction:+.1%}" for r in sel)
        mod = ", ".join(f"{r.distance_m * 1e3:g} mm {r.model_fraction:+.1%}" for r in sel)
        lines.append(f"- {depth * 1e3:g} mm deep, interaction / single: FEM {fem}; model {mod}.")
    single = max(abs(r.force_errors[1]) for r in rs)
    lines.append(f"- The model's single punch is within {single:.1%} of the FEM's at every position and depth.")
    heave = [r for r in PROFILE_RADII_M if c.fem_profile[r] < 0]
    if heave:
        lo = min(c.fem_profile.values())
        lines += [
            f"- The reference's surface beside one punch rises above its rest height at "
            f"{', '.join(f'{r * 1e3:g}' for r in heave)} mm (least u/depth {lo:+.3f}): the 5.3 mm of nearly incompressible "
            "tissue (nu = 0.48) bonded to a rigid base pushes the volume under the punch up around it. A second punch in "
            "that ring presses skin that stands higher, so the FEM's pair needs more force than its single punch there "
            "(positive interaction). The model's membranes on their foundations give a dimple that decays monotonically "
            "(never negative), so its interaction is negative at every distance: a miss in sign at the distances where "
            "the reference heaves, and in size where the disks overlap (4 mm).",
            "- Cause, as far as these numbers show: not the decay length alone (the model's dimple at 4 mm is "
            f"{c.model_profile[4e-3]:.3f} of the depth, the FEM's {c.fem_profile[4e-3]:.3f}) but the missing heave "
            "(volume conservation of the layer: a membrane on a Winkler foundation has no lateral flow), and at 4 mm "
            "the coupling through the dimple at the other punch's centre only (the FEM's punch feels the other's "
            "whole footprint: its disk reaches 1.5 mm from the other centre, inside the other disk).",
        ]
    return "\n".join(lines)


def markdown(rs: list[Row], c: Checks, command: str) -> str:
    """The page: the command, the table, the aims and verdicts, the checks and the method."""
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
            "## Checks",
            "",
            "Lateral boundary: the single punch centred on the block (quarter model, the existing mesh) against the "
            "single punch 10 mm off centre (the 20 mm pair's single, half model); the difference bounds the side's "
            "effect on the 20 mm rows together with the mesh change.",
            "",
            checks_text(c),
            "",
            findings(rs, c),
            "",
            METHOD,
        ]
    )


def main(argv=None) -> int:
    """``skin-sim two-punch``: print the table, write ``docs/validation/two_punch.md``; 1 when an aim fails."""
    ap = argparse.ArgumentParser(prog="skin-sim two-punch", description=__doc__.split("\n")[0])
    ap.add_argument("--fresh", action="store_true", help="solve the FEM again ignoring the caches (about an hour)")
    ap.add_argument("--out", default=str(OUT), help="folder of two_punch.md (under docs/: solves go to the tracked cache)")
    a = ap.parse_args(argv)
    out = Path(a.out)
    out.mkdir(parents=True, exist_ok=True)
    cache.WRITE_DOCS = out.resolve().is_relative_to(cache.DOCS)
    t0 = time.perf_counter()
    cfg = load_tissue_config(CONFIG)
    rs = rows(cfg, a.fresh)
    c = checks(cfg, a.fresh)
    command = "skin-sim two-punch" + "".join(f" {shlex.quote(x)}" for x in (argv if argv is not None else sys.argv[1:]))
    text = markdown(rs, c, command)
    (out / "two_punch.md").write_text(text)
    print(table(rs))
    print()
    print(aims_text())
    print()
    print(issue_table(rs))
    print()
    print(checks_text(c))
    print()
    print(findings(rs, c))
    ok = all(r.ok for r in rs)
    print(f"\noverall: {'PASS' if ok else 'FAIL'}  ({time.perf_counter() - t0:.0f} s; wrote {out / 'two_punch.md'})")
    return 0 if ok else 1
