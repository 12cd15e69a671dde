"""The punches' common step: the tissue's own contact is the tool's force (no physics of the tool's own).

:class:`~.flat.FlatPunch` and :class:`~.sphere.SpherePunch` differ only in the :class:`~skin_sim_node.model.Indenter`
they press the tissue with (its eq 6 contact and modal load).
"""

from __future__ import annotations

from ..model import FLAG_CONTACT, Indenter, TissueConfig
from .base import Tool, ToolPose, ToolStep, tissue_step


class Punch(Tool):
    """A rigid punch of ``tool.radius_m``: the tissue's layered (or paper) contact, with its friction.

    Parameters
    ----------
    cfg : TissueConfig
    """

    sphere = False
    """The tip's shape (a class attribute of the subclass): spherical or flat."""

    @classmethod
    def indenter(cls, cfg: TissueConfig) -> Indenter:
        """A tip of ``tool.radius_m``, flat or spherical (:attr:`sphere`)."""
        return Indenter(cfg.tool_radius_m, cls.sphere)

    def step(self, pose: ToolPose) -> ToolStep:
        """The tissue's step at the tip; its tangent (:meth:`SkinModel.tangent`) only in contact."""
        t = self.tissue
        t.step(pose.position_m, pose.velocity_m_s, pose.dt_s, pose.restart)
        return tissue_step(t, t.force_vector_n, t.tangent() if t.flags & FLAG_CONTACT else None)
