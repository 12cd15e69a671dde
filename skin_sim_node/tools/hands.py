"""Two hands on one skin (issue 32): N tools pressing one tissue, each through its own series chain. No rclpy.

The tissue's membranes are linear (eq 2: the wave equation of each layer, with its foundation), so the deformation under
several contacts is the sum of each contact's own modal field. Each tool keeps the modal field it drives (its own
:class:`~skin_sim_node.model.SkinModel`, centred where it presses, with its chain, friction anchor, viscoelastic arms,
edge footprint, anisotropic patch and, for a needle, its track), and the sum of the fields is the one tissue
(:meth:`SharedSkin.surface_displacement_at`, :meth:`SharedSkin.heights_m`, :meth:`SharedSkin.cross_section`).

The coupling: each tool's chain (eq 6) acts at a surface that includes the others' deflection. Tool ``i`` at depth
``d_i`` below the rest surface, where the others have lowered the surface by ``w_i``, presses its own field to ``e_i =
d_i - w_i``: its step runs at ``z_i + w_i`` (:class:`CoupledTool`). Tool ``j`` (a flat punch or finger pad, a sphere, a
needle) gives ``w_i = G_ij(s) Psi_i'(e_i) Psi_j(e_j)``: the heave kernel at the centres' distance
(:mod:`~skin_sim_node.model.heave`: the skin is nearly incompressible and bonded to a base, so it rises 5-15 mm beside a
contact, as the 3D reference does) times the pair's load maps at the two tools' own depths, each read from its own field
at its centre (:mod:`~skin_sim_node.tools.reciprocal`: the gradient of one complementary energy ``G Psi_i Psi_j``, so
the coupling does no net work over a closed path and the cross stiffnesses are equal, Betti; in one state ``Psi_i' Psi_j
= e_j``, the depth kernel the FEM two-punch rows validate). The kernel is **one table for both directions**
(:func:`couples_by_kernel`, ``_table``): the mean of each tool's footprint profile (its kernel's indenter: a flat tool's
radius, a needle's own 0.41 mm for 21 G, a sphere's contact disk at 1 mm) read over the other's receiving disk (a flat
tool's radius, a sphere's disk, a needle's point). With the depth kernel alone (``w_i = G e_j``) the cross stiffnesses
were ``-K_i G`` and ``-K_j G``, and a quasi-static loop (0.01 mm/s) of a needle's tent and a pad returned 2.3 uJ; with
the load maps it takes -2.00 uJ, the two chains' own dissipation (``skin-sim two-hands --loop``, docs/two_hands.md).
Only the paper form, whose membranes carry almost no tension and so no heave
(:func:`~skin_sim_node.model.heave.uses_kernel`), reads the other tool's own field at tool ``i``'s place, ``u_j(x_i,
y_i)``, both ways (not reciprocal). A finger pressing 3 mm from a needle's entry lowers the skin there, so the needle's
dimple starts lower and its puncture comes later along the needle's travel; 6 mm out the skin stands higher and the
puncture comes earlier (``skin-sim two-hands``, docs/two_hands.md).

Order: the tools step one after another (each tick of each hand, when its pose arrives), each reading the others'
fields as they stand (the Gauss-Seidel order of a partitioned solve). The loop gain of the coupling is about
``g_ij g_ji``, ``g_ij = dw_i / de_j`` (about ``G`` times the chains' tangent over secant stiffness, 1.1-1.2; for two
2.5 mm punches ``G`` is at most 0.084, held inside the overlap, and -0.038 / -0.072 / -0.055 at 6 / 8 / 10 mm), so the
iteration contracts at every distance.

Overlap rule (:func:`overlap_hold_m`, :data:`OVERLAP_EASE_M`): where two footprints overlap (centres closer than the
sum of their kernel radii: a flat tool's radius, a needle's 0.41 mm, a sphere's disk at 1 mm) the kernel is held from
where they touch inward, its slope eased to 0 over 0.5 mm; where large footprints touch in each other's heave, from
where the kernel crosses zero instead, so overlapping tools never raise each other. The superposed kernel there (0.25
of the depth at 4 mm for two 2.5 mm punches) counts the shared lens twice, where the reference's pair (one rigid body
of the union footprint) implies 0.067-0.072, and with the load maps' tangent gain it would pass 1 near coincidence
(two tools snapping into one's share). Held and eased, the kernel and its slope are continuous, so the vertical and
the lateral forces have no jolt (tests/test_hands.py sweeps the distance through ``r_1 + r_2`` to 0); at 4 mm it gives
0.084 (the FEM rows at 4 mm: interaction +10 / +21 % of the FEM's, docs/validation/two_punch.md). Two coincident tools
are not one tool: each keeps its chain (two hands cannot hold one place).

The local contact model a device renders (:class:`~skin_sim_node.model.ContactTangent`) is this tool's, with positions
in the tissue frame (the friction anchor lowered back by ``w_i``), the coupling's lateral force ``L_i grad(w_i)`` in
its force (:meth:`CoupledTool.step`), and the coupling to first order: ``K`` gains ``K[:, 2] grad(w_i)^T`` (moving
sideways along the others' slope) and ``grad(w_i) K[2, :]`` (the lateral force following the load), and
``coupling_rate_n_per_s = K[:, 2] dw_i/dt`` is
the other tools' own motion, which the bridge renders for at most one server period (docs/two_hands.md).

Not modelled: the heave in the drawn surface (the display sums the tools' own fields, which only dent), and contact
between two overlapping flat disks beyond the held kernel (the overlap rule above).

Limit: :data:`MAX_HANDS` tools.
"""

from __future__ import annotations

import math
from collections.abc import Sequence

import numpy as np

from ..model import SkinModel
from ..model.grid import assemble_heights
from ..model.heave import TABLE_STEP_M, coupling_table, uses_kernel
from ..model.interfaces import interface_depths_m
from .base import Tool, ToolPose, ToolStep, evolve
from .reciprocal import LoadMap, load_map

MAX_HANDS = 2
"""Most tools one tissue takes. Two hands is the clinical scene (a hand anchoring or palpating beside a tool in the
other, issue 32). The bound is the machine's, not the model's: each hand's device path costs about half a core at
1 kHz with rclpy here (docs/performance.md: a bare echo alone is 56 % of a core), so two hands fill a 2-core machine
(``skin-sim bench-device --hands 2``: node and both bridges take 79-90 % of a core in one process, 116-124 % as three,
docs/two_hands.md); the coupling itself reads each other tool's field once per tick and its kernel at up to four
places (``skin-sim two-hands``' cost study)."""


CONTINUOUS_STEP_S = 0.02
"""A tool's step longer than this (s) is a jump of its field, not its motion: a gap stepped in parts (``max_dt_s``
parts, 0.1 s by default) or a stall's resume, at a server rate down to 50 Hz. The other tools' coupling rate is not
taken across it (:meth:`CoupledTool.step`): a device would extrapolate the jump once more."""

SLOPE_STEP_M = 10e-6
"""The finite-difference step of the other fields' slope under a tool (m): the model's displacement accuracy
(``lod.tolerance_m`` default) in depth is reached over millimetres of the fields' decay, so 10 um resolves the slope
with a relative error of order 1e-3 and stays far above round-off (1e-16 m on a 1e-4 m field)."""


SPHERE_DEPTH_M = 1e-3
"""The depth (m) at which a sphere's footprint is taken for the kernel: its Hertz contact radius ``sqrt(R d)`` at the
issue's shallower press (1 mm; 2.24 mm for a 5 mm ball, 3.16 mm at 2 mm). The kernel's footprint is fixed per pair (one
table); the depth-dependent part of a sphere's coupling, its stiffness, is in its load map
(:mod:`~skin_sim_node.tools.reciprocal`). Beyond a few millimetres the heave depends little on the footprint's radius
(a 2.5 mm punch's and a 5 mm pad's kernels at 8 mm: -0.072 and -0.081 of the depth)."""


def _footprint_m(cfg, radius_m: float) -> float:
    """A sphere's kernel footprint radius (m, :data:`SPHERE_DEPTH_M`) or ``radius_m``."""
    return math.sqrt(cfg.tool_radius_m * SPHERE_DEPTH_M) if cfg.tool_shape == "sphere" else radius_m


def receiver_radius_m(cfg) -> float:
    """The radius (m) of the disk over which a tool of ``cfg`` feels another's heave: a flat tool's radius, a sphere's
    footprint (:data:`SPHERE_DEPTH_M`); 0 (its point) for a needle, whose contact is its tip."""
    return 0.0 if cfg.tool_shape == "needle" else _footprint_m(cfg, cfg.tool_radius_m)


def couples_by_kernel(a_cfg, b_cfg) -> bool:
    """Whether two tools couple through the heave kernel: on membranes that carry tension
    (:func:`~skin_sim_node.model.heave.uses_kernel`, of both: the pair's one table serves both directions). Any two
    tools do (flat, sphere, needle); the paper form's membranes do not."""
    return uses_kernel(a_cfg) and uses_kernel(b_cfg)


def source_radius_m(tool: Tool) -> float:
    """The radius (m) of the footprint whose heave a tool spreads: its kernel's indenter (a flat tool's radius, a
    needle's own radius: its field is a punch of that radius pressed to the dimple's depth; a sphere's footprint,
    :data:`SPHERE_DEPTH_M`)."""
    return _footprint_m(tool.cfg, type(tool).indenter(tool.cfg).radius_m)


def _table(receiver: Tool, source: Tool) -> tuple[float, list[float]]:
    """The reciprocal kernel of a pair: the mean of the two directions'
    :func:`~skin_sim_node.model.heave.coupling_table` (each one's footprint, :func:`source_radius_m`, read over the
    other's receiving disk, :func:`receiver_radius_m`), its step (m) and values; the same for ``(i, j)`` and ``(j, i)``."""
    s, g_ij = coupling_table(source.cfg, source_radius_m(source), receiver_radius_m(receiver.cfg))
    _, g_ji = coupling_table(receiver.cfg, source_radius_m(receiver), receiver_radius_m(source.cfg))
    g = 0.5 * (g_ij + g_ji)
    hold = overlap_hold_m(s, g, source_radius_m(source) + source_radius_m(receiver))
    if hold > 0.0:  # overlapping footprints: held, its slope eased to 0 over OVERLAP_EASE_M (module docstring)
        g_hold = float(np.interp(hold, s, g))
        slope = (float(np.interp(hold + TABLE_STEP_M, s, g)) - g_hold) / TABLE_STEP_M  # from outside
        b = min(OVERLAP_EASE_M, hold)
        u = np.clip(s - (hold - b), 0.0, b)  # 0 inside the ease, b at the hold
        inside = s < hold
        g[inside] = g_hold - slope / (2 * b) * (b * b - u[inside] ** 2)
    return float(s[1] - s[0]), g.tolist()


OVERLAP_EASE_M = 0.5e-3
"""Over this distance inside the hold (m) the held kernel's slope eases from the kernel's own to 0 (a quadratic), so
the kernel and its slope are continuous and so are the coupling's vertical and lateral forces (``L grad(w)``: a kink
in the kernel is a step in the lateral force, 28 mN in one tick at 5 mm/s where two 2.5 mm punches touch). 0.5 mm is
the smallest of 0.25, 0.5 and 1 mm whose overlap sweep (``skin-sim two-hands``, study 3) stays below one punch's
per-tick change pressing in at the same speed (4.1 mN: 5.7, 2.9 and 1.5 mN); the wider the ease, the higher the held
value (0.051 + 0.17 b / 2 for two 2.5 mm punches). It was chosen by the sweep; it also moves the FEM's 4 mm rows
(interaction +9 / +23 % of the FEM's with it, -32 / -23 % with the flat hold), which were seen before the choice.
Session 13 gave the reference's overlapping single a mesh conforming to its disk and solved the reference one mesh
level finer (level -1, converged within 0.001 of level 0 there): the rows are +10 / +21 % with it."""


def overlap_hold_m(s, g, touch_m: float) -> float:
    """Where a pair's kernel ``g`` (at distances ``s``) is held for every distance inside: where the two footprints
    touch (``touch_m``, the sum of their kernel radii) if the kernel lowers the skin there, else where it crosses zero
    inside that (large footprints touch in each other's heave: overlapping, they would raise each other, 20 % more
    force for two coincident 5 mm pads); 0 if it never does."""
    if np.interp(touch_m, s, g) >= 0.0:
        return touch_m
    inside = np.flatnonzero((s < touch_m) & (g >= 0.0))
    if inside.size == 0:
        return 0.0
    k = int(inside[-1])  # the last distance inside that lowers; the next one raises
    return float(s[k] + (s[k + 1] - s[k]) * g[k] / (g[k] - g[k + 1]))


class SharedSkin:
    """One tissue pressed by several tools: the sum of their modal fields (module docstring).

    Parameters
    ----------
    tools : sequence of Tool
        The tools, each with its own tissue (:func:`~skin_sim_node.tools.make_tool` of its configuration); the
        configurations share the tissue (layers, sheet, patch) and differ in the tool (``tool.*``, ``needle.*``).

    Attributes
    ----------
    hands : tuple of CoupledTool
        Each tool behind the seam, coupled to the others: give ``hands[i]`` to hand ``i``'s session.
    """

    def __init__(self, tools: Sequence[Tool]):
        if not 1 <= len(tools) <= MAX_HANDS:
            raise ValueError(f"a tissue takes 1 to {MAX_HANDS} tools, got {len(tools)}")
        first = tools[0].cfg
        for t in tools[1:]:
            if t.cfg.sheet_size_m != first.sheet_size_m or len(t.cfg.layers) != len(first.layers):
                raise ValueError("the tools of one tissue need the same sheet and layers")
        self.hands = tuple(CoupledTool(t, self, i) for i, t in enumerate(tools))
        self._heave: list[list[tuple[float, list[float]] | None]] = [
            [_table(dst, src) if j != i and couples_by_kernel(dst.cfg, src.cfg) else None for j, src in enumerate(tools)]
            for i, dst in enumerate(tools)
        ]
        """``_heave[i][j]``: how far tool ``j`` lowers the surface under tool ``i`` over its own depth, by the centres'
        distance: the pair's table (the same for ``[j][i]``), its step (m) and values (a list: the tick reads two
        entries of it); None: ``j``'s own field is read."""
        for h, row in zip(self.hands, self._heave):
            if any(table is not None for table in row):  # on the kernel with another: its load map
                h.load_map = load_map(type(h.inner), h.cfg)

    @property
    def tissues(self) -> tuple[SkinModel, ...]:
        """Each tool's own modal field (its :class:`~skin_sim_node.model.SkinModel`)."""
        return tuple(h.tissue for h in self.hands)

    def others_displacement_at(self, i: int, x: float, y: float) -> float:
        """Downward surface displacement (m) under tool ``i`` at ``(x, y)`` from every tool but ``i``: ``w_i``.

        A tool ``j`` on the kernel with tool ``i`` (both on membranes that carry tension: :func:`couples_by_kernel`)
        lowers it by the two load maps at their own depths (:mod:`~skin_sim_node.tools.reciprocal`) times the pair's
        kernel (:mod:`~skin_sim_node.model.heave`:
        the skin rises beside a contact, so ``w_i`` turns negative 5-15 mm out); any other tool by its own field at
        ``(x, y)``. A field at rest (no active layer) adds nothing and costs nothing.
        """
        return self.displacement_from(self.sources(i), x, y)

    def sources(self, i: int) -> list[tuple]:
        """What the other tools' fields are now, for :meth:`displacement_from` (one tool's step reads them at up to
        four places, and they do not change within it): per active other tool, ``(load, x_j, y_j, table_step, table)``
        for a pair on the kernel (``Psi_i'(e_i) Psi_j(e_j)``, the two load maps at each one's own depth at its centre,
        and the pair's kernel, :meth:`others_displacement_at`) or ``(tissue,)`` for another."""
        out: list[tuple] = []
        me = self.hands[i]
        slope: float | None = None  # this tool's Psi' at its own depth: read once, for every other tool on the kernel
        for j, h in enumerate(self.hands):
            if j == i or not h.tissue.active.any():
                continue
            table = self._heave[i][j]
            if table is not None:
                if h._xy is not None and me.load_map is not None and h.load_map is not None:
                    xj, yj = h._xy
                    if slope is None:
                        slope = me.centre_load()[2] if me._xy is not None else me.load_map.slope(0.0)
                    e_j, psi_j, _ = h.centre_load()
                    delta = slope * math.copysign(psi_j, e_j)  # LoadMap.lowering, from the tools' cached reads
                    if math.isfinite(delta):  # a field gone non-finite (its session resets it) never reaches another
                        out.append((delta, xj, yj, *table))
            else:
                out.append((h.tissue,))
        return out

    @staticmethod
    def displacement_from(sources: list[tuple], x: float, y: float) -> float:
        """``w`` at ``(x, y)`` from :meth:`sources` (m, downward): each kernel source's load times the pair's kernel,
        interpolated linearly on its uniform table (zero past its end), each other source's own field there."""
        w = 0.0
        for src in sources:
            if len(src) == 1:
                u = src[0].surface_displacement_at(x, y)
                if math.isfinite(u):
                    w += u
                continue
            delta, xj, yj, step, g = src
            t = math.hypot(x - xj, y - yj) / step
            if t < len(g) - 1:  # past the table (or infinitely far): nothing; a NaN place: NaN, as np.interp gives
                k = int(t)
                w += delta * (g[k] + (t - k) * (g[k + 1] - g[k]))
            elif t != t:
                w = math.nan
        return w

    def others_time_s(self, i: int) -> tuple[float, float]:
        """The other tools' stepped time (s, summed) and the time of their last jump (s, the latest): what
        :meth:`CoupledTool.step` needs to take the others' field change as a rate over *their* motion."""
        t = jump = 0.0
        for j, h in enumerate(self.hands):
            if j != i:
                t += h.time_s
                jump = max(jump, h.jump_time_s)
        return t, jump

    def surface_displacement_at(self, x: float, y: float) -> float:
        """Downward surface displacement (m) of the one tissue at ``(x, y)``: every tool's field."""
        return sum(h.tissue.surface_displacement_at(x, y) for h in self.hands if h.tissue.active.any())

    def heights_m(self) -> np.ndarray:
        """Heights (m, z up) of the surface and each layer top on the sheet's grid, shape ``(L, ny, nx)``: every
        field's layer displacements summed (linear membranes), assembled as one tissue's (section II.D.4, step 6)."""
        base = self.hands[0].tissue
        disp = np.zeros_like(base.build_grid().displacement_m)
        for h in self.hands:
            disp += h.tissue.build_grid().displacement_m
        out = np.empty_like(disp)
        assemble_heights(disp, base._rest_tops, out)  # the rest heights every field shares
        return out

    def cross_section(self, xs, y: float) -> np.ndarray:
        """Heights (m, z up) of the surface and each layer top along ``xs`` at ``y``, shape ``(L, len(xs))``: every
        field's layer displacements summed (as :meth:`SkinModel.cross_section` for one)."""
        xs = np.asarray(xs, dtype=float)
        base = self.hands[0].tissue
        rest = np.concatenate([np.zeros((1, xs.size)), interface_depths_m(base.cfg, xs, np.full_like(xs, y))])
        disp = np.zeros((rest.shape[0], xs.size))
        for h in self.hands:
            t = h.tissue
            disp += np.array([[t.layer_displacement_at(li, x, y) for x in xs] for li in range(rest.shape[0])])
        return -rest - np.cumsum(disp[::-1], axis=0)[::-1]


class CoupledTool(Tool):
    """A tool of a :class:`SharedSkin`: its own step at a surface lowered by the other tools' fields.

    Parameters
    ----------
    inner : Tool
        The tool (its physics and its own field).
    skin : SharedSkin
    index : int
        Its place in ``skin.hands``.
    """

    def __init__(self, inner: Tool, skin: SharedSkin, index: int):  # no Tool.__init__: the inner tool has the tissue
        self.inner = inner
        self.cfg = inner.cfg
        self.tissue = inner.tissue
        self.needs = inner.needs  # type: ignore[misc]  # the inner tool's declaration, on the instance
        self.skin = skin
        self.index = index
        self.shift_m = 0.0
        """The others' deflection ``w_i`` at the last step (m, downward)."""
        self.shift_rate_m_s = 0.0
        """Its rate over the last step at this tool's place (m/s): how fast the other tools lowered (or raised) it."""
        self._xy: tuple[float, float] | None = None  # this tool's place at the last step
        self.time_s = 0.0
        """Model time this tool has stepped (s, the sum of its steps' ``dt_s``)."""
        self.jump_time_s = 0.0
        """:attr:`time_s` at its last jump (a restart, a release or reset, a step over :data:`CONTINUOUS_STEP_S`)."""
        self._seen: tuple[float, float] | None = None  # the others' (time, jump time) at this tool's last step
        self.load_map: LoadMap | None = None
        """Its :class:`~skin_sim_node.tools.reciprocal.LoadMap` when it couples to another by the kernel (set by the
        :class:`SharedSkin`)."""
        self._centre: tuple | None = None  # (tissue, its version, place, e, |Psi|, Psi'): centre_load's last read

    def step(self, pose: ToolPose) -> ToolStep:
        """The inner tool's step at ``z + w_i``; its record, with positions back in the tissue frame, the coupling's
        lateral force and the coupling in its tangent.

        The lateral force is ``L_i grad(w_i)`` (:meth:`lateral_load_n`): the pair's complementary energy depends on
        the centres' distance, so a tool on the others' slope is pushed down it (toward a neighbour's dimple, away
        from its heave); without it a tool sliding a closed loop beside another took energy from the tissue (+34 uJ
        at 0.05 mm/s, an independent review). To first order: ``K`` gains ``K[:, 2] grad(w_i)^T`` (moving sideways
        along the slope changes this tool's own depth) and ``grad(w_i) K[2, :]`` in its lateral rows (the lateral
        force follows the load), and :attr:`ContactTangent.coupling_rate_n_per_s` is ``K[:, 2] dw_i/dt`` at this
        tool's place (the other tools' own motion, which a device renders for one server period)."""
        x, y, z = pose.position_m
        self.time_s += max(pose.dt_s, 0.0)
        if pose.restart or pose.dt_s > CONTINUOUS_STEP_S:
            self.jump_time_s = self.time_s
        sources = self.skin.sources(self.index)  # the others' fields do not change within this step

        def others(px: float, py: float) -> float:
            return self.skin.displacement_from(sources, px, py)

        w = others(x, y)
        prev, prev_xy, self.shift_m, self._xy = self.shift_m, self._xy, w, (x, y)
        seen, self._seen = self._seen, self.skin.others_time_s(self.index)
        if w == 0.0 and prev == 0.0:
            self.shift_rate_m_s = 0.0
            return self.inner.step(pose)
        s = self.inner.step(evolve(pose, position_m=(x, y, z + w)))
        # the other fields' change at this tool's last place (its own sideways motion is in K), over the time the others
        # stepped since (their motion, not this tool's tick: a burst of one hand's answers is not a fast other hand);
        # none across a jump of theirs or of this tool's
        elapsed = self._seen[0] - seen[0] if seen is not None else 0.0
        jumped = seen is None or self._seen[1] > seen[0] or pose.restart or pose.dt_s > CONTINUOUS_STEP_S
        if elapsed > 0.0 and not jumped and prev_xy is not None:
            here_then = others(prev_xy[0], prev_xy[1]) if prev_xy != (x, y) else w
            self.shift_rate_m_s = (here_then - prev) / elapsed
        else:
            self.shift_rate_m_s = 0.0
        t = s.tangent
        fz = float(s.force_n[2])
        if t is None and not fz > 0.0:
            return s
        gx = (others(x + SLOPE_STEP_M, y) - w) / SLOPE_STEP_M
        gy = (others(x, y + SLOPE_STEP_M) - w) / SLOPE_STEP_M
        if not (math.isfinite(gx) and math.isfinite(gy)):
            return s
        changes: dict = {}
        if fz > 0.0:  # the lateral force of the coupling's potential: d phi / d x_i = L_i grad(w_i)
            load = self.lateral_load_n(fz, x, y)
            force = np.array(s.force_n, dtype=float)
            force[0] += load * gx
            force[1] += load * gy
            changes["force_n"] = force
        if t is None:
            return evolve(s, **changes)
        # in plain floats (nine entries: NumPy's per-call cost is most of a tick's coupling), in NumPy's order
        (k00, k01, k02), (k10, k11, k12), (k20, k21, k22) = np.asarray(t.stiffness_n_per_m, dtype=float).tolist()
        k00 += k02 * gx  # moving sideways along the others' slope changes this tool's own depth: K[:, 0:2] += K[:, 2] g^T
        k10 += k12 * gx
        k20 += k22 * gx
        k01 += k02 * gy
        k11 += k12 * gy
        k21 += k22 * gy
        k00 += gx * k20  # the lateral force follows the load, to first order (L ~ F_z): K[0:2, :] += g K[2, :]
        k01 += gx * k21
        k02 += gx * k22
        k10 += gy * k20
        k11 += gy * k21
        k12 += gy * k22
        rate = self.shift_rate_m_s
        tangent: dict = {
            "stiffness_n_per_m": np.array(((k00, k01, k02), (k10, k11, k12), (k20, k21, k22))),
            "coupling_rate_n_per_s": np.array((k02 * rate, k12 * rate, k22 * rate)),
        }
        if t.friction_anchor_m is not None:
            anchor = np.array(t.friction_anchor_m, dtype=float)
            anchor[2] -= w
            tangent["friction_anchor_m"] = anchor
        return evolve(s, tangent=evolve(t, **tangent), **changes)

    def centre_load(self) -> tuple[float, float, float]:
        """This tool's own field's depth ``e`` (m) at its place of the last step, with ``|Psi(e)|`` and ``Psi'(e)`` of
        its load map (:mod:`~skin_sim_node.tools.reciprocal`); needs a place and a load map.

        Read once per state of its field (:attr:`SkinModel.version` changes with every kernel call, reset or restored
        state; a release or an idle step leaves the field as it was): a coupled tick needs it three times (its own
        lateral load, its next step's load map, the other tool's step), and each read is a kernel call and a law
        lookup. The values are those of :meth:`SkinModel.surface_displacement_at` and :meth:`LoadMap.psi_and_slope`, unchanged."""
        t = self.tissue
        c = self._centre
        if c is None or c[0] is not t or c[1] != t.version or c[2] != self._xy:
            assert self._xy is not None and self.load_map is not None
            e = t.surface_displacement_at(*self._xy)
            psi, p = self.load_map.psi_and_slope(e)
            c = self._centre = (t, t.version, self._xy, e, psi, p)
        return c[3], c[4], c[5]

    def lateral_load_n(self, force_z_n: float, x: float, y: float) -> float:
        """``L_i = Psi_i(e_i) / Psi_i'(e_i)`` (N): what turns the others' slope under this tool into its lateral force,
        ``L_i grad(w_i)``, the derivative of the pair's complementary energy ``G Psi_i Psi_j`` in this tool's place
        (:mod:`~skin_sim_node.tools.reciprocal`), ``e_i`` its own field's depth at ``(x, y)``; the vertical force
        ``force_z_n`` for a linear law, and without a load map (the paper form: the others' own fields)."""
        m = self.load_map
        if m is None:
            return force_z_n
        if (x, y) == self._xy:  # its place of this step: the read the next ticks' load maps take too
            e, psi, p = self.centre_load()
        else:
            e = self.tissue.surface_displacement_at(x, y)
            psi, p = m.psi_and_slope(e)
        if not (math.isfinite(e) and e > 0.0):
            return 0.0
        return psi / p  # LoadMap.ratio

    def release(self) -> None:
        self.inner.release()
        self.jump_time_s = self.time_s = self.time_s + CONTINUOUS_STEP_S  # its field jumps: no rate across it

    def reset(self) -> None:
        self.inner.reset()
        self.shift_m = self.shift_rate_m_s = 0.0
        self._xy = self._seen = None
        self.jump_time_s = self.time_s = self.time_s + CONTINUOUS_STEP_S

    def at_rest(self, step: ToolStep) -> ToolStep:
        return self.inner.at_rest(step)

    def readout(self) -> dict | None:
        return self.inner.readout()

    def state(self) -> dict:
        return self.inner.state()

    def describe(self) -> str:
        """One line: which tool this hand holds."""
        return f"hand {self.index}: {self.cfg.tool_shape}"
