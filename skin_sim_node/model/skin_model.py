"""``SkinModel``: the stateful layered skin model (section II.D.4) over the numba kernels.

It packs its configuration into the kernels' arrays (:mod:`.layout`) and chooses its form once
(:class:`~.paper.PaperForm` or :class:`~.layered.LayeredForm`: a tick kernel and a tangent). A layer
with a degenerate wave speed (:data:`DEGENERATE_RETURN_S`) is released from rest by the model itself.

The force path (:meth:`SkinModel.step`) never touches the grid; the per-layer grids
and the assembled surface/interface heights are built only when
:meth:`SkinModel.build_grid` is called (the first "no more than a scene needs" lever).
The other levers are switched by ``cfg.lod`` (``lod.*`` parameters): adaptive mode count,
affected layers only, patch-only grid work, and idle (no kernel call at rest).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from .config import TissueConfig
from .contact import ContactTangent, Indenter
from .grid import assemble_heights, assemble_heights_box, layer_field_box_rot, patch_box
from .interfaces import interface_depths_m
from .layered import LayeredForm
from .layout import (
    FLAG_CONTACT,
    FLAG_OFF_SHEET,
    IS_ACTIVE,
    IS_DRIVEN,
    IS_LEVEL,
    LS_AMP,
    LS_COMP,
    LS_CX,
    LS_CY,
    LS_DROPPED,
    LS_FE,
    LS_THICK,
    OUT_DEPTH_M,
    OUT_FORCE_N,
    OUT_FX,
    OUT_FZ,
    OUT_HOLD,
    OUT_N_AFFECTED,
    OUT_NX,
    OUT_NZ,
    OUT_RADIUS_M,
    OUT_SETTLED,
    OUT_STRESS_PA,
    OUT_T,
    Form,
    pack,
    settle_tolerance_m,
)
from .modal import ModalBasis, modal_basis
from .modal_kernels import layer_point_displacement_rot, modal_energy, surface_at
from .paper import PaperForm

DEGENERATE_RETURN_S = 1.0
"""A layer whose fundamental mode needs longer than this for a quarter period (``pi / (2 lambda_11)``)
to return has a degenerate wave speed: skin visibly recovers from an indent well within a second,
while the paper's eq 9 (``lambda_11 = 0.0032 rad/s``) takes 490 s. Such a layer is released from
rest (``B*_mn = 0``, as eq 9 itself), since with no restoring force in human time a release velocity
``v`` would carry it ``v / lambda_11`` (31 m at 0.1 m/s) away."""


def quarter_periods_s(basis: ModalBasis) -> np.ndarray:
    """Each layer's return time: the quarter period ``pi / (2 lambda_11)`` of its fundamental (s); inf for
    ``lambda_11 = 0``."""
    lam11 = basis.lam.min(axis=1)  # each layer's fundamental, rad/s
    with np.errstate(divide="ignore"):
        return np.where(lam11 > 0, 0.5 * math.pi / lam11, math.inf)


@dataclass(frozen=True)
class Grid:
    """Views of the model's grid buffers (valid until the next ``build_grid``).

    ``displacement_m[l]`` is layer l's downward displacement; ``heights_m[0]`` the surface
    height and ``heights_m[j]`` the height of the top of layer j (z up, rest surface 0).
    Rows are y (``ys_m``), columns x (``xs_m``).
    """

    xs_m: np.ndarray
    ys_m: np.ndarray
    displacement_m: np.ndarray
    heights_m: np.ndarray


class SkinModel:
    """Three-layer skin under a rigid tool: Reuss force and modal wave-equation deformation.

    Parameters
    ----------
    cfg : TissueConfig
        A validated configuration (see :func:`skin_sim_node.model.config.config_from_flat`).
    indenter : Indenter, optional
        The rigid tip that presses it (its radius and shape); default the configuration's punch
        (``tool.radius_m``, ``tool.shape``). A tool (:mod:`skin_sim_node.tools`) passes its own.

    Notes
    -----
    Frame: x, y in the tissue plane with the sheet centred on the origin, z up, rest
    surface at z = 0; the tool depth is ``-z``. The reaction force acts along +z.
    """

    def __init__(self, cfg: TissueConfig, indenter: Indenter | None = None):
        self.cfg = cfg
        self.indenter = Indenter.of(cfg) if indenter is None else indenter
        self.basis: ModalBasis = modal_basis(cfg, self.indenter.radius_m)
        lod = cfg.lod
        self._skip_settled = lod.affected_layers
        self._settle_tol = settle_tolerance_m(cfg)
        self._idle_ok = lod.idle
        self._patch_only = lod.patch_only
        self.kernel_calls = 0  # tick kernel invocations (idle ticks make none)
        self.idle_ticks = 0
        self.last_tick_idle = False
        self.version = 0  # changes whenever the state may have changed (a kernel call or a reset)
        self.grid_builds = 0
        sx, sy = cfg.sheet_size_m
        self._half = (0.5 * sx, 0.5 * sy)
        self._patch = cfg.patch_size_m
        self._turn = (math.cos(cfg.anisotropy_angle_rad), math.sin(cfg.anisotropy_angle_rad))  # the patch along the lines
        # the kernels' grouped arguments (.layout), with named views of the state
        self._arrays = arrays = pack(cfg, self.basis, self.indenter)
        self.q, self.v, self._prop = arrays.mstate[0], arrays.mstate[1], arrays.mstate[2:6]
        self.compression_m = arrays.lstate[LS_COMP]
        self.dropped_m = arrays.lstate[LS_DROPPED]  # displacement bound shed with outer modes since last driven
        self.amplitude_bound_m = arrays.lstate[LS_AMP]  # bound on a free layer's future displacement; inf when driven
        self.centre = arrays.lstate[LS_CX : LS_CY + 1].T  # (L, 2) view
        self.memory = arrays.lstate[LS_FE : LS_THICK + 1]  # layered form: elastic force, Prony arms, thickness
        self.driven = arrays.istate[IS_DRIVEN]
        self.level = arrays.istate[IS_LEVEL]  # index into basis levels (mode count) per layer
        self.active = arrays.istate[IS_ACTIVE]
        self._sx_buf, self._sy_buf = arrays.sbuf[0], arrays.sbuf[1]
        self._out = arrays.out
        self.flags = 0
        # the form, chosen once: its tick kernel and its tangent
        self._form: Form = LayeredForm(arrays, cfg) if cfg.form == "layered" else PaperForm(arrays, cfg)
        # degenerate layers (DEGENERATE_RETURN_S) are released from rest: only then does a tick copy the state
        quarter_s = quarter_periods_s(self.basis)
        self._degenerate = quarter_s > DEGENERATE_RETURN_S
        self._degenerate_layers = tuple(la.name for la, d in zip(cfg.layers, self._degenerate) if d)
        self._slowest_return_s = float(quarter_s.max())
        self._released = np.zeros(len(cfg.layers), dtype=bool)  # layers release() let go since the last tick
        self._tick = self._tick_releasing_from_rest if self._degenerate_layers else self._form.tick
        self._allocate_grid()
        self.reset()

    def _allocate_grid(self) -> None:
        """The grid buffers of :meth:`build_grid`: cell centres, rest depths of the layer tops, fields and scratch."""
        cfg, b = self.cfg, self.basis
        n_l = len(cfg.layers)
        ny, nx = cfg.grid_shape
        sx, sy = cfg.sheet_size_m
        self.xs = -0.5 * sx + (np.arange(nx) + 0.5) * sx / nx
        self.ys = -0.5 * sy + (np.arange(ny) + 0.5) * sy / ny
        X, Y = np.meshgrid(self.xs, self.ys)
        self._rest_tops = np.concatenate([np.zeros((1, ny, nx)), interface_depths_m(cfg, X, Y)])
        self._disp = np.zeros((n_l, ny, nx))
        self._heights = np.zeros((n_l, ny, nx))
        assemble_heights(self._disp, self._rest_tops, self._heights)
        self._dirty = np.zeros((n_l, 4), dtype=np.int64)  # per layer: written box ix0, ix1, iy0, iy1
        m_max = n_max = int(b.m_lim.max())
        self._q_dense = np.zeros((m_max, n_max))
        self._sx = np.zeros((m_max + 1, nx))
        self._sy = np.zeros((n_max + 1, ny))
        self._tmp = np.zeros((n_max + 1, nx))
        self._used = [
            (b.m_used[b.m_used <= lim], b.n_used[b.n_used <= lim]) for lim in b.m_lim
        ]  # distinct m, n of each level's prefix

    @property
    def degenerate_layers(self) -> tuple[str, ...]:
        """Names of the layers with a degenerate wave speed (:data:`DEGENERATE_RETURN_S`), released from rest;
        empty if none."""
        return self._degenerate_layers

    @property
    def slowest_return_s(self) -> float:
        """The largest quarter period ``pi / (2 lambda_11)`` of the layers' fundamentals (s); inf for a layer with
        ``lambda_11 = 0``."""
        return self._slowest_return_s

    def reset(self) -> None:
        """Return to rest: no contact, no deformation."""
        for a in (
            self.q,
            self.v,
            self.centre,
            self.compression_m,
            self._out,
            self.amplitude_bound_m,
            self.dropped_m,
            self.memory,
        ):
            a[...] = 0.0
        self._out[OUT_NZ] = 1.0
        self.driven[:] = 0
        self.level[:] = 0
        self.active[:] = 0 if self._skip_settled else 1
        self._released[:] = False
        self.flags = 0
        self._out[OUT_SETTLED] = 1.0 if self._settle_tol > 0.0 else 0.0
        self.version = getattr(self, "version", 0) + 1

    @property
    def settled(self) -> bool:
        """No layer driven and every layer's displacement bound below ``lod.tolerance_m`` (as of the last kernel call)."""
        return bool(self._out[OUT_SETTLED])

    def modes_per_axis(self) -> np.ndarray:
        """Modes per axis each layer currently uses (its level)."""
        return self.basis.level_modes[self.level]

    def release(self) -> None:
        """End contact now: every layer relaxes freely from its current shape and velocity (a degenerate layer
        from its shape at rest, on the next :meth:`step`). The friction's anchor is kept for the next contact on the
        same spot (a stall or a teleport is not a lift-off; :mod:`.friction`)."""
        if self._degenerate_layers:
            self._released |= self.driven.astype(bool)
        self.driven[:] = 0
        self._out[OUT_T] = 0.0
        self._out[OUT_HOLD] = 2.0  # the tool did not leave: the friction's anchor waits for it (layered form)

    def step(self, tool_xyz, tool_velocity, dt: float, restart: bool = False) -> float:
        """Advance one tick with the tool at ``tool_xyz`` (m) moving at ``tool_velocity`` (m/s).

        Returns the normal reaction force magnitude in newtons (>= 0; along +z in the paper form,
        along :attr:`contact_normal` in the layered form, whose full vector with friction is
        :attr:`force_vector_n`). ``dt`` (s) is the time since the previous tick; the release dynamics
        are exact for any ``dt >= 0`` and the layered form's chain is implicit (passive for any ``dt``).
        ``restart``: contact restarts after an unknown time (a first pose, a stall past ``stall_hold_s``, a
        teleport), so the layered form's viscoelastic arms start relaxed.
        """
        x, y, z = tool_xyz
        if self._idle_ok and z >= 0.0 and self._out[OUT_SETTLED]:
            # idle: the tool is off the tissue and every layer has settled: no kernel work
            self.idle_ticks += 1
            self.last_tick_idle = True
            if self.flags & ~FLAG_OFF_SHEET:
                self._out[:OUT_SETTLED] = 0.0
                self._out[OUT_FX : OUT_T + 1] = 0.0  # the friction's anchor (OUT_ZX..) is tissue state: kept
                self._out[OUT_NZ] = 1.0
                self.compression_m[:] = 0.0
            self.flags = 0 if abs(x) <= self._half[0] and abs(y) <= self._half[1] else FLAG_OFF_SHEET
            return 0.0
        vx, vy, vz = tool_velocity
        self.kernel_calls += 1
        self.version += 1
        self.last_tick_idle = False
        self.flags = self._tick(x, y, z, vx, vy, vz, dt, restart)
        return float(self._out[OUT_FORCE_N])

    def _tick_releasing_from_rest(self, x, y, z, vx, vy, vz, dt, restart=False) -> int:
        """The form's tick, for a tissue with degenerate layers: one released this tick (by the tick or by
        :meth:`release` since the last one) restarts from its last driven shape at rest (eq 9's ``B* = 0``),
        advanced over the tick with its exact modal propagator."""
        driven_before = self.driven.astype(bool) | self._released
        q_before = self.q.copy()
        flags = self._form.tick(x, y, z, vx, vy, vz, dt, restart)
        self._released[:] = False
        for li in np.flatnonzero(driven_before & ~self.driven.astype(bool) & self._degenerate):
            self.q[li] = self._prop[0, li] * q_before[li]
            self.v[li] = self._prop[2, li] * q_before[li]
        return flags

    # --- state read-outs -------------------------------------------------------------
    @property
    def force_n(self) -> float:
        """Normal force magnitude (N) of the last step (what :meth:`step` returns)."""
        return float(self._out[OUT_FORCE_N])

    @property
    def force_vector_n(self) -> np.ndarray:
        """Reaction force vector on the tool (N, tissue frame) of the last step: along the contact
        normal plus friction in the layered form, ``(0, 0, force_n)`` in the paper form."""
        return self._out[OUT_FX : OUT_FZ + 1].copy()

    @property
    def contact_normal(self) -> np.ndarray:
        """Unit contact normal of the last step (``+z`` out of contact)."""
        return self._out[OUT_NX : OUT_NZ + 1].copy()

    @property
    def contact_radius_m(self) -> float:
        """Contact radius (m) of the last step; 0 out of contact."""
        return float(self._out[OUT_RADIUS_M])

    @property
    def stress_pa(self) -> float:
        """Contact stress of the last tick (Pa): force over the loaded area (eq 6)."""
        return float(self._out[OUT_STRESS_PA])

    @property
    def depth_m(self) -> float:
        """Tool depth used by the Reuss split (clamped at the bottom), 0 out of contact."""
        return float(self._out[OUT_DEPTH_M])

    @property
    def n_affected(self) -> int:
        """Number of layers the last tick moved (the affected-layers lever leaves the rest at rest)."""
        return int(self._out[OUT_N_AFFECTED])

    @property
    def in_contact(self) -> bool:
        """True if the last tick had the tool in contact (``FLAG_CONTACT``)."""
        return bool(self.flags & FLAG_CONTACT)

    def tangent(self) -> ContactTangent:
        """The force of the last step and its local derivatives (see :mod:`.contact`).

        Paper form: the engaged layers are springs and dampers in series under the common
        velocity of eq 6, so ``dF/dz = -A_0 / sum(A_i / k_i)`` and
        ``dF/dv_z = -A_0 sum(b_i / k_i) / sum(A_i / k_i)`` (from ``sigma`` in :func:`.paper.reuss_split`).

        Layered form: ``F = F_n (n - mu g)`` with ``g = v_t / sqrt(|v_t|^2 + v_s^2)`` and ``v_t`` the
        tool velocity in the tangent plane, so ``K = dF/dx = (n - mu g) grad(F_n)^T``, with ``grad F_n``
        from the backward-Euler chain at this tick's ``dt`` (the series tangent ``1 / sum(1 / G_i)``,
        ``G_i = k_i phi'(eps_i) + b_i / dt``, plus the thickness and contact-radius terms), and
        ``D = dF/dv = -mu F_n (I / r - v_t v_t^T / r^3) (I - n n^T)``; the normal force does not depend
        on the velocity argument (the chain's rates come from positions).
        """
        return self._form.tangent(self.flags)

    def layer_displacement_at(self, layer: int, x: float, y: float) -> float:
        """Current downward displacement (m) of one layer at ``(x, y)`` (eq 2 at a point)."""
        b = self.basis
        nk = b.k_prefix[self.level[layer]]
        return layer_point_displacement_rot(
            self.q[layer, :nk],
            self.centre[layer, 0],
            self.centre[layer, 1],
            b.mode_m[:nk],
            b.mode_n[:nk],
            self._patch[0],
            self._patch[1],
            *self._turn,
            float(x),
            float(y),
            self._sx_buf,
            self._sy_buf,
        )

    def surface_displacement_at(self, x: float, y: float) -> float:
        """Current downward surface displacement (m) at ``(x, y)``: sum over the active layers (eq 2, one kernel call:
        :func:`~.modal_kernels.surface_at`, about 1 us; the other tools' field at a tool, every tick, issue 32)."""
        a = self._arrays
        return surface_at(float(x), float(y), a.sp, a.blev, a.bk, a.mstate, a.lstate, a.istate, a.sbuf)

    def cross_section(self, xs, y: float) -> np.ndarray:
        """Heights (m, z up) of the surface and each layer top along ``xs`` at ``y``, shape (L, len(xs)).

        Evaluated pointwise, so it resolves interface detail finer than the grid.
        """
        xs = np.asarray(xs, dtype=float)
        disp = np.array([[self.layer_displacement_at(li, x, y) for x in xs] for li in range(self.q.shape[0])])
        rest = np.concatenate([np.zeros((1, xs.size)), interface_depths_m(self.cfg, xs, np.full_like(xs, y))])
        below = np.cumsum(disp[::-1], axis=0)[::-1]
        return -rest - below

    def energy(self) -> float:
        """Modal energy per unit modal mass, summed over layers (m^2/s^2)."""
        return float(modal_energy(self.q, self.v, self.basis.lam))

    def build_grid(self, layers=None) -> Grid:
        """Evaluate the per-layer displacement fields and assemble surface/interface heights.

        Parameters
        ----------
        layers : iterable of int, optional
            Layers to evaluate; the others are taken as zero (default: all).

        With ``lod.patch_only`` only the cells of each layer's patch are evaluated, and only
        the box covering this build's and the previous build's patches is cleared and
        re-assembled (elsewhere the heights are the rest heights already in the buffer); without
        it every sheet cell is evaluated and assembled. With ``lod.affected_layers`` a layer at
        rest is not evaluated.
        """
        b = self.basis
        ny, nx = self._disp.shape[1:]
        box = [nx, 0, ny, 0]  # union of the cells written now or last time
        self.grid_builds += 1
        for li in range(self.q.shape[0]):
            wanted = layers is None or li in layers
            at_rest = self._skip_settled and not self.active[li]
            d = self._dirty[li]
            if self._patch_only:
                if d[1] > d[0] and d[3] > d[2]:
                    self._disp[li, d[2] : d[3], d[0] : d[1]] = 0.0
                    _grow(box, d)
                d[:] = 0
                if not wanted or at_rest:
                    continue
                cx, cy = self.centre[li]
                (a, b_side), (c, s) = self._patch, self._turn
                ix0, ix1, iy0, iy1 = patch_box(self.xs, self.ys, cx, cy, a, b_side, c, s)
            else:
                if not wanted or at_rest:
                    self._disp[li] = 0.0
                    continue
                ix0, ix1, iy0, iy1 = 0, nx, 0, ny
            lv = self.level[li]
            nk = b.k_prefix[lv]
            m_used, n_used = self._used[lv]
            layer_field_box_rot(
                self.q[li, :nk],
                self.centre[li, 0],
                self.centre[li, 1],
                b.mode_m[:nk],
                b.mode_n[:nk],
                m_used,
                n_used,
                self._patch[0],
                self._patch[1],
                *self._turn,
                self.xs,
                self.ys,
                ix0,
                ix1,
                iy0,
                iy1,
                self._q_dense,
                self._sx,
                self._sy,
                self._tmp,
                self._disp[li],
            )
            d[:] = (ix0, ix1, iy0, iy1)
            _grow(box, d)
        if not self._patch_only:
            assemble_heights(self._disp, self._rest_tops, self._heights)
        elif box[1] > box[0] and box[3] > box[2]:
            assemble_heights_box(self._disp, self._rest_tops, box[0], box[1], box[2], box[3], self._heights)
        return Grid(self.xs, self.ys, self._disp, self._heights)

    # --- state hand-over (the session; the replay report's model at peak) -------------------
    _STATE = (
        "q",
        "v",
        "centre",
        "driven",
        "compression_m",
        "level",
        "dropped_m",
        "active",
        "amplitude_bound_m",
        "memory",
        "_out",
    )

    def state(self) -> dict:
        """A copy of the dynamic state (modal amplitudes, patch centres, mode levels, active set, outputs)."""
        return {"flags": self.flags, **{k: getattr(self, k).copy() for k in self._STATE}}

    def set_state(self, state: dict) -> None:
        """Restore a :meth:`state` copy of a model of the same configuration."""
        for k in self._STATE:
            getattr(self, k)[...] = state[k]
        self._released[:] = False
        self.flags = state["flags"]
        self.version += 1


def _grow(box: list, d) -> None:
    """Grow ``box`` (ix0, ix1, iy0, iy1) to cover ``d``."""
    box[0], box[1] = min(box[0], d[0]), max(box[1], d[1])
    box[2], box[3] = min(box[2], d[2]), max(box[3], d[3])


def warm_up(cfg: TissueConfig) -> None:
    """Compile (or load from numba's cache) every kernel and touch every code path once.

    Includes :meth:`SkinModel.tangent`, which the session calls in contact: left to the first press, loading its
    kernel from the cache stalled a live node's tick thread for 100 ms or more (seen in a native profile).
    """
    model = SkinModel(cfg)
    for i in range(60):
        d = 4e-3 * min(i, 30) / 30
        model.step((0.001 * i, 0.0, -d), (0.001, 0.0, -0.1), 1e-3)
        model.tangent()
    model.step((0.0, 0.0, 0.01), (0.0, 0.0, 0.5), 1e-3)
    model.step((0.0, 0.0, 0.01), (0.0, 0.0, 0.0), 2e-3)
    model.surface_displacement_at(0.0, 0.0)
    model.energy()
    model.build_grid()
