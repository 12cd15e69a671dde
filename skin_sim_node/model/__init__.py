"""Pure model core: no rclpy. Config, interfaces, Reuss mechanics, modal deformation: the tissue (the tools that press
it: :mod:`skin_sim_node.tools`)."""

from .config import ConfigError, TissueConfig, config_from_flat, load_tissue_config, preset
from .contact import ContactTangent, Indenter, normal_tangent
from .interfaces import classify, interface_depths_m
from .layout import FLAG_BOTTOMED, FLAG_CONTACT, FLAG_LAYER_BOUND, FLAG_OFF_SHEET, FLAG_SEPARATED
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
    "Indenter",
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
