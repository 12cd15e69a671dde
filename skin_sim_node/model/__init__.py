"""Pure model core: no rclpy. Config, interfaces, Reuss mechanics, modal deformation."""

from .config import ConfigError, TissueConfig, config_from_flat, load_tissue_config, preset
from .interfaces import classify, interface_depths_m
from .skin_model import Grid, SkinModel

__all__ = [
    "ConfigError",
    "Grid",
    "SkinModel",
    "TissueConfig",
    "classify",
    "config_from_flat",
    "interface_depths_m",
    "load_tissue_config",
    "preset",
]
