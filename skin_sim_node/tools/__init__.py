"""Tools: the rigid objects the hand holds, each behind one seam (:class:`~.base.Tool`). No rclpy.

- :mod:`.base`: the seam (:class:`Tool`, what a tool declares: :class:`ToolNeeds`; what its step returns:
  :class:`ToolStep`);
- :mod:`.punch`, :mod:`.flat`, :mod:`.sphere`: the punches (the tissue's own contact);
- :mod:`.needle`: the needle (issue 22; its physics in :mod:`skin_sim_node.model.needle`).

:func:`make_tool` chooses the tool of a configuration once (``tool.shape``); :func:`warm_up` compiles its kernels.
"""

from __future__ import annotations

from ..model import SkinModel, TissueConfig
from ..model.skin_model import warm_up as warm_up_tissue
from .base import DOWN, Readout, Tool, ToolNeeds, ToolPose, ToolStep, tissue_step
from .flat import FlatPunch
from .hands import MAX_HANDS, CoupledTool, SharedSkin
from .needle import NeedleTool
from .sphere import SpherePunch

TOOLS: dict[str, type[Tool]] = {"flat": FlatPunch, "sphere": SpherePunch, "needle": NeedleTool}
"""The tool class of each ``tool.shape`` (msgs_schema/tissue.py's choices)."""


def make_tool(cfg: TissueConfig) -> Tool:
    """The tool of ``cfg`` (``cfg.tool_shape``) pressing a tissue at rest.

    Parameters
    ----------
    cfg : TissueConfig

    Returns
    -------
    Tool
    """
    return TOOLS[cfg.tool_shape](cfg)


def make_tools(cfgs: list[TissueConfig]) -> list[Tool]:
    """One tool per hand's configuration: a single tool as :func:`make_tool`; two press one tissue
    (:class:`~.hands.SharedSkin`: each tool's chain at a surface lowered by the other's field).

    Parameters
    ----------
    cfgs : list of TissueConfig
        Each hand's configuration: the same tissue, each with its tool (``tool.*``).

    Returns
    -------
    list of Tool
    """
    tools = [make_tool(c) for c in cfgs]
    return tools if len(tools) == 1 else list(SharedSkin(tools).hands)


def tissue(cfg: TissueConfig) -> SkinModel:
    """A tissue at rest as the tool of ``cfg`` presses it (its :class:`~skin_sim_node.model.Indenter`): the display's and
    the replay report's, which take a copy of the tool's tissue state (:meth:`SkinModel.set_state`).

    Parameters
    ----------
    cfg : TissueConfig

    Returns
    -------
    SkinModel
    """
    return SkinModel(cfg, TOOLS[cfg.tool_shape].indenter(cfg))


def warm_up(cfg: TissueConfig) -> None:
    """Compile (or load from numba's cache) every kernel the tool of ``cfg`` runs, and touch every path once.

    The tissue's (:func:`skin_sim_node.model.skin_model.warm_up`), the tool's own (:meth:`Tool.warm_up`), and the
    tool's step and tangent through a press, a lift and a rest (left to the first press, loading a kernel from the
    cache stalled a live node's tick thread for 100 ms or more).
    """
    warm_up_tissue(cfg)
    tool_class = TOOLS[cfg.tool_shape]
    tool_class.warm_up(cfg)
    tool = tool_class(cfg)
    for i in range(60):
        d = 4e-3 * min(i, 30) / 30
        tool.step(ToolPose((0.001 * i, 0.0, -d), (0.001, 0.0, -0.1), DOWN, 1e-3, i == 0))
    tool.step(ToolPose((0.0, 0.0, 0.01), (0.0, 0.0, 0.5), DOWN, 1e-3, False))
    tool.readout()
    tool.release()
    tool.reset()


__all__ = [
    "DOWN",
    "MAX_HANDS",
    "CoupledTool",
    "SharedSkin",
    "TOOLS",
    "FlatPunch",
    "NeedleTool",
    "Readout",
    "SpherePunch",
    "Tool",
    "ToolNeeds",
    "ToolPose",
    "ToolStep",
    "make_tool",
    "make_tools",
    "tissue",
    "tissue_step",
    "warm_up",
]
