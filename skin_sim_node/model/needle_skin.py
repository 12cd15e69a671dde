"""``NeedleSkin``: the skin model under a needle (``tool.shape`` 'needle', issue 22).

The force is the needle's (:class:`~.needle.NeedleModel`: dimple, puncture, cutting, shaft friction, lateral bed
along the track). A track starts where the tip enters through the surface on the sheet at more than 10 degrees (or at
a contact restart); a tip below the surface without one (too flat a needle, or one steepened after it got there;
off the sheet) is a surface contact: the layered form's indentation and friction of a punch of the needle's radius.
A needle pushed sideways harder than cutting a slot through the inserted layers takes (``sum_i lambda Gamma_i l_i``)
tears: its track starts again where it is. Before the first rupture the tent slides with the tip (frictionless): the
track follows the needle's position and angle.

With a track, the layered kernel of :class:`~.skin_model.SkinModel` still runs, for the deformation only: it is driven
at the tip with the dimple's normal depth while a layer ahead is intact, so the grid shows the dimple before
the puncture, and it is lifted off once every layer is cut, so the grid shows the release (the layers recover along
their own law, the paper's return to rest). Its own force is not published. The kernel's tool radius is the needle's.

``SkinModel(cfg)`` returns a ``NeedleSkin`` for a needle configuration, so every caller gets the needle through the
one model class.
"""

from __future__ import annotations

import dataclasses
import math

import numpy as np

from .config import TissueConfig
from .contact import ContactTangent
from .layout import FLAG_CONTACT, FLAG_OFF_SHEET
from .needle import NeedleModel, NeedleParams, NeedleTick
from .needle import warm_up as needle_warm_up
from .skin_model import SkinModel

_EYE3 = np.eye(3)
DOWN = (0.0, 0.0, -1.0)
"""The needle axis of an identity orientation: straight down into the tissue (msgs_schema/topics.py, tool_pose)."""
SLIDE_TOLERANCE_M = 1e-6
"""Before the first rupture the track follows the tip: it is started again once the tip is this far off its axis (m;
a tenth of a 10 um display cell, far below what a hand feels)."""
SLIDE_TOLERANCE_RAD = 1e-3
"""... or once the needle has turned this far from the track's axis (rad)."""
LIFT_M = 1e-3
"""Height (m) the deformation kernel's tool is lifted to once no layer ahead is dimpled: off the tissue."""


class NeedleSkin(SkinModel):
    """The layered skin under a needle of ``cfg.needle_outer_diameter_m`` (module docstring).

    Parameters
    ----------
    cfg : TissueConfig
        A validated needle configuration (``tool_shape == 'needle'``, layered form).
    """

    def __init__(self, cfg: TissueConfig):
        radius = 0.5 * cfg.needle_outer_diameter_m
        super().__init__(dataclasses.replace(cfg, tool_radius_m=radius))
        self.cfg = cfg
        self.needle = NeedleModel(
            cfg, NeedleParams(outer_diameter_m=cfg.needle_outer_diameter_m, lubricated=cfg.needle_lubricated)
        )
        self._radius = radius
        self._tip = np.zeros(3)
        self._prev_z: float | None = None  # the tip's height at the last step (None: no step since a reset)
        self._surface = False  # the tip is below the surface without a track: the layered contact of a thin punch
        self.tears = 0  # tracks torn sideways (the lateral bed's force above the slot-cutting force)
        self.last_needle = NeedleTick(np.zeros(3))

    def reset(self) -> None:
        """Return to rest and withdraw the needle (no track)."""
        super().reset()
        if hasattr(self, "needle"):
            self.needle.reset()
            self.last_needle = NeedleTick(np.zeros(3))
            self._prev_z, self._surface = None, False

    def release(self) -> None:
        """End contact now (a teleport or a stale input): the tissue relaxes and the track is forgotten."""
        super().release()
        self.needle.reset()
        self.last_needle = NeedleTick(np.zeros(3))

    def step(self, tool_xyz, tool_velocity, dt: float, restart: bool = False, axis=DOWN) -> float:
        """Advance one tick with the needle's tip at ``tool_xyz`` (m) along the unit ``axis`` (toward the tip).

        Returns the magnitude of the force on the needle (N); :attr:`force_vector_n` is the vector.
        """
        tip = np.asarray(tool_xyz, dtype=float)
        self._tip = tip
        nd = self.needle
        prev_z, self._prev_z = self._prev_z, float(tip[2])
        # a track starts where the tip enters through the surface on the sheet (or at a contact restart, the tip
        # having been where it is for an unknown time); a tip that got below the surface otherwise (a needle too flat
        # to start one, then steepened; off the sheet) stays a surface contact until it is lifted out
        on_sheet = abs(tip[0]) <= self._half[0] and abs(tip[1]) <= self._half[1]
        if nd.inserted or (on_sheet and (prev_z is None or prev_z >= 0.0 or restart)):
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
            # nothing is cut yet: the tent slides with the tip (a frictionless tip on the skin), so the track is
            # where the needle is now, not where it first touched
            nd.reset()
            t = nd.step(tip, axis)
        self.last_needle = t
        self._surface = not nd.inserted and tip[2] < 0.0
        if self._surface:  # the layered form's contact of a punch of the needle's radius: indentation and friction
            return super().step(tip, tool_velocity, dt, restart)
        u = nd.axis
        ahead = self.needle.inserted and t.ruptured < len(self.cfg.layers) and t.dimple_m > 0.0
        depth = t.dimple_m * abs(u[2]) if ahead else -LIFT_M
        v = tool_velocity if ahead else (0.0, 0.0, 0.0)
        super().step((tip[0], tip[1], -depth), v, dt, restart)
        self.flags = FLAG_CONTACT if self.needle.inserted else (self.flags & FLAG_OFF_SHEET)
        return self.force_n

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

    # --- the needle's force and its tangent (the layered contact's in surface mode) ----------------
    @property
    def force_n(self) -> float:
        """Magnitude of the force on the needle (N) of the last step."""
        if self._surface:
            return super().force_n
        f = self.last_needle.force_n
        return float(math.sqrt(float(f @ f)))

    @property
    def force_vector_n(self) -> np.ndarray:
        """Force on the needle (N, tissue frame) of the last step: ``-R u`` along the track plus the lateral bed."""
        if self._surface:
            return super().force_vector_n
        return np.asarray(self.last_needle.force_n, dtype=float).copy()

    @property
    def contact_normal(self) -> np.ndarray:
        """``-u``: the direction the axial resistance pushes the needle (``+z`` out of the tissue)."""
        if self._surface:
            return super().contact_normal
        return -self.needle.axis.copy() if self.needle.inserted else np.array([0.0, 0.0, 1.0])

    @property
    def contact_radius_m(self) -> float:
        """The needle's radius while it is in the tissue (m), else 0."""
        if self._surface:
            return super().contact_radius_m
        return self._radius if self.needle.inserted else 0.0

    @property
    def depth_m(self) -> float:
        """Depth of the tip below the rest surface (m), 0 out of the tissue."""
        if self._surface:
            return super().depth_m
        return max(-float(self._tip[2]), 0.0) if self.needle.inserted else 0.0

    @property
    def n_affected(self) -> int:
        """Layers the needle has cut, plus the one it dimples."""
        if self._surface:
            return super().n_affected
        t = self.last_needle
        return min(t.ruptured + (1 if t.dimple_m > 0.0 else 0), len(self.cfg.layers)) if self.needle.inserted else 0

    @property
    def in_contact(self) -> bool:
        """True while the needle is in the tissue (a track) or presses its surface (no track)."""
        return self.needle.inserted or (self._surface and bool(self.flags & FLAG_CONTACT))

    def lateral_stiffness_n_per_m(self) -> float:
        """Stiffness of the bed that holds the shaft in its track, at the tip (N/m): ``0.5 sum_i k_l E_i l_i`` (the
        step kernel's ``k``)."""
        return 0.5 * self.last_needle.lateral_k_n_per_m

    def tangent(self) -> ContactTangent:
        """The needle's force and its local derivatives: ``K = -k_a u u^T - k_l (I - u u^T)``, ``D = 0`` (position
        laws: the dimple's equilibrium chain, the cutting ramp and Dahl's friction are rate-independent), and the
        axial law for the device (:meth:`NeedleModel.law`).

        ``k_a`` is the slope of the axial resistance: the dimple's or cutting ramp's plus Dahl's presliding slope
        ``F_c (1 - |z|) / x_0`` and the capacity's growth ``z dF_c/ds``.
        """
        if self._surface:
            return super().tangent()
        t = self.last_needle
        law = self.needle.law(t, self._tip)
        f = np.asarray(t.force_n, dtype=float).copy()
        if law is None:
            return ContactTangent(f, np.zeros((3, 3)), np.zeros((3, 3)), np.array([0.0, 0.0, 1.0]), 0.0)
        u = np.asarray(law.axis)
        uu = u[:, None] * u[None, :]
        cap, z = law.friction_capacity_n, law.friction_state
        k_a = law.axial_gradient_n_per_m + cap * (1.0 - abs(z)) / law.dahl_length_m + z * law.friction_capacity_gradient_n_per_m
        k_l = self.lateral_stiffness_n_per_m()
        k = (k_l - max(k_a, 0.0)) * uu - k_l * _EYE3
        return ContactTangent(f, k, np.zeros((3, 3)), -u, self._radius, needle=law)

    def needle_state(self) -> dict:
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


SkinModel.TOOL_MODELS["needle"] = NeedleSkin
SkinModel.TOOL_WARM_UPS["needle"] = needle_warm_up
