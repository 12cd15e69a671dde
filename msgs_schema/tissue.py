"""The tissue parameter schema: every ``tissue.*`` parameter with default, unit, bounds and reason.

The single definition of every tissue parameter. The ROS node declares its parameters from
it, the YAML presets in ``config/`` use its names under ``ros__parameters`` (with the
``tissue.`` prefix), :func:`msgs_schema.parameters.check_tissue` validates values against it,
and :func:`skin_sim_node.model.config.build_config` builds the frozen config the model runs on.
Defaults are the ``default`` preset; their sources are in ``docs/model.md`` (section "Parameter
sources"). Imports nothing from the implementation.
"""

from __future__ import annotations

import math
from typing import Any

from .spec import ParamSpec

LAYER_NAMES = ("epidermis", "dermis", "fat")
"""The layers, top down: the one list (the contact message's entries, the snapshot's rows, the presets' keys)."""
INTERFACE_NAMES = ("epidermis_dermis", "dermis_fat")
"""The interfaces between consecutive layers, top down."""


def _f(
    name: str, default: float, unit: str, desc: str, *, min: float = 0.0, max: float | None = None, min_exclusive: bool = True
) -> ParamSpec[float]:
    """A float parameter, by default ``> 0``."""
    return ParamSpec(name, float, default, unit, desc, min=min, max=max, min_exclusive=min_exclusive)


def _i(name: str, default: int, desc: str, *, min: int = 1, max: int | None = None) -> ParamSpec[int]:
    """A count (unit ``1``), by default ``>= 1``."""
    return ParamSpec(name, int, default, "1", desc, min=min, max=max, min_exclusive=False)


def _b(name: str, default: bool, desc: str) -> ParamSpec[bool]:
    """A switch."""
    return ParamSpec(name, bool, default, "-", desc)


def _s(name: str, default: str, desc: str, choices: tuple[str, ...]) -> ParamSpec[str]:
    """One of ``choices``."""
    return ParamSpec(name, str, default, "-", desc, choices=choices)


# Level of detail ("no more than a scene needs", issue 7); docs/performance.md measures each lever.
LOD_TOLERANCE_M = 10e-6
"""Displacement tolerance (m). Stated choice: 1 % of the 1 mm height-map cell, invisible in the
display, and about the smallest skin indentation a fingertip detects (of the order of 10 um)."""


def _lod_specs() -> list[ParamSpec]:
    return [
        _f(
            "lod.tolerance_m",
            LOD_TOLERANCE_M,
            "m",
            "displacement tolerance: adaptive mode count, settled layers, idle and display change detection "
            "(10 um: 1 % of a 1 mm height-map cell)",
        ),
        _b(
            "lod.adaptive_modes",
            True,
            "choose each driven layer's modes per axis (1..59 odd, against a 60 x 60 reference) from its compression "
            "and lod.tolerance_m; off: the fixed modes.m x modes.n",
        ),
        _b(
            "lod.affected_layers",
            True,
            "compute only layers that are driven or still moving: a free layer whose displacement bound falls "
            "below lod.tolerance_m is set to rest and skipped",
        ),
        _b("lod.patch_only", True, "grid builds touch only the cells of the deformation patches, not the whole sheet"),
        _b("lod.idle", True, "no kernel call while the tool is off the tissue and every layer has settled"),
    ]


# Default layer values (the `default` preset). Sources: docs/model.md, "Parameter sources"; the fitted constants and the
# formulas that give these literals: skin_sim_node/model/calibration.py (tests/test_model.py checks them bit for bit).
TOOL_RADIUS_M = 2.5e-3
"""Default tool tip radius (``tool.radius_m``)."""
FOUNDATION_LENGTH_M = 1.63e-3
"""Default decay length of the membranes' foundation (``patch.foundation_length_m``; fitted by ``skin-sim calibrate``,
docs/validation.md section 0b)."""
STIFFENING_EXPONENT = 1.297
"""Default ``n`` of the layered form's compression law (``layers.*.stiffening``; fitted, docs/validation.md "Stiffness
the hand feels")."""
LAYER_PARAMETER_DEFAULTS: dict[str, dict[str, float]] = {
    "epidermis": {
        "thickness_m": 75e-6,
        "stiffness_n_per_m": 392699.0816987242,
        "damping_n_s_per_m": 0.0252911111254665,
        "area_m2": 1.9634954084936207e-05,
        "density_kg_per_m3": 1150.0,
        "tension_n_per_m": 0.41745000000000004,
    },
    "dermis": {
        "thickness_m": 1.2e-3,
        "stiffness_n_per_m": 822.7045761588271,
        "damping_n_s_per_m": 0.3926939828315912,
        "area_m2": 1.9634954084936207e-05,
        "density_kg_per_m3": 1116.0,
        "tension_n_per_m": 6.481728,
    },
    "fat": {
        "thickness_m": 4.0e-3,
        "stiffness_n_per_m": 553.3419676707776,
        "damping_n_s_per_m": 0.46591624795879155,
        "area_m2": 1.9634954084936207e-05,
        "density_kg_per_m3": 971.0,
        "tension_n_per_m": 3.14604,
    },
}
"""Per layer (in :data:`LAYER_NAMES` order) the literal defaults of ``layers.<name>.*``: the layered form's spring at the
tool's area (the column ``E A / h`` times the fitted load spreading), the damper that critically damps the fundamental
release mode, the tool's area, the density and the membrane tension ``rho h c^2`` (eq 1) of the layer's Young's modulus,
density and elastography wave speed (:data:`skin_sim_node.model.calibration.LAYER_SOURCES`)."""
FRICTION_COEFFICIENT = 0.5
"""Dry skin: friction coefficients above 0.2 and typically around 0.5, pressure-independent (Derler and Gerhardt
2012, Tribol Lett 45:1, review of the published measurements); moist skin is higher (> 1)."""
PUNCH_SMALL_STRAIN_STIFFNESS_N_PER_M = 326.3
"""Small-strain normal stiffness of the default 2.5 mm flat punch on the default skin (N/m): the compressible
neo-Hookean reference the layered law is fitted to (:data:`STIFFENING_EXPONENT`; docs/validation.md)."""
TANGENTIAL_STIFFNESS_N_PER_M = 223.3  # the literal of skin_sim_node.model.calibration.tangential_stiffness_n_per_m()
"""Tangential (presliding) stiffness of the skin under the tool (N/m), 223.3: contact mechanics on the model's own
calibrated half-space. A rigid circular contact of radius ``a`` that sticks moves ``Q (2 - nu) / (8 G a)`` under a
tangential force ``Q`` (Mindlin 1949, J Appl Mech 16:259; Johnson 1985, Contact Mechanics, sec. 7.1), and
``P (1 - nu^2) / (2 E a)`` under a normal one (Sneddon 1965), so ``k_t / k_n = 2 (1 - nu) / (2 - nu)`` (0.684 at
``nu = 0.48``) times the punch's normal stiffness :data:`PUNCH_SMALL_STRAIN_STIFFNESS_N_PER_M`. A constant (the
sphere takes it too, a stated choice): a stiffness that changed with depth while the skin is stretched would store
energy without work (docs/model.md, "Friction"). The presliding distance it gives, ``mu F_n / k_t`` (1.8 mm at the
1.5 mm press), lies in the contact-mechanics band ``[1, 1.5] mu F_n / k_t`` (rigid stick to Cattaneo-Mindlin partial
slip, Johnson 1985 sec. 7.2); in vivo the stick-to-slip transition of skin is gradual, slip spreading from the edge of
the contact inward (Delhaye et al. 2014, J R Soc Interface 11:20140698): a stated engineering choice, not a fit."""
PRONY_DEFAULTS = {"g1": 0.75, "tau1_s": 0.007, "g2": 0.75, "tau2_s": 0.28}
"""The layered form's default reduced relaxation ``G(t) = 1 + g1 exp(-t/tau1) + g2 exp(-t/tau2)`` (relative to the
equilibrium law), the same for every layer (surface data cannot separate the layers). ``G(0)/G(inf) = 2.5``: the
in-vivo rate effect, peak force 2-2.75 x quasi-static (Spartacus et al. 2021, PLOS ONE 16:e0261008), and fingerpad
skin relaxing about twice as fast as it creeps (Wang & Hayward 2007), which for a standard linear solid means
``G(0)/G(inf)`` about 2. Time constants: in vivo, skin answers a pressure step with about 10 ms and 0.1-1 s
(PMID 23604906; those are creep/recovery times, which the model's recovery reproduces with these relaxation
times). The split between g1 and g2 is not fixed by the data (a stated choice: equal). Sources, quotes and the
fit targets: docs/data/viscoelastic/; the model's figures: ``skin-sim visco``."""


def _visco_specs() -> list[ParamSpec]:
    d = PRONY_DEFAULTS
    return [
        _f(
            "viscoelastic.g1",
            d["g1"],
            "1",
            "layered form: fast Prony term g1 of every layer's reduced relaxation G(t) = 1 + g1 exp(-t/tau1) + "
            "g2 exp(-t/tau2) (quasi-linear viscoelasticity, relative to the equilibrium law; 0: none)",
            max=20.0,
            min_exclusive=False,
        ),
        _f("viscoelastic.tau1_s", d["tau1_s"], "s", "layered form: time constant of the fast Prony term", max=100.0),
        _f(
            "viscoelastic.g2",
            d["g2"],
            "1",
            "layered form: slow Prony term g2 of the reduced relaxation (0: none)",
            max=20.0,
            min_exclusive=False,
        ),
        _f("viscoelastic.tau2_s", d["tau2_s"], "s", "layered form: time constant of the slow Prony term", max=100.0),
    ]


ANISOTROPY_RATIO = 1.79
"""Default ``anisotropy.ratio``: a layer's in-plane coefficient along the tension (Langer) lines over that across
them. Lakhani et al. 2021 (Front Bioeng Biotechnol 9:749492, doi:10.3389/fbioe.2021.749492, abstract): human forearm
skin in vivo (12 forearms, full-field suction), linear moduli 5.52 +- 1.13 MPa along, 3.09 +- 0.47 MPa across
(5.52 / 3.09 = 1.79; the toe moduli 0.59 / 0.52 = 1.13 bound it below); the stiff direction follows Kraissl's lines.
The membrane coefficient of this model is ``rho_A c^2 = mu h`` (elastography's shear wave speed; docs/model.md,
"Tension lines"), the layer's in-plane shear stiffness, so its anisotropy is the modulus's. docs/data/tension_lines.yaml
holds the numbers and their provenance."""
ANISOTROPY_ANGLE_RAD = 0.0
"""Default ``anisotropy.angle_rad``: the lines along the sheet's x axis (stated choice: the sheet's x is laid along
the lines; a person's map of lines varies, so the direction is a parameter)."""


def _layer_specs() -> list[ParamSpec]:
    specs = []
    for name, d in LAYER_PARAMETER_DEFAULTS.items():
        p = f"layers.{name}."
        specs += [
            _f(p + "thickness_m", d["thickness_m"], "m", f"mean {name} thickness"),
            _f(
                p + "stiffness_n_per_m",
                d["stiffness_n_per_m"],
                "N/m",
                f"{name} Kelvin-Voigt spring k (eq 6); layered form: small-strain stiffness at the mean thickness "
                "(column E A / h times the load-spreading factor fitted to the neo-Hookean reference)",
            ),
            _f(
                p + "damping_n_s_per_m",
                d["damping_n_s_per_m"],
                "N*s/m",
                f"{name} Kelvin-Voigt damper b (eq 6)",
                min_exclusive=False,
            ),
            _f(p + "area_m2", d["area_m2"], "m^2", f"{name} loaded area A (eq 6; paper form)"),
            _f(
                p + "density_kg_per_m3",
                d["density_kg_per_m3"],
                "kg/m^3",
                f"{name} volumetric density; areal rho = density*thickness (eq 1)",
            ),
            _f(p + "tension_n_per_m", d["tension_n_per_m"], "N/m", f"{name} membrane tension T (eq 1)"),
            _f(
                p + "stiffening",
                STIFFENING_EXPONENT,
                "1",
                f"{name} exponent n of the layered form's law f = k h ((1 - c/h)^-n - 1) / n (0: -k h ln(1 - c/h))",
                max=10.0,
                min_exclusive=False,
            ),
        ]
    return specs


def _interface_specs() -> list[ParamSpec]:
    # Egg-carton interfaces (section II.C). Amplitudes and wavelengths: docs/model.md.
    defaults = {"epidermis_dermis": (40e-6, 0.2e-3), "dermis_fat": (0.5e-3, 5.0e-3)}
    specs = []
    for name, (amp, wl) in defaults.items():
        p = f"interfaces.{name}."
        specs += [
            _f(p + "amplitude_m", amp, "m", f"{name} egg-carton amplitude", min_exclusive=False),
            _f(p + "wavelength_x_m", wl, "m", f"{name} egg-carton wavelength along x"),
            _f(p + "wavelength_y_m", wl, "m", f"{name} egg-carton wavelength along y"),
        ]
    return specs


def _general_specs() -> list[ParamSpec]:
    return [
        _s(
            "form",
            "layered",
            "force and engagement model: 'layered' (all layers in series from first contact, strain-stiffening, "
            "series Kelvin-Voigt chain, friction) or 'paper' (Fig 3 engagement, common velocity, eq 9)",
            ("layered", "paper"),
        ),
        _f("sheet.size_x_m", 0.12, "m", "tissue sheet extent along x, centred on the frame origin"),
        _f("sheet.size_y_m", 0.12, "m", "tissue sheet extent along y, centred on the frame origin"),
        _f("patch.size_x_m", 0.06, "m", "deformation patch side along x (paper: 60 mm)"),
        _f("patch.size_y_m", 0.06, "m", "deformation patch side along y (paper: 60 mm)"),
        _f(
            "patch.foundation_length_m",
            FOUNDATION_LENGTH_M,
            "m",
            "decay length l of the membranes' elastic foundation (k_A = T / l^2): how far the dent spreads from the "
            "tool; fitted to the large-deformation reference's surface fields (skin-sim calibrate); 0: the paper's "
            "bare membrane",
            max=0.06,
            min_exclusive=False,
        ),
        _i("grid.nx", 120, "output height-map cells along x over the sheet", min=2, max=1024),
        _i("grid.ny", 120, "output height-map cells along y over the sheet", min=2, max=1024),
        _i(
            "modes.m",
            15,
            "modal terms along x (M in eq 2); <= 61: with jittery tick intervals the propagator "
            "is recomputed every tick, ~51 us at 61 x 61 (2026-12-05, quiet)",
            max=61,
        ),
        _i("modes.n", 15, "modal terms along y (N in eq 2); <= 61, as modes.m", max=61),
        _f("tool.radius_m", TOOL_RADIUS_M, "m", "tool tip radius; the disk load of the indentation shape"),
        _s(
            "tool.shape",
            "flat",
            "tool tip: 'flat' punch of tool.radius_m, 'sphere' of that radius (contact radius sqrt(R d); layered form), or "
            "'needle' of needle.outer_diameter_m along the pose's orientation (punctures the layers; layered form)",
            ("flat", "sphere", "needle"),
        ),
        _f(
            "contact.friction_coefficient",
            FRICTION_COEFFICIENT,
            "1",
            "Coulomb friction coefficient of the tool on dry skin (layered form; Derler and Gerhardt 2012: typically 0.5)",
            max=5.0,
            min_exclusive=False,
        ),
        _f(
            "anisotropy.ratio",
            ANISOTROPY_RATIO,
            "1",
            "tension (Langer) lines: each layer's membrane coefficient and in-plane modulus along the lines over "
            "across them (T_along = T sqrt(ratio), T_across = T / sqrt(ratio), geometric mean T; the normal force "
            "sees the geometric mean only). Forearm 1.79 (Lakhani 2021, linear moduli 5.52 / 3.09 MPa); 1: isotropic",
            min=0.1,
            max=10.0,
        ),
        _f(
            "anisotropy.angle_rad",
            ANISOTROPY_ANGLE_RAD,
            "rad",
            "direction of the tension lines from the sheet's x axis; the modal patch's first side (patch.size_x_m) "
            "is laid along them",
            min=-math.pi / 2,
            max=math.pi / 2,
            min_exclusive=False,
        ),
        _f(
            "contact.tangential_stiffness_n_per_m",
            TANGENTIAL_STIFFNESS_N_PER_M,
            "N/m",
            "presliding friction: the skin under the tool stretches with it at this stiffness until the force reaches "
            "mu F_n, then slips (Hayward-Armstrong adhesion point; layered form, flat and sphere). Default 2(1-nu)/(2-nu) "
            "x the punch's 326.3 N/m normal stiffness (Mindlin, Johnson 1985 sec. 7.1); 0: no friction",
            max=1e5,
            min_exclusive=False,
        ),
    ]


NEEDLE_OUTER_DIAMETER_M = 0.819e-3
"""Default ``needle.outer_diameter_m``: a 21 G hypodermic, nominal outer diameter of normal-wall tubing (ISO
9626:2016, table 1): the common gauge of venepuncture and intramuscular injection (stated choice)."""


def _needle_specs() -> list[ParamSpec]:
    return [
        _f(
            "needle.outer_diameter_m",
            NEEDLE_OUTER_DIAMETER_M,
            "m",
            "needle outer diameter (tool.shape 'needle'): 18 G 1.270e-3, 21 G 0.819e-3, 25 G 0.514e-3, 27 G 0.413e-3, "
            "30 G 0.311e-3 (ISO 9626); the puncture thresholds, cutting and shaft friction scale with it",
            min=0.1e-3,
            max=2.0e-3,
            min_exclusive=False,
        ),
        _b(
            "needle.lubricated",
            True,
            "siliconised needle (commercial hypodermics are); false: a dry needle, 2 x the puncture, cutting and "
            "friction forces (Schneider 1978: dry 1.5-3 x)",
        ),
    ]


TISSUE_PARAMETERS: tuple[ParamSpec, ...] = tuple(
    _general_specs() + _layer_specs() + _visco_specs() + _interface_specs() + _lod_specs() + _needle_specs()
)
"""Every tissue parameter, named without the ``tissue.`` prefix the node declares them with
(:data:`msgs_schema.parameters.SPEC_BY_NAME` looks them up)."""


def tissue_defaults() -> dict[str, Any]:
    """Every tissue parameter at its default.

    Returns
    -------
    dict
        Dotted name (no ``tissue.`` prefix) -> default, in schema order.
    """
    return {s.name: s.default for s in TISSUE_PARAMETERS}
