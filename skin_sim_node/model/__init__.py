"""Pure model core: no rclpy. Config, interfaces, Reuss mechanics, modal deformation."""

from .config import ConfigError, TissueConfig, config_from_flat, load_tissue_config, preset
from .interfaces import classify, interface_depths_m
from .kernels import FLAG_BOTTOMED, FLAG_CONTACT, FLAG_LAYER_BOUND, FLAG_OFF_SHEET, FLAG_SEPARATED
from .skin_model import Grid, SkinModel

__all__ = [
    "FLAG_BOTTOMED",
    "FLAG_CONTACT",
    "FLAG_LAYER_BOUND",
    "FLAG_OFF_SHEET",
    "FLAG_SEPARATED",
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
