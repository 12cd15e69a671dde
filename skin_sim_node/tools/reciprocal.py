"""The load maps that make the two-tool coupling a potential's (issue 32): each tool's own depth in, its "load" out,
from its own relaxed static law. No rclpy.

Why. Tool ``i`` presses its own chain to ``e_i = d_i - w_i`` (:class:`~skin_sim_node.tools.hands.CoupledTool`): ``d_i``
its depth, ``w_i`` how far the other tool ``j`` lowers the surface under it. With ``w_i = G e_j`` (the heave kernel
``G``, one table for the pair, times the other's own depth) the static cross stiffnesses are ``-K_i G`` and
``-K_j G``, ``K`` each chain's tangent stiffness: unequal wherever the two chains are (a needle's tent and a pad, or
one chain pressed deeper: the layers stiffen with strain, 350 N/m secant at 0.25 mm, 570 N/m at 2 mm for a 2.5 mm
punch, :func:`static_law`). Unequal cross stiffnesses are a curl: a quasi-static loop of the needle's tent and a pad
through their two depths returned +2.30 uJ (0.01 mm/s, where each tool alone takes -1.88 uJ).

What. The coupling is written as contact mechanics writes it, the depths the gradient of a complementary energy of
the forces (Betti's reciprocity): ``d_i = e_i + dphi/dF_i`` with one function of the two relaxed forces for the pair,
``phi = G Psi_i(F_i) Psi_j(F_j)``, so

``w_i = G Psi_i'(F_i) Psi_j(F_j)``, ``F = F(e)`` each tool's relaxed static law at its own depth.

For any ``Psi`` the coupling then does no net work over a closed path: ``sum_i F_i dw_i = d(F . grad phi - phi)`` is
an exact differential, so over a slow loop what both tools take is their chains' own (each passive: its dampers and
Prony arms dissipate), and the relaxed static cross stiffnesses are equal. The chains' forces beyond the relaxed law
(rate-dependent) also meet ``w``; that is not a potential, and it is checked, not proven: every path and loop of
``skin-sim two-hands`` (1 mm/s and 5 mm/s) and the loops at 0.01 mm/s dissipate. ``Psi`` is chosen so that two tools in one state
feel the depth kernel, ``w_i = G e_j`` (what the FEM two-punch rows validate: ``skin-sim two-punch``):
``Psi Psi' = e(F)``, i.e. ``Psi = sqrt(2 H(F))``, ``H = int_0^F e dF`` the chain's complementary energy. Where the
states differ, reciprocity itself moves the lowering: ``K_i dw_i/de_j = K_j dw_j/de_i``, and these maps split it
evenly, by the square root of the two chains' stiffness ratio. An untouched 21 G needle (its tent's 277 N/m) beside a
2.5 mm punch pressed 1 / 2 mm feels the punch's lowering 1.31 / 1.54 x the depth kernel's (the punch's ``2 H / e^2``
is 658 N/m at 2 mm); an untouched punch beside the needle's tent 1.08 / 1.24 x. No measurement separates the two
states' split; the FEM reference has two equal punches in one state.

How. :func:`static_law` steps a fresh tool of the configuration at :data:`STATIC_DT_S` (the dampers and Prony arms
relax within a step, so the force is the relaxed law's: 433.7 N/m at 1 mm for the 2.5 mm punch, as 1.5 s of holding
gives) at :data:`LAW_DEPTHS_M`; :class:`LoadMap` tabulates ``p = Psi' = e / sqrt(2 H)`` at those forces, linear
between them, and ``Psi`` its exact integral (piecewise quadratic), so ``Psi'`` is exactly ``Psi``'s derivative along
the interpolated law and both are continuous (no jolt); past the last node ``p`` stays constant; ``Psi`` is odd (a
tool pulling the skin up, a needle's withdrawal, lifts the surface beside it by the same law). The coupling reads each
tool's own depth from its own field at its centre (:meth:`~skin_sim_node.tools.hands.SharedSkin.sources`), as the
depth kernel did.
"""

from __future__ import annotations

import bisect
import math

import numpy as np

from ..model import TissueConfig
from .base import DOWN, Tool, ToolPose

STATIC_DT_S = 1.0
"""The step (s) that reads a chain's relaxed law: over 3 x the slowest Prony arm's 0.28 s, and its backward Euler
passes relaxed through a step of any length (docs/model.md); stepped :data:`STATIC_STEPS` times per depth."""

STATIC_STEPS = 4
"""Steps per depth of :func:`static_law`: the relaxed force to 4 digits (the 1.5 s hold of a 1 mm/s press gives the
same 433.7 N/m at 1 mm for the 2.5 mm punch)."""

LAW_DEPTHS_M = tuple(k * 0.1e-3 for k in range(1, 31))
"""The depths (m) of the tabulated law, every 0.1 mm to 3 mm: the hands' working range (the issue's presses to 2 mm,
a needle's tent to its puncture at 3.2 mm); the load depth's slope ``p`` changes by under 2 % between nodes. Deeper, or
past a needle's puncture (the force falls), ``p`` stays at its last value."""


def static_law(tool_type: type[Tool], cfg: TissueConfig) -> tuple[np.ndarray, np.ndarray]:
    """The relaxed static law of a tool of ``cfg``: depths (m) and vertical forces (N), from 0, rising (read-only).

    A fresh tool (its own tissue) pressed straight down at the origin to each of :data:`LAW_DEPTHS_M`, each held
    :data:`STATIC_STEPS` steps of :data:`STATIC_DT_S`; the nodes stop where the force stops rising (a needle's
    puncture, a form whose force saturates). Cached per tool type and tissue (a few ms each)."""
    key = (tool_type, cfg)
    if key not in _LAWS:
        tool = tool_type(cfg)
        depths, forces = [0.0], [0.0]
        first = True
        for d in LAW_DEPTHS_M:
            f = 0.0
            for _ in range(STATIC_STEPS):
                pose = ToolPose((0.0, 0.0, -d), (0.0, 0.0, 0.0), DOWN, STATIC_DT_S, first)
                f = float(tool.step(pose).force_n[2])
                first = False
            if not (math.isfinite(f) and f > forces[-1]):
                break
            depths.append(d)
            forces.append(f)
        e_arr, f_arr = np.array(depths), np.array(forces)
        e_arr.setflags(write=False)
        f_arr.setflags(write=False)
        _LAWS[key] = (e_arr, f_arr)
    return _LAWS[key]


_LAWS: dict[tuple[type[Tool], TissueConfig], tuple[np.ndarray, np.ndarray]] = {}
_MAPS: dict[tuple[type[Tool], TissueConfig], LoadMap] = {}


class LoadMap:
    """``Psi`` and ``Psi' = dPsi/dF`` of one tool's relaxed law (module docstring), read at its own depth ``e``.

    The law's force ``F(e)`` is a monotone cubic between its nodes (:func:`static_law`; PCHIP tangents), so its slope,
    the chain's stiffness, is continuous: with a piecewise-linear law the coupling's two directions met different
    chord stiffnesses across a node, 2-3 % apart (an independent review's cross stiffnesses). ``Psi' = p`` is linear in
    ``F`` between the nodes (``p = e / sqrt(2 H)`` there, ``H`` by the trapezoid rule) and ``Psi`` its exact integral,
    so ``Psi'`` is exactly ``dPsi/dF`` along the law and both are continuous; ``Psi' Psi = e`` at the nodes to 0.2 %.
    Past the last node the law goes on along its last tangent and ``p`` stays constant; ``Psi`` is odd in ``e`` and
    ``Psi'`` even. Near ``e = 0`` ``p`` is the first segment's secant limit ``1 / sqrt(F_1 / e_1)``: exact for a law
    linear at the origin (flat tools, a needle's tent); a sphere's Hertzian start (``F ~ e^1.5``, ``p -> inf``) is
    met to 12 % below 0.2 mm (an independent review), to 0.2 % from 0.3 mm.

    Parameters
    ----------
    depths_m, forces_n : array_like
        The relaxed static law (:func:`static_law`): from (0, 0), depths and forces rising; at least one node past 0.
    """

    def __init__(self, depths_m, forces_n):
        from scipy.interpolate import PchipInterpolator

        e = np.asarray(depths_m, float)
        f = np.asarray(forces_n, float)
        if e.size < 2 or e[0] != 0.0 or f[0] != 0.0 or np.any(np.diff(e) <= 0) or np.any(np.diff(f) <= 0):
            raise ValueError("a load map needs a law rising from (0, 0)")
        comp = np.concatenate([[0.0], np.cumsum(0.5 * (e[1:] + e[:-1]) * np.diff(f))])  # H(F) = int_0^F e dF
        p = np.empty_like(e)
        p[1:] = e[1:] / np.sqrt(2.0 * comp[1:])
        p[0] = 1.0 / math.sqrt(f[1] / e[1])  # the small-force limit, 1 / sqrt(K_0): Psi ~ F / sqrt(K_0)
        psi = np.concatenate([[0.0], np.cumsum(0.5 * (p[1:] + p[:-1]) * np.diff(f))])
        tangents = PchipInterpolator(e, f).derivative()(e) if e.size > 2 else np.full(e.size, f[1] / e[1])
        self.depths_m = e.tolist()
        """The nodes' depths (m)."""
        self.forces_n = f.tolist()
        """The nodes' relaxed forces (N)."""
        self.stiffness_n_per_m = [float(t) for t in tangents]
        """The law's slope at the nodes (N/m): the cubic's tangents."""
        self.slopes = p.tolist()
        """``p = Psi'`` at the nodes (1 / sqrt(N/m))."""
        self.values = psi.tolist()
        """``Psi`` at the nodes (sqrt(N m)): the exact integral of the piecewise-linear ``p``."""

    def _locate(self, depth_m: float) -> tuple[int, float]:
        """The segment ``k`` of ``|depth_m|`` (the last one past the nodes) and the force there along the law (N)."""
        e, f, m = self.depths_m, self.forces_n, self.stiffness_n_per_m
        a = abs(depth_m)
        k = min(bisect.bisect_right(e, a) - 1, len(e) - 2)
        if a >= e[-1]:
            return len(e) - 1, f[-1] + m[-1] * (a - e[-1])
        h = e[k + 1] - e[k]
        t = (a - e[k]) / h
        t2, t3 = t * t, t * t * t
        lo = (2 * t3 - 3 * t2 + 1) * f[k] + (t3 - 2 * t2 + t) * h * m[k]  # cubic Hermite
        hi = (-2 * t3 + 3 * t2) * f[k + 1] + (t3 - t2) * h * m[k + 1]
        return k, lo + hi

    def force_n(self, depth_m: float) -> float:
        """The relaxed law's force at ``|depth_m|`` (N): the cubic, or its last tangent past the nodes."""
        return self._locate(depth_m)[1]

    def psi_and_slope(self, depth_m: float) -> tuple[float, float]:
        """``|Psi|`` and ``Psi'`` at the relaxed force of depth ``|depth_m|``, from one lookup (what :meth:`slope`,
        :meth:`value` and :meth:`ratio` read; a coupled tool keeps it per state of its field,
        ``CoupledTool.centre_load``)."""
        k, force = self._locate(depth_m)
        p, psi, f = self.slopes, self.values, self.forces_n
        u = force - f[k]
        if k == len(f) - 1:  # past the last node: p constant
            return psi[k] + p[k] * u, p[k]
        df = f[k + 1] - f[k]
        return psi[k] + (p[k] + 0.5 * (p[k + 1] - p[k]) * u / df) * u, p[k] + (p[k + 1] - p[k]) * u / df

    def slope(self, depth_m: float) -> float:
        """``Psi'`` at the relaxed force of depth ``depth_m`` (1 / sqrt(N/m), even)."""
        return self.psi_and_slope(depth_m)[1]

    def value(self, depth_m: float) -> float:
        """``Psi`` at the relaxed force of depth ``depth_m`` (sqrt(N m), odd)."""
        return math.copysign(self.psi_and_slope(depth_m)[0], depth_m)

    def ratio(self, depth_m: float) -> float:
        """``Psi / Psi'`` at depth ``depth_m`` (N, for ``depth_m`` >= 0): a tool's load ``L`` in its lateral force."""
        v, slope = self.psi_and_slope(depth_m)
        return v / slope

    def lowering(self, own_depth_m: float, other: LoadMap, other_depth_m: float) -> float:
        """``Psi_i'(e_i) Psi_j(e_j)`` (m): how far another tool at its own depth ``other_depth_m`` lowers the surface
        under this one at ``own_depth_m``, over the pair's kernel ``G``; ``e_j`` when the two are in one state."""
        return self.slope(own_depth_m) * other.value(other_depth_m)


def load_map(tool_type: type[Tool], cfg: TissueConfig) -> LoadMap:
    """The :class:`LoadMap` of a tool of ``cfg`` (:func:`static_law`; shared by every tissue of that tool)."""
    key = (tool_type, cfg)
    if key not in _MAPS:
        _MAPS[key] = LoadMap(*static_law(tool_type, cfg))
    return _MAPS[key]
