"""The one way from a node's parameter set to what runs: its :class:`NodeParams` and its :class:`TissueConfig`.

The contract checks the node parameters (:func:`msgs_schema.parameters.node_params_from_flat`); the tissue part goes
the one way every tissue configuration is built, :func:`skin_sim_node.model.config.config_from_flat` (the contract's
:func:`~msgs_schema.parameters.check_tissue`, then the model's geometry checks). Above the model core, which builds no
node parameters (tests/test_presets.py). Used by the node (at start and on a live set) and the offline replay
(:func:`skin_sim_node.bags.offline.load_params`).
"""

from __future__ import annotations

from collections.abc import Iterable, Mapping
from typing import Any

from msgs_schema.parameters import (
    SPEC_BY_NAME,
    TISSUE_PREFIX,
    NodeParams,
    check_value,
    node_params_from_flat,
    tissue_part,
)
from msgs_schema.spec import check_names

from .model import TissueConfig, config_from_flat


def configure(flat: Mapping[str, Any], changed: Iterable[str] = ()) -> tuple[NodeParams, TissueConfig]:
    """The node parameters and the built tissue config of a full dotted parameter dict.

    Parameters
    ----------
    flat : mapping
        Declared name (tissue parameters with the ``tissue.`` prefix) -> value; missing ones take their defaults.
    changed : iterable of str
        Names checked first against their declared spec, so that the reason for a rejected set names them as declared
        (``tissue.`` prefix kept).

    Returns
    -------
    NodeParams, TissueConfig

    Raises
    ------
    ConfigError
        With the reason: an unknown name, a bad value, or a geometry that does not fit.
    """
    check_names(flat, SPEC_BY_NAME)  # every unknown name at once, each with its closest valid name (issue 29)
    for name in changed:
        check_value(name, flat[name])
    return node_params_from_flat(flat), config_from_flat(tissue_part(flat))


def hand_configs(flat: Mapping[str, Any], cfg: TissueConfig) -> list[TissueConfig]:
    """Each hand's tool configuration (issue 32): ``cfg`` (the first hand's, ``tissue.tool.*``), and with a second hand
    (``second_hand_ns``) the same tissue under ``second_tool_shape`` / ``second_tool_radius_m``, built and checked the
    one way (:func:`configure`). The node, the offline replay, the demo and the lab all take them from here.

    Parameters
    ----------
    flat : mapping
        The node's dotted parameter dict.
    cfg : TissueConfig
        ``configure(flat)``'s tissue.

    Returns
    -------
    list of TissueConfig

    Raises
    ------
    ConfigError
        The second hand's tool does not fit the tissue.
    """
    if not flat.get("second_hand_ns", ""):
        return [cfg]
    second = dict(flat) | {
        TISSUE_PREFIX + "tool.shape": flat.get("second_tool_shape", SPEC_BY_NAME["second_tool_shape"].default),
        TISSUE_PREFIX + "tool.radius_m": flat.get("second_tool_radius_m", SPEC_BY_NAME["second_tool_radius_m"].default),
    }
    return [cfg, configure(second)[1]]
