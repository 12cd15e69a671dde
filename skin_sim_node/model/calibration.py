"""The fitted constants and formulas behind the tissue's defaults (moved out of the contract, issue 28).

The contract (:mod:`msgs_schema.tissue`) holds each parameter's name, unit, bounds and literal default; this module holds
where those literals come from - the layers' measured moduli, densities and wave speeds (:data:`LAYER_SOURCES`), the
constants fitted to the neo-Hookean references (:data:`LOAD_SPREADING`, :data:`WALL_STRAIN`, the bottom's
:data:`BONE_STRAIN` and :data:`BONE_STIFFNESS`) and the formulas (:func:`layered_stiffness_n_per_m`,
:func:`critical_damping_n_s_per_m`, ...) - and what the model reads back from a live configuration
(:func:`youngs_moduli_pa`). tests/test_model.py checks that the contract's literals are these formulas' values, bit for
bit. Sources: docs/model.md, "Parameter sources"; docs/validation.md.
"""

from __future__ import annotations

import math
from typing import TYPE_CHECKING

from msgs_schema.tissue import LAYER_NAMES, LAYER_PARAMETER_DEFAULTS, STIFFENING_EXPONENT, TOOL_RADIUS_M

if TYPE_CHECKING:
    from .config import TissueConfig

CALIBRATED_TOOL_RADIUS_M = TOOL_RADIUS_M
"""The flat punch's radius the layered law was fitted with (m): the needle's tent scales its dimple from it."""
TOOL_AREA_M2 = math.pi * CALIBRATED_TOOL_RADIUS_M**2
"""The calibrated punch's area (m^2): the layers' default loaded area ``A`` (eq 6)."""
LAYER_SOURCES = {
    # thickness_m, youngs_modulus_pa (quasi-static compression/indentation modulus), density_kg_per_m3,
    # shear_wave_speed_m_per_s (elastography: the membrane's dynamics, eq 1)
    "epidermis": (75e-6, 1.5e6, 1150.0, 2.2),
    "dermis": (1.2e-3, 20e3, 1116.0, 2.2),
    "fat": (4.0e-3, 26.1e3, 971.0, 0.9),
}
"""Per layer (in :data:`~msgs_schema.tissue.LAYER_NAMES` order): thickness (m), Young's modulus (Pa), density
(kg/m^3) and shear wave speed (m/s) behind the ``layers.*`` defaults."""
POISSON_RATIO = 0.48
"""Poisson ratio of every layer (nearly incompressible soft tissue): the Sneddon punch stiffness and the FEM
references."""
_PATCH_M = 0.06
FITTED_STIFFENING_EXPONENT = STIFFENING_EXPONENT
"""``n`` of the compression law ``phi = ((1 - eps)^-n - 1) / n`` for every layer (the contract's literal default of
``layers.*.stiffening``): fitted, with :data:`LOAD_SPREADING` and :data:`WALL_STRAIN`, to the force *and* its slope
``dF/dd`` of the axisymmetric compressible neo-Hookean flat-punch reference (mesh level 3, default moduli, 0.1-3 mm) and
its small-strain (linear-law) stiffness 326.3 N/m: ``python -m skin_sim_lab.validation.fit_law --wall`` prints
n = 1.2971 (issue 20; docs/validation.md, "Stiffness the hand feels"). The fit is of the chain's equilibrium elastic law
(dampers relaxed)."""
LOAD_SPREADING = {"epidermis": 1.0, "dermis": 2.514, "fat": 4.319}
"""Layered form: each layer's spring is ``s_i E_i A / h_i``, the column stiffness times this factor. The column
``E A / h`` ignores that the material round the punch confines the column and carries load sideways. Dermis and fat
factors: fitted with :data:`FITTED_STIFFENING_EXPONENT` and :data:`WALL_STRAIN` to the flat-punch neo-Hookean
reference's force and slope (``python -m skin_sim_lab.validation.fit_law --wall``: 2.514 and 4.319; small-strain
stiffness 327.6 N/m against the reference's 326.3, force within 2.0 % and ``dF/dd`` within 4.2 % over 0.1-3 mm, no layer
strained beyond 0.9 at 3 mm). Both lie between a free column (1) and a laterally confined one (the constrained modulus
``(1 - nu) / ((1 + nu)(1 - 2 nu)) E = 8.8 E`` at ``nu = 0.48``), as a partly confined layer must. Force data fix the
chain's compliance better than its split between the layers. The epidermis is not fitted (0.1 % of the chain's
compliance; docs/validation.md). The previous fit (2.234, 5.867 with n = 0.119 and wall 0.99, to the force alone of the
3D references) gave a small-strain stiffness 13 % high and ``dF/dd`` -18 % to +49 % off (issue 20)."""
WALL_STRAIN = 0.343
"""Layer strain beyond which the compression law continues along its tangent (the law's slope saturates at
``(1 - 0.343)^-2.297 = 2.6`` x the small-strain stiffness). Fitted with :data:`FITTED_STIFFENING_EXPONENT` (same
command): the neo-Hookean punch's stiffness rises from 326 N/m to ~800 N/m by 2 mm and then levels off (the compressible
material flows out from under the punch), which a law that stiffens without bound up to the bottom cannot follow
(best fit with the wall at 0.99: ``dF/dd`` -19 % to +27 %). Trade-off, stated: the bottom is no longer a steep wall -
below the 5.275 mm stack the force keeps rising at about 0.9 N/mm, not 63 N/mm; a bottom wall now needs its own term in
the law (issue 20 notes). The chain's Newton solve stays well conditioned (the law is linear past the wall)."""
BONE_STRAIN = 0.97
"""Layer strain at which the bottom (fascia on muscle and bone) starts to stop the tool: the compression law gains
``K_bone (eps - 0.97)^2 / 2`` (:data:`BONE_STIFFNESS`) up to full compression and continues along its tangent past
it. 0.97: the default layers reach it only at the stack's bottom (the fitted law has the dermis at strain 0.90 at
3 mm and 0.94 at 4.5 mm; the wall engages between 5.0 and 5.275 mm), so the fitted force and ``dF/dd`` over
0.05-3 mm are unchanged."""
BONE_STIFFNESS = 10000.0
"""``K_bone`` (dimensionless, in units of the layer's small-strain stiffness): the wall's slope grows as
``K_bone (eps - 0.97)``, so at full compression a layer is 300 x its small-strain stiffness and the force rises at
about 95 N/mm below the stack (``bench-model --physics`` prints the curve; the 0.99-wall law gave 63 N/mm). A
steep, finite, C1 wall, never a clamp (stated choice)."""
PAPER_MODULI_PA = {"epidermis": 1.5e6, "dermis": 20e3, "fat": 2.5e3}
"""Young's moduli behind the ``paper`` preset's Sneddon ``k`` (unchanged from before the layered form)."""


def critical_damping_n_s_per_m(density_kg_per_m3: float, thickness_m: float, wave_speed_m_per_s: float) -> float:
    """``b`` that critically damps a layer's fundamental release mode: ``b = 2 m11 lambda_11``.

    ``m11 = rho_A a b / 4`` is the (1,1) modal mass of the default 60 mm patch and
    ``lambda_11 = c pi sqrt(2) / a`` (eq 3); see ``gamma`` in :mod:`.modal`.
    """
    m11 = density_kg_per_m3 * thickness_m * _PATCH_M**2 / 4
    return 2 * m11 * wave_speed_m_per_s * math.pi * math.sqrt(2) / _PATCH_M


def flat_punch_stiffness_n_per_m(youngs_modulus_pa: float, radius_m: float) -> float:
    """Indentation stiffness ``k = 2 E r / (1 - nu^2)`` of a rigid flat punch on a half-space.

    Sneddon (1965); the ``paper`` preset's per-layer ``k`` (its values before the layered form).
    """
    return 2.0 * youngs_modulus_pa * radius_m / (1.0 - POISSON_RATIO**2)


def column_stiffness_n_per_m(youngs_modulus_pa: float, thickness_m: float, area_m2: float = TOOL_AREA_M2) -> float:
    """Small-strain stiffness ``k = E A / h`` of the free layer column under the tool."""
    return youngs_modulus_pa * area_m2 / thickness_m


def layered_stiffness_n_per_m(name: str, youngs_modulus_pa: float, thickness_m: float, area_m2: float = TOOL_AREA_M2) -> float:
    """The layered form's small-strain spring of layer ``name``: the column stiffness times :data:`LOAD_SPREADING`
    (the law is ``f = k h phi(c / h)``)."""
    return LOAD_SPREADING[name] * column_stiffness_n_per_m(youngs_modulus_pa, thickness_m, area_m2)


def layer_parameter_defaults() -> dict[str, dict[str, float]]:
    """The ``layers.<name>.*`` defaults these sources and formulas give (the contract's literals,
    :data:`msgs_schema.tissue.LAYER_PARAMETER_DEFAULTS`)."""
    out = {}
    for name, (h, e, rho, c) in LAYER_SOURCES.items():
        out[name] = {
            "thickness_m": h,
            "stiffness_n_per_m": layered_stiffness_n_per_m(name, e, h),
            "damping_n_s_per_m": critical_damping_n_s_per_m(rho, h, c),
            "area_m2": TOOL_AREA_M2,
            "density_kg_per_m3": rho,
            "tension_n_per_m": rho * h * c**2,  # T = rho_areal c^2 (eq 1) with c from elastography
        }
    return out


def youngs_moduli_pa(cfg: TissueConfig) -> list[float]:
    """Each layer's Young's modulus (Pa) in a live configuration: the layered spring inverted, ``E_i = k_i h_i / (s_i
    A_i)`` (:func:`layered_stiffness_n_per_m`).

    Written relative to the calibrated default, ``E_i = E_i,0 (k_i h_i) / (k_i,0 h_i,0) A_i,0 / A_i`` (the same value,
    since ``s_i = k_i,0 h_i,0 / (E_i,0 A_i,0)``), so that a layer at its defaults gets its source modulus exactly (not an
    ulp off it) and a live change of ``k``, ``h`` or ``A`` moves it as the law says.

    Parameters
    ----------
    cfg : TissueConfig

    Returns
    -------
    list of float
        In :data:`~msgs_schema.tissue.LAYER_NAMES` order.
    """
    out = []
    for name, la in zip(LAYER_NAMES, cfg.layers):
        d = LAYER_PARAMETER_DEFAULTS[name]
        e0 = LAYER_SOURCES[name][1]
        k0h0 = d["stiffness_n_per_m"] * d["thickness_m"]
        out.append(e0 * ((la.stiffness_n_per_m * la.thickness_m) / k0h0) * (d["area_m2"] / la.area_m2))
    return out


def layer_moduli_pa(cfg: TissueConfig, poisson: float = POISSON_RATIO) -> tuple[float, ...]:
    """Young's modulus per layer, read from the config (both forms).

    ``layers.<name>.youngs_modulus_pa`` when the schema has it; otherwise inverted from the layer
    spring, by the rule the form's springs are built with (``msgs_schema.tissue``):

    - ``layered``: the spread column, ``k = s E A / h`` (:func:`skin_sim_node.model.calibration.layered_stiffness_n_per_m`,
      ``s`` = :data:`skin_sim_node.model.calibration.LOAD_SPREADING`), so ``E = k h / (s A)`` with the layer's ``thickness_m``
      and ``area_m2``;
    - ``paper``: Sneddon's flat punch on a half-space, ``k = 2 E r0 / (1 - nu^2)``
      (:func:`skin_sim_node.model.calibration.flat_punch_stiffness_n_per_m`), so ``E = k (1 - nu^2) / (2 r0)``.

    Either way the preset's moduli come back, and a changed spring changes the reference's modulus.
    """
    flat = cfg.as_flat()
    out = []
    for la in cfg.layers:
        n = la.name
        e = flat.get(f"layers.{n}.youngs_modulus_pa")
        if e is None and cfg.form == "layered":
            e = la.stiffness_n_per_m * la.thickness_m / (la.area_m2 * LOAD_SPREADING.get(n, 1.0))
        elif e is None:
            e = la.stiffness_n_per_m * (1 - poisson**2) / (2 * cfg.tool_radius_m)
        out.append(float(f"{e:.12g}"))  # round-off free, so cache keys are stable
    return tuple(out)


def tangential_stiffness_n_per_m() -> float:
    """The presliding stiffness of the skin under the default punch (N/m), the contract's
    ``contact.tangential_stiffness_n_per_m`` default (:data:`msgs_schema.tissue.TANGENTIAL_STIFFNESS_N_PER_M`, its
    sources): ``k_t = 2 (1 - nu) / (2 - nu) k_n`` (Mindlin 1949 tangential, Sneddon 1965 normal compliance of a rigid
    circular contact on a half-space) with the fitted punch's small-strain ``k_n``, rounded to 0.1 N/m."""
    from msgs_schema.tissue import PUNCH_SMALL_STRAIN_STIFFNESS_N_PER_M

    return round(2.0 * (1.0 - POISSON_RATIO) / (2.0 - POISSON_RATIO) * PUNCH_SMALL_STRAIN_STIFFNESS_N_PER_M, 1)
