"""Pure model core: no rclpy. Config, interfaces, Reuss mechanics, modal deformation."""

from .config import ConfigError, TissueConfig, config_from_flat, load_tissue_config, preset
from .contact import ContactTangent, normal_tangent
from .interfaces import classify, interface_depths_m
from .layout import FLAG_BOTTOMED, FLAG_CONTACT, FLAG_LAYER_BOUND, FLAG_OFF_SHEET, FLAG_SEPARATED
from .needle_skin import NeedleSkin  # registers the needle's model with SkinModel
from .skin_model import DEGENERATE_RETURN_S, Grid, SkinModel, warm_up

__all__ = [
    "DEGENERATE_RETURN_S",
    "FLAG_BOTTOMED",
    "FLAG_CONTACT",
    "FLAG_LAYER_BOUND",
    "FLAG_OFF_SHEET",
    "FLAG_SEPARATED",
    "ConfigError",
    "ContactTangent",
    "Grid",
    "NeedleSkin",
    "SkinModel",
    "TissueConfig",
    "classify",
    "config_from_flat",
    "interface_depths_m",
    "load_tissue_config",
    "normal_tangent",
    "preset",
    "warm_up",
]
