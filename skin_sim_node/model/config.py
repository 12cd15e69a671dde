"""Tissue configuration: one parameter schema, a frozen config, validation and YAML I/O.

The schema (:data:`TISSUE_PARAMETERS`) is the single definition of every tissue
parameter: dotted name, type, default, unit, bounds and description. The ROS node
declares its parameters from it, the YAML presets in ``config/`` use its names
under ``ros__parameters``, and :func:`config_from_flat` builds the frozen
:class:`TissueConfig` the model runs on. Defaults are the ``default`` preset;
their sources are in ``docs/model.md`` (section "Parameter sources").
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np
import yaml

LAYER_NAMES = ("epidermis", "dermis", "fat")
INTERFACE_NAMES = ("epidermis_dermis", "dermis_fat")
NODE_NAME = "skin_sim_node"


class ConfigError(ValueError):
    """A tissue configuration that the model cannot run on; the message says why."""


@dataclass(frozen=True)
class ParamSpec:
    """One parameter: dotted name, Python type, default, unit, bounds, description."""

    name: str
    type: type
    default: Any
    unit: str
    description: str
    min: float | None = None
    max: float | None = None
    min_exclusive: bool = True

    def check(self, value: Any) -> Any:
        """Return ``value`` coerced to this spec's type, or raise :class:`ConfigError`."""
        if self.type is bool:
            if not isinstance(value, (bool, np.bool_)):
                raise ConfigError(f"{self.name}: expected true/false, got {value!r}")
            return bool(value)
        if self.type is int:
            if isinstance(value, bool) or not isinstance(value, (int, np.integer)):
                if isinstance(value, float) and value.is_integer():
                    value = int(value)
                else:
                    raise ConfigError(f"{self.name}: expected an integer, got {value!r}")
            value = int(value)
        elif self.type is float:
            if isinstance(value, bool) or not isinstance(value, (int, float, np.number)):
                raise ConfigError(f"{self.name}: expected a number, got {value!r}")
            value = float(value)
            if not math.isfinite(value):
                raise ConfigError(f"{self.name}: must be finite, got {value!r}")
        if self.min is not None:
            bad = value <= self.min if self.min_exclusive else value < self.min
            if bad:
                op = ">" if self.min_exclusive else ">="
                raise ConfigError(f"{self.name} = {value!r} {self.unit}: must be {op} {self.min}")
        if self.max is not None and value > self.max:
            raise ConfigError(f"{self.name} = {value!r} {self.unit}: must be <= {self.max}")
        return value


def _f(name, default, unit, desc, lo=0.0, hi=None, lo_excl=True):
    return ParamSpec(name, float, default, unit, desc, lo, hi, lo_excl)


def _i(name, default, desc, lo=1, hi=None):
    return ParamSpec(name, int, default, "1", desc, lo, hi, False)


def _b(name, default, desc):
    return ParamSpec(name, bool, default, "-", desc)


# Level of detail ("no more than a scene needs", issue 7); docs/performance.md measures each lever.
LOD_TOLERANCE_M = 10e-6
"""Displacement tolerance (m). Stated choice: 1 % of the 1 mm height-map cell, invisible in the
display, and about the smallest skin indentation a fingertip detects (of the order of 10 um)."""


def _lod_specs() -> list[ParamSpec]:
    return [
        _f(
            "lod.tolerance_m", LOD_TOLERANCE_M, "m",
            "displacement tolerance: adaptive mode count, settled layers, idle and display change detection "
            "(10 um: 1 % of a 1 mm height-map cell)",
        ),
        _b(
            "lod.adaptive_modes", True,
            "choose each driven layer's modes per axis (1..59 odd, against a 60 x 60 reference) from its compression "
            "and lod.tolerance_m; off: the fixed modes.m x modes.n",
        ),
        _b(
            "lod.affected_layers", True,
            "compute only layers that are driven or still moving: a free layer whose displacement bound falls "
            "below lod.tolerance_m is set to rest and skipped",
        ),
        _b("lod.patch_only", True, "grid builds touch only the cells of the deformation patches, not the whole sheet"),
        _b("lod.idle", True, "no kernel call while the tool is off the tissue and every layer has settled"),
    ]  # fmt: skip


# Default layer values (the `default` preset). Sources: docs/model.md, "Parameter sources".
_TOOL_RADIUS_M = 2.5e-3
_TOOL_AREA_M2 = math.pi * _TOOL_RADIUS_M**2
_LAYER_DEFAULTS = {
    # thickness_m, youngs_modulus_pa, density_kg_per_m3, shear_wave_speed_m_per_s
    "epidermis": (75e-6, 1.5e6, 1150.0, 2.2),
    "dermis": (1.2e-3, 20e3, 1116.0, 2.2),
    "fat": (4.0e-3, 2.5e3, 971.0, 0.9),
}
_POISSON = 0.48
_PATCH_M = 0.06


def critical_damping_n_s_per_m(density_kg_per_m3: float, thickness_m: float, wave_speed_m_per_s: float) -> float:
    """``b`` that critically damps a layer's fundamental release mode: ``b = 2 m11 lambda_11``.

    ``m11 = rho_A a b / 4`` is the (1,1) modal mass of the default 60 mm patch and
    ``lambda_11 = c pi sqrt(2) / a`` (eq 3); see ``gamma`` in :mod:`.modal`.
    """
    m11 = density_kg_per_m3 * thickness_m * _PATCH_M**2 / 4
    return 2 * m11 * wave_speed_m_per_s * math.pi * math.sqrt(2) / _PATCH_M


def flat_punch_stiffness_n_per_m(youngs_modulus_pa: float, radius_m: float) -> float:
    """Indentation stiffness ``k = 2 E r / (1 - nu^2)`` of a rigid flat punch on a half-space.

    Sneddon (1965); used for the default per-layer ``k`` so that ``k`` depends on the
    layer's material and the tool, not on the paper's unstated spring constants.
    """
    return 2.0 * youngs_modulus_pa * radius_m / (1.0 - _POISSON**2)


def _layer_specs() -> list[ParamSpec]:
    specs = []
    for name, (h, e, rho, c) in _LAYER_DEFAULTS.items():
        k = flat_punch_stiffness_n_per_m(e, _TOOL_RADIUS_M)
        damping = critical_damping_n_s_per_m(rho, h, c)
        tension = rho * h * c**2  # T = rho_areal c^2 (eq 1) with c from elastography
        p = f"layers.{name}."
        specs += [
            _f(p + "thickness_m", h, "m", f"mean {name} thickness"),
            _f(p + "stiffness_n_per_m", k, "N/m", f"{name} Kelvin-Voigt spring k (eq 6)"),
            _f(p + "damping_n_s_per_m", damping, "N*s/m", f"{name} Kelvin-Voigt damper b (eq 6)", 0.0, None, False),
            _f(p + "area_m2", _TOOL_AREA_M2, "m^2", f"{name} loaded area A (eq 6)"),
            _f(
                p + "density_kg_per_m3",
                rho,
                "kg/m^3",
                f"{name} volumetric density; areal rho = density*thickness (eq 1)",
            ),
            _f(p + "tension_n_per_m", tension, "N/m", f"{name} membrane tension T (eq 1)"),
        ]
    return specs


def _interface_specs() -> list[ParamSpec]:
    # Egg-carton interfaces (section II.C). Amplitudes and wavelengths: docs/model.md.
    defaults = {"epidermis_dermis": (40e-6, 0.2e-3), "dermis_fat": (0.5e-3, 5.0e-3)}
    specs = []
    for name, (amp, wl) in defaults.items():
        p = f"interfaces.{name}."
        specs += [
            _f(p + "amplitude_m", amp, "m", f"{name} egg-carton amplitude", 0.0, None, False),
            _f(p + "wavelength_x_m", wl, "m", f"{name} egg-carton wavelength along x"),
            _f(p + "wavelength_y_m", wl, "m", f"{name} egg-carton wavelength along y"),
        ]
    return specs


TISSUE_PARAMETERS: tuple[ParamSpec, ...] = tuple(
    [
        _f("sheet.size_x_m", 0.12, "m", "tissue sheet extent along x, centred on the frame origin"),
        _f("sheet.size_y_m", 0.12, "m", "tissue sheet extent along y, centred on the frame origin"),
        _f("patch.size_x_m", 0.06, "m", "deformation patch side along x (paper: 60 mm)"),
        _f("patch.size_y_m", 0.06, "m", "deformation patch side along y (paper: 60 mm)"),
        _i("grid.nx", 120, "output height-map cells along x over the sheet", 2, 1024),
        _i("grid.ny", 120, "output height-map cells along y over the sheet", 2, 1024),
        _i(
            "modes.m",
            15,
            "modal terms along x (M in eq 2); <= 61: with jittery tick intervals the propagator "
            "is recomputed every tick, ~67 us at 61 x 61",
            1,
            61,
        ),
        _i("modes.n", 15, "modal terms along y (N in eq 2); <= 61, as modes.m", 1, 61),
        _f("tool.radius_m", _TOOL_RADIUS_M, "m", "tool tip radius; the disk load of the indentation shape"),
    ]
    + _layer_specs()
    + _interface_specs()
    + _lod_specs()
)
SPEC_BY_NAME = {s.name: s for s in TISSUE_PARAMETERS}


@dataclass(frozen=True)
class LayerConfig:
    """One layer's Kelvin-Voigt (eq 6) and membrane (eq 1) parameters, SI units."""

    name: str
    thickness_m: float
    stiffness_n_per_m: float
    damping_n_s_per_m: float
    area_m2: float
    density_kg_per_m3: float
    tension_n_per_m: float

    @property
    def areal_density_kg_per_m2(self) -> float:
        return self.density_kg_per_m3 * self.thickness_m

    @property
    def wave_speed_m_per_s(self) -> float:
        """``c = sqrt(T / rho)`` (eq 1), with ``rho`` the areal density."""
        return math.sqrt(self.tension_n_per_m / self.areal_density_kg_per_m2)


@dataclass(frozen=True)
class InterfaceConfig:
    """An egg-carton interface: ``depth = mean - amplitude*cos(2 pi x/wx)*cos(2 pi y/wy)``."""

    name: str
    mean_depth_m: float
    amplitude_m: float
    wavelength_x_m: float
    wavelength_y_m: float


@dataclass(frozen=True)
class LodConfig:
    """Level-of-detail switches and the displacement tolerance (m) they share."""

    tolerance_m: float = LOD_TOLERANCE_M
    adaptive_modes: bool = True
    affected_layers: bool = True
    patch_only: bool = True
    idle: bool = True


@dataclass(frozen=True)
class TissueConfig:
    """Everything the model needs, frozen. Build with :func:`config_from_flat` or presets."""

    sheet_size_m: tuple[float, float]
    patch_size_m: tuple[float, float]
    grid_shape: tuple[int, int]  # (ny, nx), row-major image order
    modes: tuple[int, int]  # (M, N)
    tool_radius_m: float
    layers: tuple[LayerConfig, ...]
    interfaces: tuple[InterfaceConfig, ...]
    lod: LodConfig
    flat: tuple[tuple[str, Any], ...]  # the validated dotted parameters it came from

    @property
    def total_thickness_m(self) -> float:
        return sum(layer.thickness_m for layer in self.layers)

    def as_flat(self) -> dict[str, Any]:
        return dict(self.flat)

    def replace(self, **changes: Any) -> TissueConfig:
        """A new validated config with some dotted parameters changed."""
        flat = self.as_flat()
        flat.update(changes)
        return config_from_flat(flat)


def default_flat() -> dict[str, Any]:
    return {s.name: s.default for s in TISSUE_PARAMETERS}


def config_from_flat(values: dict[str, Any]) -> TissueConfig:
    """Validate dotted parameters (missing ones take schema defaults) into a TissueConfig.

    Raises
    ------
    ConfigError
        Unknown names, wrong types, out-of-bound values, a patch larger than the
        sheet, or interfaces that cross each other, pierce the surface or the bottom.
    """
    unknown = sorted(set(values) - set(SPEC_BY_NAME))
    if unknown:
        raise ConfigError(f"unknown tissue parameter(s): {', '.join(unknown)}")
    flat = default_flat()
    for name, value in values.items():
        flat[name] = SPEC_BY_NAME[name].check(value)

    layers = tuple(
        LayerConfig(
            name=n,
            thickness_m=flat[f"layers.{n}.thickness_m"],
            stiffness_n_per_m=flat[f"layers.{n}.stiffness_n_per_m"],
            damping_n_s_per_m=flat[f"layers.{n}.damping_n_s_per_m"],
            area_m2=flat[f"layers.{n}.area_m2"],
            density_kg_per_m3=flat[f"layers.{n}.density_kg_per_m3"],
            tension_n_per_m=flat[f"layers.{n}.tension_n_per_m"],
        )
        for n in LAYER_NAMES
    )
    mean_depths = np.cumsum([layer.thickness_m for layer in layers])
    interfaces = tuple(
        InterfaceConfig(
            name=n,
            mean_depth_m=float(mean_depths[i]),
            amplitude_m=flat[f"interfaces.{n}.amplitude_m"],
            wavelength_x_m=flat[f"interfaces.{n}.wavelength_x_m"],
            wavelength_y_m=flat[f"interfaces.{n}.wavelength_y_m"],
        )
        for i, n in enumerate(INTERFACE_NAMES)
    )
    cfg = TissueConfig(
        sheet_size_m=(flat["sheet.size_x_m"], flat["sheet.size_y_m"]),
        patch_size_m=(flat["patch.size_x_m"], flat["patch.size_y_m"]),
        grid_shape=(flat["grid.ny"], flat["grid.nx"]),
        modes=(flat["modes.m"], flat["modes.n"]),
        tool_radius_m=flat["tool.radius_m"],
        layers=layers,
        interfaces=interfaces,
        lod=LodConfig(
            tolerance_m=flat["lod.tolerance_m"],
            adaptive_modes=flat["lod.adaptive_modes"],
            affected_layers=flat["lod.affected_layers"],
            patch_only=flat["lod.patch_only"],
            idle=flat["lod.idle"],
        ),
        flat=tuple(sorted(flat.items())),
    )
    _check_geometry(cfg)
    return cfg


def _check_geometry(cfg: TissueConfig) -> None:

    sx, sy = cfg.sheet_size_m
    px, py = cfg.patch_size_m
    if px > sx or py > sy:
        raise ConfigError(f"patch {px * 1e3:.1f} x {py * 1e3:.1f} mm is larger than the sheet {sx * 1e3:.1f} x {sy * 1e3:.1f} mm")
    if cfg.tool_radius_m >= 0.5 * min(px, py):
        raise ConfigError(f"tool.radius_m = {cfg.tool_radius_m} m must be smaller than half the patch side")
    # Exact bound: each egg-carton reaches mean +- amplitude somewhere on a large sheet, and two
    # cartons of different wavelengths come arbitrarily close to opposite extremes, so the
    # layer between them keeps positive thickness everywhere iff gap > sum of amplitudes.
    tops = [(0.0, 0.0, "surface")] + [(i.mean_depth_m, i.amplitude_m, i.name) for i in cfg.interfaces]
    tops.append((cfg.total_thickness_m, 0.0, "bottom"))
    for (d_up, a_up, n_up), (d_lo, a_lo, n_lo) in zip(tops[:-1], tops[1:]):
        gap = (d_lo - d_up) - a_up - a_lo
        if gap <= 0.0:
            raise ConfigError(
                f"interfaces cross: '{n_lo}' reaches '{n_up}' (mean gap {(d_lo - d_up) * 1e3:.3f} mm, "
                f"amplitudes {a_up * 1e3:.3f} + {a_lo * 1e3:.3f} mm); reduce an amplitude or increase a thickness"
            )


def load_yaml(path: str | Path, node_name: str = NODE_NAME) -> dict[str, Any]:
    """Read a ``ros__parameters`` YAML file and return all its parameters, dotted."""
    with open(path) as fh:
        doc = yaml.safe_load(fh) or {}
    if node_name not in doc and len(doc) == 1:
        node_name = next(iter(doc))
    try:
        params = doc[node_name]["ros__parameters"]
    except (KeyError, TypeError) as exc:
        raise ConfigError(f"{path}: expected '{node_name}: ros__parameters:' at the top") from exc
    return flatten(params)


def flatten(tree: dict[str, Any], prefix: str = "") -> dict[str, Any]:
    out: dict[str, Any] = {}
    for key, value in tree.items():
        name = f"{prefix}{key}"
        if isinstance(value, dict):
            out.update(flatten(value, name + "."))
        else:
            out[name] = value
    return out


def unflatten(flat: dict[str, Any]) -> dict[str, Any]:
    tree: dict[str, Any] = {}
    for name, value in flat.items():
        node = tree
        *parents, leaf = name.split(".")
        for p in parents:
            node = node.setdefault(p, {})
        node[leaf] = value
    return tree


def tissue_part(flat: dict[str, Any], prefix: str = "tissue.") -> dict[str, Any]:
    """The tissue parameters of a node's dotted parameter dict, prefix stripped."""
    return {k[len(prefix) :]: v for k, v in flat.items() if k.startswith(prefix)}


def load_tissue_config(path: str | Path) -> TissueConfig:
    """Load and validate the ``tissue.*`` parameters of a node YAML file."""
    return config_from_flat(tissue_part(load_yaml(path)))


def dump_yaml(flat_by_prefix: dict[str, Any], path: str | Path, node_name: str = NODE_NAME) -> None:
    """Write dotted parameters as a ``ros__parameters`` YAML file."""
    doc = {node_name: {"ros__parameters": unflatten(flat_by_prefix)}}
    with open(path, "w") as fh:
        yaml.safe_dump(doc, fh, sort_keys=False)


CONFIG_DIR = Path(__file__).resolve().parents[2] / "config"


def preset(name: str) -> TissueConfig:
    """A shipped preset: ``default`` (physiological) or ``paper`` (eq 9, one mode)."""
    path = CONFIG_DIR / f"{name}.yaml"
    if not path.exists():
        from importlib import resources

        path = Path(str(resources.files("skin_sim_node") / "config" / f"{name}.yaml"))
    if not path.exists():
        raise ConfigError(f"no preset named {name!r} (looked for {path})")
    return load_tissue_config(path)
