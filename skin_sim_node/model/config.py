"""Tissue configuration: the frozen config the model runs on, built from checked parameters, and YAML I/O.

The schema (:data:`msgs_schema.tissue.TISSUE_PARAMETERS`) and the validation of parameter values
(:func:`msgs_schema.parameters.check_tissue`, :func:`msgs_schema.parameters.validate_parameters`) live in
the contract. Here :func:`build_config` turns checked values into the frozen :class:`TissueConfig`, with the
model's own geometry checks (patch within the sheet, tool within the patch, interfaces that do not cross);
:func:`config_from_flat` is the two in one, for values that were not checked yet.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np
import yaml

from msgs_schema.parameters import NODE_NAME, SPEC_BY_NAME, check_tissue, tissue_part
from msgs_schema.spec import ConfigError, check_names, read_yaml
from msgs_schema.tissue import INTERFACE_NAMES, LAYER_NAMES, LOD_TOLERANCE_M, tissue_defaults

__all__ = [
    "ConfigError",
    "InterfaceConfig",
    "LayerConfig",
    "LodConfig",
    "TissueConfig",
    "ViscoelasticConfig",
    "build_config",
    "config_from_flat",
    "default_flat",
    "dump_yaml",
    "flatten",
    "load_tissue_config",
    "load_yaml",
    "preset",
    "preset_path",
    "unflatten",
]


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
    stiffening: float = 0.0  # exponent n of the layered form's compression law

    @property
    def areal_density_kg_per_m2(self) -> float:
        """``density * thickness`` (kg/m^2), the membrane's mass per area (eq 1)."""
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
class ViscoelasticConfig:
    """The layered form's quasi-linear viscoelasticity (Fung): every layer's reduced relaxation function
    ``G(t) = 1 + g1 exp(-t / tau1) + g2 exp(-t / tau2)``, relative to the equilibrium (elastic) law. ``g1 = g2 = 0``
    is the purely elastic chain."""

    g1: float = 0.0
    tau1_s: float = 0.01
    g2: float = 0.0
    tau2_s: float = 0.5


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
    form: str = "layered"  # "layered" or "paper"
    tool_shape: str = "flat"  # "flat", "sphere" or "needle"
    friction_coefficient: float = 0.0
    tangential_stiffness_n_per_m: float = 0.0  # presliding stiffness of the friction (friction.py); 0: none
    foundation_length_m: float = 0.0  # membranes' foundation decay length (modal.py); 0: bare membrane
    viscoelastic: ViscoelasticConfig = ViscoelasticConfig()  # layered form's Prony arms; default: none
    anisotropy_ratio: float = 1.0  # membrane coefficient along / across the tension lines (modal.py); 1: isotropic
    anisotropy_angle_rad: float = 0.0  # direction of the lines (and of the patch's first side) from the sheet's x axis
    needle_outer_diameter_m: float = 0.819e-3  # tool.shape 'needle' (needle.py)
    needle_lubricated: bool = True

    @property
    def total_thickness_m(self) -> float:
        """Sum of the layers' mean thicknesses (m)."""
        return sum(layer.thickness_m for layer in self.layers)

    def as_flat(self) -> dict[str, Any]:
        """The checked dotted parameters it was built from (no ``tissue.`` prefix)."""
        return dict(self.flat)

    def replace(self, **changes: Any) -> TissueConfig:
        """A new validated config with some dotted parameters changed.

        Parameters
        ----------
        **changes
            Dotted tissue name (no prefix) -> new value.

        Returns
        -------
        TissueConfig
        """
        flat = self.as_flat()
        flat.update(changes)
        return config_from_flat(flat)


def equilibrium(cfg: TissueConfig) -> TissueConfig:
    """``cfg`` without the viscoelastic arms (``viscoelastic.g1 = g2 = 0``): its equilibrium (fully relaxed) law,
    the one the hyperelastic references check.

    In the runtime (not with the lab's checks in ``skin_sim_lab.oracles.physics``, which re-export it): the needle's
    dimple chain (:mod:`.needle`) is built on it."""
    return cfg.replace(**{"viscoelastic.g1": 0.0, "viscoelastic.g2": 0.0})


def default_flat() -> dict[str, Any]:
    """Every tissue parameter at its default (:func:`msgs_schema.tissue.tissue_defaults`).

    Returns
    -------
    dict
        Dotted name (no ``tissue.`` prefix) -> default.
    """
    return tissue_defaults()


def config_from_flat(values: dict[str, Any]) -> TissueConfig:
    """Check dotted tissue parameters (missing ones take schema defaults) and build a TissueConfig: the one way from a
    parameter set to a tissue configuration (:func:`load_tissue_config`, :func:`preset`, :meth:`TissueConfig.replace`
    and, for a node's whole parameter set, :func:`skin_sim_node.configure.configure` all come through here).

    :func:`msgs_schema.parameters.check_tissue` (unknown names, wrong types, out-of-bound values), then
    :func:`build_config` (the geometry); either raises :class:`ConfigError` with the reason.

    Parameters
    ----------
    values : dict
        Dotted tissue name (no ``tissue.`` prefix) -> value.

    Returns
    -------
    TissueConfig
    """
    return build_config(check_tissue(values))


def build_config(flat: dict[str, Any]) -> TissueConfig:
    """The frozen TissueConfig of checked tissue parameters, after the model's own geometry checks.

    Parameters
    ----------
    flat : dict
        Every tissue parameter (no ``tissue.`` prefix) -> its checked value, as
        :func:`msgs_schema.parameters.check_tissue` returns them.

    Returns
    -------
    TissueConfig

    Raises
    ------
    ConfigError
        A patch larger than the sheet, a tool as wide as the patch, or interfaces that cross each other,
        pierce the surface or the bottom.
    """
    layers = tuple(
        LayerConfig(
            name=n,
            thickness_m=flat[f"layers.{n}.thickness_m"],
            stiffness_n_per_m=flat[f"layers.{n}.stiffness_n_per_m"],
            damping_n_s_per_m=flat[f"layers.{n}.damping_n_s_per_m"],
            area_m2=flat[f"layers.{n}.area_m2"],
            density_kg_per_m3=flat[f"layers.{n}.density_kg_per_m3"],
            tension_n_per_m=flat[f"layers.{n}.tension_n_per_m"],
            stiffening=flat[f"layers.{n}.stiffening"],
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
        form=flat["form"],
        tool_shape=flat["tool.shape"],
        friction_coefficient=flat["contact.friction_coefficient"],
        tangential_stiffness_n_per_m=flat["contact.tangential_stiffness_n_per_m"],
        foundation_length_m=flat["patch.foundation_length_m"],
        viscoelastic=ViscoelasticConfig(
            g1=flat["viscoelastic.g1"],
            tau1_s=flat["viscoelastic.tau1_s"],
            g2=flat["viscoelastic.g2"],
            tau2_s=flat["viscoelastic.tau2_s"],
        ),
        anisotropy_ratio=flat["anisotropy.ratio"],
        anisotropy_angle_rad=flat["anisotropy.angle_rad"],
        needle_outer_diameter_m=flat["needle.outer_diameter_m"],
        needle_lubricated=flat["needle.lubricated"],
    )
    _check_geometry(cfg)
    return cfg


def _check_geometry(cfg: TissueConfig) -> None:
    """Raise :class:`ConfigError` if the patch, the tool or the interfaces do not fit (see :func:`build_config`)."""
    sx, sy = cfg.sheet_size_m
    px, py = cfg.patch_size_m
    if px > sx or py > sy:
        raise ConfigError(f"patch {px * 1e3:.1f} x {py * 1e3:.1f} mm is larger than the sheet {sx * 1e3:.1f} x {sy * 1e3:.1f} mm")
    if cfg.tool_shape == "needle" and cfg.form != "layered":
        raise ConfigError("tool.shape 'needle' needs form 'layered' (its dimple is the layered form's chain)")
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
    """Read a ``ros__parameters`` YAML file and return all its parameters, dotted (not validated).

    Parameters
    ----------
    path : str or Path
    node_name : str
        The top key; a file with a single other top key is read under that one.

    Returns
    -------
    dict
        Declared name -> value.

    Raises
    ------
    ConfigError
        Not YAML, or no ``<node_name>: ros__parameters:`` at the top.
    """
    doc = read_yaml(path) or {}  # a file that is not YAML: one line, as every other bad parameter file
    if not isinstance(doc, dict):
        raise ConfigError(f"{path}: expected '{node_name}: ros__parameters:' at the top")
    if node_name not in doc and len(doc) == 1:
        node_name = next(iter(doc))
    try:
        params = doc[node_name]["ros__parameters"]
    except (KeyError, TypeError) as exc:
        raise ConfigError(f"{path}: expected '{node_name}: ros__parameters:' at the top") from exc
    return flatten(params)


def flatten(tree: dict[str, Any], prefix: str = "") -> dict[str, Any]:
    """Nested mappings to dotted names (``{"a": {"b": 1}}`` -> ``{"a.b": 1}``).

    Parameters
    ----------
    tree : dict
    prefix : str
        Put before every name.

    Returns
    -------
    dict
    """
    out: dict[str, Any] = {}
    for key, value in tree.items():
        name = f"{prefix}{key}"
        if isinstance(value, dict):
            out.update(flatten(value, name + "."))
        else:
            out[name] = value
    return out


def unflatten(flat: dict[str, Any]) -> dict[str, Any]:
    """Dotted names to nested mappings, the inverse of :func:`flatten`.

    Parameters
    ----------
    flat : dict

    Returns
    -------
    dict
    """
    tree: dict[str, Any] = {}
    for name, value in flat.items():
        node = tree
        *parents, leaf = name.split(".")
        for p in parents:
            node = node.setdefault(p, {})
        node[leaf] = value
    return tree


def load_tissue_config(path: str | Path) -> TissueConfig:
    """Load, check and build the ``tissue.*`` parameters of a node YAML file.

    Parameters
    ----------
    path : str or Path

    Returns
    -------
    TissueConfig
    """
    flat = load_yaml(path)
    check_names(flat, SPEC_BY_NAME)  # a misspelt node parameter in the file is an error here too, not ignored
    return config_from_flat(tissue_part(flat))


def dump_yaml(flat_by_prefix: dict[str, Any], path: str | Path, node_name: str = NODE_NAME) -> None:
    """Write dotted parameters as a ``ros__parameters`` YAML file.

    Parameters
    ----------
    flat_by_prefix : dict
        Declared name -> value, written in this order.
    path : str or Path
    node_name : str
        The top key.
    """
    doc = {node_name: {"ros__parameters": unflatten(flat_by_prefix)}}
    with open(path, "w") as fh:
        yaml.safe_dump(doc, fh, sort_keys=False)


PRESET_DIR = Path(__file__).resolve().parents[1] / "config"
"""The shipped presets, package data: ``scripts/gen_presets.py`` writes them with the top-level ``config/*.yaml``."""


def preset_path(name: str) -> Path:
    """The file of a shipped preset, ``skin_sim_node/config/NAME.yaml`` (the same as the top-level ``config/NAME.yaml``).

    Raises
    ------
    ConfigError
        No preset of that name.
    """
    path = PRESET_DIR / f"{name}.yaml"
    if not path.exists():
        raise ConfigError(f"no preset named {name!r} (looked for {path})")
    return path


def preset(name: str) -> TissueConfig:
    """A shipped preset: ``default`` (layered form, in-vivo parameters, forearm tension lines), ``isotropic`` (the
    default without tension lines), ``needle`` (the default under a 21 G needle) or ``paper`` (the paper's form, eq 9,
    one mode)."""
    return load_tissue_config(preset_path(name))
