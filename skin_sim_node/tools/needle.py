"""The needle (``tool.shape`` 'needle', issue 22): a :class:`~.base.Tool` whose force is its own physics.

The force is the needle's (:class:`~skin_sim_node.model.needle.NeedleModel`: dimple, puncture, cutting, shaft
friction, lateral bed along the track). A track starts where the tip enters through the surface on the sheet at more
than 10 degrees (or at a contact restart); a tip below the surface without one (too flat a needle, or one steepened
after it got there; off the sheet) is a surface contact: the layered form's indentation and friction of a punch of the
needle's radius. A needle pushed sideways harder than cutting a slot through the inserted layers takes
(``sum_i lambda Gamma_i l_i``) tears: its track starts again where it is. Before the first rupture the track follows
the needle's position and angle; the tent's friction anchor (the skin's stuck point under the tip) is kept across
those restarts, so the tent's force is a potential's plus a dissipative friction (passive on any closed path).

With a track, the tissue's layered kernel (:class:`~skin_sim_node.model.SkinModel`, pressed by an
:class:`~skin_sim_node.model.Indenter` of the needle's radius) still runs, for the deformation only: it is driven at
the tip with the dimple's normal depth while a layer ahead is intact, so the grid shows the dimple before the puncture,
and it is lifted off once every layer is cut, so the grid shows the release (the layers recover along their own law,
the paper's return to rest). Its own force is not published.

What the session needs of it is declared (:attr:`NeedleTool.needs`): the pose's orientation (the axis), a rate bound on
rises only (the puncture drop is felt at once), no friction law in the contact model (the needle's law is
:class:`msgs_schema.contact_model.NeedleLaw`), and its own read-out topic ``tissue/needle``.

The physics stays in :mod:`skin_sim_node.model.needle` and :mod:`~skin_sim_node.model.needle_kernels`: it is the
layered tissue's mechanics along a track (the layers' rupture and the chain of :mod:`~skin_sim_node.model.layered`,
on the arrays of :mod:`~skin_sim_node.model.layout`), tested and benchmarked on its own; this module is the tool.
"""

from __future__ import annotations

import math

import numpy as np

from msgs_schema import convert as cv

from ..model import FLAG_CONTACT, FLAG_OFF_SHEET, ContactTangent, Indenter, TissueConfig
from ..model.needle import NeedleModel, NeedleParams, NeedleTick
from ..model.needle import warm_up as needle_warm_up
from .base import Readout, Tool, ToolNeeds, ToolPose, ToolStep, tissue_step

_EYE3 = np.eye(3)
_Z = (0.0, 0.0, 1.0)
SLIDE_TOLERANCE_M = 1e-6
"""Before the first rupture the track follows the tip: it is started again once the tip is this far off its axis (m;
a tenth of a 10 um display cell, far below what a hand feels)."""
SLIDE_TOLERANCE_RAD = 1e-3
"""... or once the needle has turned this far from the track's axis (rad)."""
LIFT_M = 1e-3
"""Height (m) the deformation kernel's tool is lifted to once no layer ahead is dimpled: off the tissue."""


class NeedleTool(Tool):
    """A needle of ``cfg.needle_outer_diameter_m`` in the layered skin (module docstring).

    Parameters
    ----------
    cfg : TissueConfig
        A validated needle configuration (``tool_shape == 'needle'``, layered form).
    """

    needs = ToolNeeds(orientation=True, rises_only=True, friction=False, readout=Readout("needle", cv.fill_needle_state))

    def __init__(self, cfg: TissueConfig):
        radius = 0.5 * cfg.needle_outer_diameter_m
        super().__init__(cfg)
        self.needle = NeedleModel(
            cfg, NeedleParams(outer_diameter_m=cfg.needle_outer_diameter_m, lubricated=cfg.needle_lubricated)
        )
        self._radius = radius
        self._half = (0.5 * cfg.sheet_size_m[0], 0.5 * cfg.sheet_size_m[1])
        self._tip = np.zeros(3)
        self._prev_z: float | None = None  # the tip's height at the last step (None: no step since a reset)
        self._surface = False  # the tip is below the surface without a track: the layered contact of a thin punch
        self.tears = 0  # tracks torn sideways (the lateral bed's force above the slot-cutting force)
        self.last_needle = NeedleTick(np.zeros(3))

    @classmethod
    def indenter(cls, cfg: TissueConfig) -> Indenter:
        """The deformation kernel's tip: a flat punch of the needle's radius."""
        return Indenter(0.5 * cfg.needle_outer_diameter_m)

    def reset(self) -> None:
        """Return to rest and withdraw the needle (no track)."""
        super().reset()
        self.needle.reset()
        self.last_needle = NeedleTick(np.zeros(3))
        self._prev_z, self._surface = None, False

    def release(self) -> None:
        """End contact now (a teleport, or a stall past ``stall_hold_s``: the tool is gone): the tissue relaxes and the
        track is forgotten. A shorter stall calls nothing: the track and its ruptures persist (issue 31)."""
        super().release()
        self.needle.reset()
        self.last_needle = NeedleTick(np.zeros(3))

    def step(self, pose: ToolPose) -> ToolStep:
        """Advance one tick with the needle's tip at ``pose.position_m`` (m) along the unit ``pose.axis`` (toward the
        tip): the needle's force and tangent, or the surface contact's (no track, tip below the surface)."""
        axis = pose.axis
        tip = np.asarray(pose.position_m, dtype=float)
        self._tip = tip
        nd = self.needle
        prev_z, self._prev_z = self._prev_z, float(tip[2])
        # a track starts where the tip enters through the surface on the sheet (or at a contact restart, the tip
        # having been where it is for an unknown time); a tip that got below the surface otherwise (a needle too flat
        # to start one, then steepened; off the sheet) stays a surface contact until it is lifted out
        on_sheet = abs(tip[0]) <= self._half[0] and abs(tip[1]) <= self._half[1]
        if nd.inserted or (on_sheet and (prev_z is None or prev_z >= 0.0 or pose.restart)):
            t = nd.step(tip, axis)
        else:
            t = NeedleTick(np.zeros(3))
        lat2 = float(t.lateral_n @ t.lateral_n) if nd.inserted and t.ruptured > 0 else 0.0
        if lat2 > 0.0 and lat2 > self._tear_force_n(t) ** 2:
            # pushed sideways harder than cutting a slot through the inserted layers takes: the needle cuts its way,
            # and its track starts again where it is (the cut layers above the tip stay cut, those below are intact)
            self.tears += 1
            nd.reset()
            t = nd.step(tip, axis)
        if nd.inserted and t.ruptured == 0 and self._off_track(tip, axis, t.insertion_m):
            # nothing is cut yet: the track is where the needle is now, not where it first touched; the tent's
            # friction anchor is the skin's and is kept (a reset would re-stick it under the tip: energy from nowhere)
            nd.reset(keep_tent=True)
            t = nd.step(tip, axis)
        self.last_needle = t
        tissue = self.tissue
        self._surface = not nd.inserted and tip[2] < 0.0
        if self._surface:  # the layered form's contact of a punch of the needle's radius: indentation and friction
            tissue.step(tip, pose.velocity_m_s, pose.dt_s, pose.restart)
            return tissue_step(tissue, tissue.force_vector_n, tissue.tangent() if tissue.flags & FLAG_CONTACT else None)
        u = nd.axis
        ahead = nd.inserted and t.ruptured < len(self.cfg.layers) and t.dimple_m > 0.0
        depth = t.dimple_m * abs(u[2]) if ahead else -LIFT_M
        v = pose.velocity_m_s if ahead else (0.0, 0.0, 0.0)
        tissue.step((tip[0], tip[1], -depth), v, pose.dt_s, pose.restart)
        tissue.flags = flags = FLAG_CONTACT if nd.inserted else (tissue.flags & FLAG_OFF_SHEET)
        inserted = nd.inserted
        n_affected = min(t.ruptured + (1 if t.dimple_m > 0.0 else 0), len(self.cfg.layers)) if inserted else 0
        return ToolStep(
            force_n=np.asarray(t.force_n, dtype=float).copy(),
            tangent=self._tangent(t) if inserted else None,
            flags=flags,
            idle=tissue.last_tick_idle,
            depth_m=max(-float(tip[2]), 0.0) if inserted else 0.0,
            n_affected=n_affected,
            compression_m=tuple(tissue.compression_m.tolist()),
            stress_pa=tissue.stress_pa,
        )

    def _off_track(self, tip: np.ndarray, axis, insertion_m: float) -> bool:
        """The tip is more than :data:`SLIDE_TOLERANCE_M` off the track's axis, or the needle turned from it (plain
        floats: a few small NumPy operations per tick cost more than the needle's kernels)."""
        nd = self.needle
        ex, ey, ez = nd.entry.tolist()
        ux, uy, uz = nd.axis.tolist()
        px, py, pz = tip.tolist()
        dx, dy, dz = px - ex - insertion_m * ux, py - ey - insertion_m * uy, pz - ez - insertion_m * uz
        if dx * dx + dy * dy + dz * dz > SLIDE_TOLERANCE_M**2:
            return True
        ax, ay, az = (float(c) for c in axis)
        na = math.sqrt(ax * ax + ay * ay + az * az)
        return na > 0.0 and (ax * ux + ay * uy + az * uz) / na < math.cos(SLIDE_TOLERANCE_RAD)

    def _tear_force_n(self, t: NeedleTick) -> float:
        """Sideways force (N) that cuts a slot through the inserted layers: ``sum_i lambda Gamma_i l_i`` (cutting a slot
        of height ``l_i`` sideways by ``dx`` takes ``Gamma_i l_i dx``)."""
        nd = self.needle
        c, d = nd.crossings, nd.params.outer_diameter_m
        f = 0.0
        for i in range(nd.ruptured):
            f += nd.params.puncture_force_n(i) / d * (min(max(t.insertion_m, c[i]), c[i + 1]) - c[i])
        return f

    def lateral_stiffness_n_per_m(self) -> float:
        """Stiffness of the bed that holds the shaft in its track, at the tip (N/m): ``0.5 sum_i k_l E_i l_i`` (the
        step kernel's ``k``)."""
        return 0.5 * self.last_needle.lateral_k_n_per_m

    def _tangent(self, t: NeedleTick) -> ContactTangent:
        """The needle's force and its local derivatives: ``K = -k_a u u^T - k_l (I - u u^T)``, ``D = 0`` (position
        laws: the dimple's equilibrium chain, the cutting ramp and Dahl's friction are rate-independent), and the
        axial law for the device (:meth:`NeedleModel.law`).

        ``k_a`` is the slope of the axial resistance: the dimple's or cutting ramp's plus Dahl's presliding slope
        ``F_c (1 - |z|) / x_0`` and the capacity's growth ``z dF_c/ds``.
        """
        law = self.needle.law(t, self._tip)
        f = np.asarray(t.force_n, dtype=float).copy()
        if law is None:
            return ContactTangent(f, np.zeros((3, 3)), np.zeros((3, 3)), np.array(_Z), 0.0)
        u = np.asarray(law.axis)
        uu = u[:, None] * u[None, :]
        cap, z = law.friction_capacity_n, law.friction_state
        k_a = law.axial_gradient_n_per_m + cap * (1.0 - abs(z)) / law.dahl_length_m + z * law.friction_capacity_gradient_n_per_m
        k_l = self.lateral_stiffness_n_per_m()
        k = (k_l - max(k_a, 0.0)) * uu - k_l * _EYE3
        return ContactTangent(f, k, np.zeros((3, 3)), -u, self._radius, needle=law)

    def readout(self) -> dict:
        """The needle for the view, charts and bags (``NeedleState.msg`` fields)."""
        nd, t = self.needle, self.last_needle
        return {
            "inserted": nd.inserted,
            "tip_m": self._tip.copy(),
            "axis": nd.axis.copy(),
            "entry_m": nd.entry.copy(),
            "insertion_m": t.insertion_m,
            "dimple_m": t.dimple_m,
            "ruptured_layers": t.ruptured,
            "crossing_m": nd.crossings.copy() if nd.inserted else np.zeros(0),
            "dimple_force_n": t.dimple_n,
            "cutting_force_n": t.cutting_n,
            "friction_force_n": t.friction_n,
            "force_n": np.asarray(t.force_n, dtype=float).copy(),
        }

    @classmethod
    def warm_up(cls, cfg: TissueConfig) -> None:
        """The needle's own kernels, every path (:func:`skin_sim_node.model.needle.warm_up`)."""
        needle_warm_up(cfg)
