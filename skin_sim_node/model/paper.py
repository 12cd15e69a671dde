"""The ``paper`` form: the paper's model as stated (Fig 3 engagement, the common velocity of eq 6, eq 9).

Layers the tool reaches (Fig 3) share the depth by the iso-stress (Reuss) split of Kelvin-Voigt
elements with one common velocity (eqs 4-8, Table I, with the typos corrected: docs/model.md);
each engaged layer's membrane takes the indentation shape of its compression (eq 3), the others
return freely (eq 2, eq 9). Kernels in the style of :mod:`.modal_kernels`, each tested compiled and
as ``.py_func`` against :mod:`skin_sim_lab.oracles.reference`; :class:`PaperForm` binds them to one
model's arrays.
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit

from .config import TissueConfig
from .contact import ContactTangent, normal_tangent
from .layout import (
    AUX_BOUNDS,
    AUX_SPLIT,
    AUX_THICK,
    FLAG_BOTTOMED,
    FLAG_CONTACT,
    FLAG_LAYER_BOUND,
    FLAG_SEPARATED,
    LP_AREA,
    LP_B,
    LP_IF_AMP,
    LP_IF_KX,
    LP_IF_KY,
    LP_IF_MEAN,
    LP_K,
    LS_COMP,
    OUT_FORCE_N,
    OUT_N_AFFECTED,
    SP_BOTTOM,
    SP_TOOL_R,
    Form,
    KernelArrays,
)
from .modal_kernels import begin_tick, drive_layer, end_tick, relax_layer


@njit(cache=True, nogil=True)
def layer_bounds(x, y, iface_mean, iface_amp, iface_kx, iface_ky, bottom_m, out_bounds):
    """Depths of the layer tops at ``(x, y)`` and of the bottom: the egg-carton interfaces (section II.C).

    ``d_j(x, y) = D_j - A_j cos(kx_j x) cos(ky_j y)``.

    Parameters
    ----------
    x, y : float
        Point (m).
    iface_mean, iface_amp : ndarray, shape (L - 1,)
        Interface mean depths ``D_j`` and amplitudes ``A_j`` (m).
    iface_kx, iface_ky : ndarray, shape (L - 1,)
        ``2 pi / wavelength`` of each interface in x and y (1/m).
    bottom_m : float
        Depth of the bottom (m).
    out_bounds : ndarray, shape (L + 1,)
        Written: ``[0]`` the surface (0), ``[1..L-1]`` the interfaces, ``[L]`` the bottom (m, down).
    """
    out_bounds[0] = 0.0
    for j in range(iface_mean.shape[0]):
        out_bounds[j + 1] = iface_mean[j] - iface_amp[j] * math.cos(iface_kx[j] * x) * math.cos(iface_ky[j] * y)
    out_bounds[iface_mean.shape[0] + 1] = bottom_m


@njit(cache=True, nogil=True)
def count_affected(depth_m, bounds):
    """Number of layers whose top lies above the tool tip (Fig 3): the first ``n`` are affected.

    Parameters
    ----------
    depth_m : float
        Tool depth (m, down).
    bounds : ndarray, shape (L + 1,)
        :func:`layer_bounds`.

    Returns
    -------
    int
        ``n`` in ``0..L``.
    """
    n = 0
    for i in range(bounds.shape[0] - 1):
        if depth_m > bounds[i]:
            n += 1
    return n


@njit(cache=True, nogil=True)
def reuss_split(n, depth_m, velocity_m_s, k, b, area, thickness, out_comp):
    """Iso-stress (Reuss) split of ``depth_m`` over the first ``n`` Kelvin-Voigt layers (eqs 4-8, Table I).

    From eq 4 (equal stress) and eq 6 (``sigma = (k_i dx_i + b_i xdot) / A_i``, common
    ``xdot``) with ``sum dx_i = depth``::

        sigma = (depth + xdot * sum(b_i / k_i)) / sum(A_i / k_i)
        dx_i  = (sigma * A_i - b_i * xdot) / k_i

    A compression outside ``[0, thickness_i]`` is held at that bound and the rest of
    the depth is split over the remaining layers (active set, at most n passes). The force on the
    tool is the stress transmitted through the stack times the top layer's area,
    ``sigma A_0`` (= ``k_0 dx_0 + b_0 xdot`` while the top layer is within its bounds).

    Parameters
    ----------
    n : int
        Affected layers (:func:`count_affected`).
    depth_m : float
        Tool depth (m).
    velocity_m_s : float
        Common normal velocity ``xdot`` into the tissue (m/s, eq 6).
    k, b, area : ndarray, shape (L,)
        Springs (N/m), dampers (N s/m) and areas (m^2) of eq 6.
    thickness : ndarray, shape (L,)
        Layer thicknesses under the tool (m).
    out_comp : ndarray, shape (L,)
        Written: the compressions ``dx_i`` of the first ``n`` layers (m).

    Returns
    -------
    stress_pa : float
        The common stress ``sigma`` (Pa).
    force_n : float
        ``sigma A_0`` (N); 0 for ``n = 0``.
    hit_bound : bool
        A compression was held at a bound.
    """
    fixed = 0  # bit i set: layer i held at a bound
    hit = False
    sigma = 0.0
    for _ in range(n + 1):
        rest = depth_m
        s_a = 0.0
        s_b = 0.0
        for i in range(n):
            if fixed >> i & 1:
                rest -= out_comp[i]
            else:
                s_a += area[i] / k[i]
                s_b += b[i] / k[i]
        if s_a <= 0.0:
            break
        sigma = (rest + velocity_m_s * s_b) / s_a
        worst = -1
        worst_excess = 0.0
        for i in range(n):
            if not fixed >> i & 1:
                c = (sigma * area[i] - b[i] * velocity_m_s) / k[i]
                out_comp[i] = c
                excess = max(-c, c - thickness[i])
                if excess > worst_excess:
                    worst_excess = excess
                    worst = i
        if worst < 0:
            break
        hit = True
        fixed |= 1 << worst
        out_comp[worst] = 0.0 if out_comp[worst] < 0.0 else thickness[worst]
    if n > 0 and fixed == (1 << n) - 1:
        # every layer at a bound (tool at the bottom): the stiffest layer's stress carries it
        sigma = 0.0
        for i in range(n):
            sigma = max(sigma, (k[i] * out_comp[i] + b[i] * velocity_m_s) / area[i])
    force = sigma * area[0] if n > 0 else 0.0
    return sigma, force, hit


@njit(cache=True, nogil=True)
def paper_step_kernel(
    tool_x, tool_y, tool_z, tool_vz, dt, lp, sp, bmodes, bvec, blev, bk, mstate, lstate, istate, aux, sbuf, out
):
    """One haptic tick of the paper form: contact, Reuss force and modal state (section II.D.4, steps 1-5).

    Layers the tool affects (Fig 3) are driven quasi-statically (eq 3: ``q = dx_l beta``, centred on the
    tool, :func:`~.modal_kernels.drive_layer`) with their share of the common velocity (eq 6); the others
    evolve freely with the exact damped modal propagator (eq 2, eq 9: release and return,
    :func:`~.modal_kernels.relax_layer`). Contact is unilateral and tested against the current deformed
    surface (:func:`~.modal_kernels.begin_tick`).

    Level of detail: layer ``l`` uses the first ``k_prefix[level[l]]`` modes; with several levels
    (adaptive modes) a driven layer takes the smallest level whose truncation bound is within the
    mode tolerance. With ``settle_tol > 0`` a free layer's displacement bound is kept; with
    ``skip_settled`` a layer below ``settle_tol`` is set to rest and skipped while inactive.

    Parameters
    ----------
    tool_x, tool_y, tool_z : float
        Tool tip (m, tissue frame, z up; the depth is ``-tool_z``).
    tool_vz : float
        Tool velocity along z (m/s); ``-tool_vz`` is the common velocity of eq 6.
    dt : float
        Time since the previous tick (s).
    lp, sp, bmodes, bvec, blev, bk, mstate, lstate, istate, aux, sbuf, out : ndarray
        The grouped arrays (:mod:`.layout`); the state and ``out`` (``OUT_*``) are written.

    Returns
    -------
    int
        The step flags (``FLAG_*``).
    """
    n_layers = istate.shape[1]
    flags, was_contact, surface, touching = begin_tick(
        tool_x, tool_y, tool_z, dt, sp, bmodes, bvec, blev, bk, mstate, lstate, istate, sbuf
    )
    depth = -tool_z
    velocity = -tool_vz
    n = 0
    force = 0.0
    sigma = 0.0
    d_eff = 0.0
    bounds = aux[AUX_BOUNDS]
    thick = aux[AUX_THICK, :n_layers]
    split = aux[AUX_SPLIT, :n_layers]
    if touching:
        ni = n_layers - 1
        layer_bounds(
            tool_x, tool_y, lp[LP_IF_MEAN, :ni], lp[LP_IF_AMP, :ni], lp[LP_IF_KX, :ni], lp[LP_IF_KY, :ni], sp[SP_BOTTOM], bounds
        )
        d_eff = depth
        if depth > bounds[n_layers]:
            d_eff = bounds[n_layers]
            flags |= FLAG_BOTTOMED
        n = count_affected(d_eff, bounds)
        for li in range(n_layers):
            thick[li] = bounds[li + 1] - bounds[li]
        sigma, force, hit = reuss_split(n, d_eff, velocity, lp[LP_K], lp[LP_B], lp[LP_AREA], thick, split)
        if hit:
            flags |= FLAG_LAYER_BOUND
        if force <= 0.0 or sigma <= 0.0:
            touching = False
            force = 0.0
            sigma = 0.0
            flags |= FLAG_SEPARATED
    if touching:
        flags |= FLAG_CONTACT
    else:
        n = 0
    for li in range(n_layers):
        if li < n:
            share = split[li] / d_eff  # layer's part of the tool velocity (common velocity, eq 6); round-off safe
            drive_layer(
                li,
                split[li],
                velocity * min(1.0, max(0.0, share)),
                tool_x,
                tool_y,
                sp,
                bmodes,
                bvec,
                blev,
                mstate,
                lstate,
                istate,
            )
        else:
            lstate[LS_COMP, li] = 0.0
            relax_layer(li, dt, sp, bmodes, bvec, blev, mstate, lstate, istate)
    radius = sp[SP_TOOL_R] if touching else 0.0
    end_tick(force, sigma, d_eff, n, surface, 0.0, 0.0, force, 0.0, 0.0, 1.0, radius, sp, lstate, istate, out)
    return flags


class PaperForm(Form):
    """The paper form bound to one model's kernel arrays (:class:`~.layout.Form`)."""

    name = "paper"

    def __init__(self, arrays: KernelArrays, cfg: TissueConfig):
        super().__init__(arrays, cfg)
        self._k, self._b, self._area = arrays.lp[LP_K], arrays.lp[LP_B], arrays.lp[LP_AREA]
        self._radius = float(arrays.sp[SP_TOOL_R])  # the indenter's (pack)

    def tick(self, x, y, z, vx, vy, vz, dt, restart=False) -> int:
        """:func:`paper_step_kernel`; only the normal velocity ``vz`` enters (eq 6)."""
        return paper_step_kernel(float(x), float(y), float(z), float(vz), float(dt), *self._args)

    def tangent(self, flags: int) -> ContactTangent:
        """Force and derivatives of the last tick (``flags``: its flags), along ``+z`` only.

        The engaged layers are springs and dampers in series under the common velocity of eq 6, so
        ``dF/dz = -A_0 / sum(A_i / k_i)`` and ``dF/dv_z = -A_0 sum(b_i / k_i) / sum(A_i / k_i)`` (from
        ``sigma`` in :func:`reuss_split`).
        """
        n = int(self._out[OUT_N_AFFECTED]) if flags & FLAG_CONTACT else 0
        if n == 0:
            return normal_tangent(0.0, 0.0, 0.0, 0.0)
        s_a = float(np.sum(self._area[:n] / self._k[:n]))
        s_b = float(np.sum(self._b[:n] / self._k[:n]))
        a0 = float(self._area[0])
        return normal_tangent(float(self._out[OUT_FORCE_N]), a0 / s_a, a0 * s_b / s_a, self._radius)
