"""The ``layered`` form (issue 11): every layer in series from first contact.

Still the paper's method - iso-stress (Reuss, eq 4) through Kelvin-Voigt layers (eq 6) and a modal
membrane per layer (eqs 1-3) - with four changes (docs/model.md, "The layered form"):

1. All layers under the tool act in series from first contact (no Fig 3 engagement), each with the
   thickness that the egg-carton interfaces (section II.C) have *averaged over the contact disk*
   (:func:`~.layered_contact.averaged_bounds`), so the heterogeneity is a smooth few-percent modulation, not jumps.
2. A strain-stiffening compression law per layer (:func:`~.layered_law.compression_law`),
   ``f_i = EA_i phi(c_i / h_i)``, ``phi(eps) = ((1 - eps)^-n - 1) / n``, which grows without bound
   as the compression ``c_i`` approaches the thickness ``h_i``; past the wall strain it continues
   along its tangent, so the bottom is a stiff wall and never a clamp.
3. A true series Kelvin-Voigt chain: each layer has its own rate, ``F / s = f_i(c_i) + b_i cdot_i``
   for every layer and ``sum c_i = d``, integrated by backward Euler (:func:`~.layered_law.chain_solve`), which
   is passive for any ``dt``.
4. Presliding friction of tool positions along the tangent plane of the deformed surface (issue 30,
   :mod:`.friction`: the skin sticks to the tool, stretches with it up to ``mu F_n``, then slips), and a flat or
   spherical tip (Hertz contact radius ``a = sqrt(R d)``, load ``C (2/3) sqrt(d/R)`` of the punch's).

Cut by job: the constitutive chain (1-3: :func:`~.layered_law.compression_law`, :func:`~.layered_law.chain_solve`,
the Prony arms) is :mod:`.layered_law`, the contact (the disk-averaged bounds, the tip's geometry, the force's
Jacobians) :mod:`.layered_contact`; this module holds the tick (:func:`layered_step_kernel`, the recovery out of
contact) that composes them with the membranes of :mod:`.modal_kernels`, and :class:`LayeredForm`, which binds it to
one model's arrays. The kernels are ``@njit(cache=True, nogil=True)``, allocate nothing and are tested compiled and
as ``.py_func`` against the NumPy/SciPy reference in :mod:`skin_sim_lab.oracles.reference`.
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit

from .calibration import BONE_STRAIN
from .config import TissueConfig
from .contact import ContactTangent, normal_tangent
from .friction import presliding_step, presliding_tangent
from .layered_contact import averaged_bounds, contact_geometry
from .layered_law import (
    DT_FLOOR_S,
    chain_solve,
    clear_memory,
    compression_law,
    layer_compression,
    prony_commit,
    prony_prepare,
)
from .layout import (
    AUX_BOUNDS,
    AUX_C,
    AUX_C_OLD,
    AUX_DBD,
    AUX_DBX,
    AUX_DBY,
    AUX_EA,
    AUX_G,
    AUX_OFF,
    AUX_THICK,
    FLAG_BOTTOMED,
    FLAG_CONTACT,
    FLAG_LAYER_BOUND,
    FLAG_OFF_SHEET,
    FLAG_SEPARATED,
    IS_ACTIVE,
    IS_DRIVEN,
    LP_B,
    LP_EA,
    LP_G1,
    LP_G2,
    LP_N,
    LS_COMP,
    LS_CX,
    LS_CY,
    LS_FE,
    LS_THICK,
    OUT_ANCHORED,
    OUT_DFN_DX,
    OUT_DFN_DY,
    OUT_DFN_DZ,
    OUT_FORCE_N,
    OUT_FX,
    OUT_FZ,
    OUT_HOLD,
    OUT_NX,
    OUT_NY,
    OUT_NZ,
    OUT_RADIUS_M,
    OUT_SLIP_M,
    OUT_T,
    OUT_ZX,
    OUT_ZY,
    OUT_ZZ,
    SP_BOTTOM,
    SP_HALF_X,
    SP_HALF_Y,
    SP_K_T,
    SP_MODE_TOL,
    SP_MU,
    SP_SPHERE,
    SP_TOOL_R,
    SP_WALL,
    Form,
    KernelArrays,
)
from .modal_kernels import begin_tick_reach, drive_layer, end_tick, footprint, layer_at, relax_layer

RATE_CAP_M_S = 3.0
"""Largest layer rate handed to a membrane (m/s): the node's default tool speed cap (``max_tool_speed_m_s``;
hands rarely exceed 2 m/s). A faster chain rate comes from a pose jump, not motion, and would set a
released membrane ringing; the force path is not capped."""


@njit(cache=True, nogil=True)
def recover_layers(dt, restart, lp, sp, bmodes, bvec, blev, mstate, lstate, istate, ea_eff, off):
    """Out of contact: each layer recovers along its chain law at zero force (viscoelastic arms included), its
    membrane driven at the last contact's centre; once every compression is below a tenth of ``lod.tolerance_m``
    the memory is cleared and the layers relax freely (eq 2), as they do with no memory.

    Recovery after a held press is the standard linear solid's: an elastic part at once (at the Kelvin-Voigt
    rate ``b / k``), the rest as the arms relax (``tau_1``, ``tau_2``).

    Parameters
    ----------
    dt : float
        Step (s).
    restart : bool
        The arms are relaxed (the tool's history is unknown).
    lp, sp, bmodes, bvec, blev, mstate, lstate, istate : ndarray
        The grouped arrays (:mod:`.layout`); the layers' state is written.
    ea_eff, off : ndarray, shape (>= L,)
        Scratch for :func:`prony_prepare`.
    """
    nl = lstate.shape[1]
    wall = sp[SP_WALL]
    if lstate[LS_THICK, 0] > 0.0:
        prony_prepare(lp, lstate, dt, restart, ea_eff, off)
        dt_eff = max(dt, DT_FLOOR_S)
        done = True
        for li in range(nl):
            h = lstate[LS_THICK, li]
            c_old = lstate[LS_COMP, li]
            beta = lp[LP_B, li] / dt_eff
            c, _ = layer_compression(-off[li], ea_eff[li], lp[LP_N, li], beta, c_old, h, wall, c_old)
            prony_commit(lp, lstate, li, c, h, wall, dt, restart)
            rate = min(RATE_CAP_M_S, max(-RATE_CAP_M_S, (c - c_old) / dt_eff))
            drive_layer(li, c, rate, lstate[LS_CX, li], lstate[LS_CY, li], sp, bmodes, bvec, blev, mstate, lstate, istate)
            istate[IS_DRIVEN, li] = 0  # recovering, not in contact: the next contact test is against the surface
            if abs(c) > 0.1 * sp[SP_MODE_TOL]:
                done = False
        if not done:
            return
        for li in range(nl):
            clear_memory(lstate, li)
    for li in range(nl):
        lstate[LS_COMP, li] = 0.0
        relax_layer(li, dt, sp, bmodes, bvec, blev, mstate, lstate, istate)


@njit(cache=True, nogil=True)
def layered_step_kernel(
    tool_x,
    tool_y,
    tool_z,
    tool_vx,
    tool_vy,
    tool_vz,
    dt,
    restart,
    lp,
    sp,
    bmodes,
    bvec,
    blev,
    bk,
    mstate,
    lstate,
    istate,
    aux,
    sbuf,
    out,
):
    """One haptic tick of the layered form: series chain force, friction, tangent and modal state.

    Arguments as :func:`~.paper.paper_step_kernel` plus the tool's velocity, which no part of the force reads (the
    chain's rates come from the positions and ``dt``, the friction is a law of positions: :mod:`.friction`). Contact is unilateral
    and tested against the current deformed surface (:func:`~.modal_kernels.begin_tick_reach`); at the sheet's edge the
    force is scaled by the contact disk's fraction on the sheet (:func:`~.modal_kernels.footprint`), and the layers are
    driven at that part's centroid. At first contact the
    chain starts from each layer's current displacement under the tool and the contact normal is
    fixed from the deformed surface's slope there (central differences over 5 um); while in contact
    every layer is driven with its own compression and rate (eq 3: ``q = c_l beta``, ``v = cdot_l
    beta``); out of contact (or when the chain relaxing with zero force is shorter than the tool
    depth) the layers recover: each follows its chain law at zero force, viscoelastic arms included
    (:func:`prony_prepare`), driving its membrane at the last contact's centre, until every compression is below
    a tenth of ``lod.tolerance_m``; then they relax freely. A new contact on the recovering spot (within the
    contact radius of its centre) continues from the recovering compressions and arms; elsewhere the material
    under the tool starts with no viscoelastic memory. Friction (:func:`~.friction.presliding_step`): a contact
    starts its anchor at the tool, except after :meth:`SkinModel.release` (``OUT_HOLD``: a stall or a teleport) when
    the tool lands within the contact radius of the old anchor, which it keeps; a true lift-off clears it.
    Writes ``out`` (``OUT_*``: force vector, normal, contact radius, anchor,
    gradient of the normal force, and ``OUT_T``/normal carried to the next tick).

    Parameters
    ----------
    tool_vx, tool_vy, tool_vz : float
        Tool velocity (m/s): unused (kept in the signature of the forms' tick kernels).
    restart : bool
        Contact restarts (the first pose, after a stall past ``stall_hold_s`` or a teleport): the Prony arms are relaxed.
    tool_x, tool_y, tool_z, dt, lp, sp, bmodes, bvec, blev, bk, mstate, lstate, istate, aux, sbuf, out
        As :func:`~.paper.paper_step_kernel`, which also returns the step flags.
    """
    nl = istate.shape[1]
    flags, was_contact, surface, touching = begin_tick_reach(
        tool_x, tool_y, tool_z, dt, sp[SP_TOOL_R], sp, bmodes, bvec, blev, bk, mstate, lstate, istate, sbuf
    )
    frac = 1.0  # the footprint: fraction of the contact disk on the sheet, its derivatives, its centroid
    dfrac_x = 0.0
    dfrac_y = 0.0
    dfrac_a = 0.0
    foot_x = tool_x
    foot_y = tool_y
    depth = -tool_z
    force_n = 0.0
    t = 0.0
    a = 0.0
    s = 1.0
    ds = 0.0
    bounds = aux[AUX_BOUNDS]
    thick = aux[AUX_THICK, :nl]
    c_old = aux[AUX_C_OLD, :nl]
    c_new = aux[AUX_C, :nl]
    g = aux[AUX_G, :nl]
    ea_eff = aux[AUX_EA, :nl]
    off = aux[AUX_OFF, :nl]
    wall = sp[SP_WALL]
    has_memory = False  # viscoelastic arms: the layers recover after contact; without them they relax freely at once
    for li in range(nl):
        if lp[LP_G1, li] > 0.0 or lp[LP_G2, li] > 0.0:
            has_memory = True
    if touching:
        a, s, ds, da_dd = contact_geometry(depth, sp[SP_TOOL_R], sp[SP_SPHERE] > 0.0)
        frac, dfrac_x, dfrac_y, dfrac_a, foot_x, foot_y = footprint(tool_x, tool_y, a, sp[SP_HALF_X], sp[SP_HALF_Y])
        averaged_bounds(tool_x, tool_y, a, da_dd, lp, sp[SP_BOTTOM], bounds, aux[AUX_DBX], aux[AUX_DBY], aux[AUX_DBD])
        for li in range(nl):
            thick[li] = bounds[li + 1] - bounds[li]
        if was_contact:
            for li in range(nl):
                c_old[li] = lstate[LS_COMP, li]
        else:  # first contact: start from the deformed state under the tool, normal from its slope
            # on the recovering spot the chain continues from its compressions and arms; elsewhere no memory
            dxc = tool_x - lstate[LS_CX, 0]
            dyc = tool_y - lstate[LS_CY, 0]
            on_spot = lstate[LS_THICK, 0] > 0.0 and dxc * dxc + dyc * dyc <= a * a
            gx = 0.0
            gy = 0.0
            hstep = 5e-6
            for li in range(nl):
                c_old[li] = 0.0
                if istate[IS_ACTIVE, li]:
                    c_old[li] = layer_at(li, tool_x, tool_y, sp, blev, bk, mstate, lstate, istate, sbuf)
                    gx += layer_at(li, tool_x + hstep, tool_y, sp, blev, bk, mstate, lstate, istate, sbuf)
                    gx -= layer_at(li, tool_x - hstep, tool_y, sp, blev, bk, mstate, lstate, istate, sbuf)
                    gy += layer_at(li, tool_x, tool_y + hstep, sp, blev, bk, mstate, lstate, istate, sbuf)
                    gy -= layer_at(li, tool_x, tool_y - hstep, sp, blev, bk, mstate, lstate, istate, sbuf)
            gx /= 2.0 * hstep
            gy /= 2.0 * hstep
            for li in range(nl):
                if on_spot:
                    c_old[li] = lstate[LS_COMP, li]
                else:
                    clear_memory(lstate, li)
                    phi0, _ = compression_law(c_old[li] / thick[li], lp[LP_N, li], wall)
                    lstate[LS_FE, li] = lp[LP_EA, li] * phi0
            # surface height -U(x, y) (z up): outward normal ~ (dU/dx, dU/dy, 1)
            norm = math.sqrt(gx * gx + gy * gy + 1.0)
            out[OUT_NX] = gx / norm
            out[OUT_NY] = gy / norm
            out[OUT_NZ] = 1.0 / norm
            out[OUT_T] = 0.0
        prony_prepare(lp, lstate, dt, restart, ea_eff, off)
        t = chain_solve(depth, out[OUT_T], ea_eff, lp[LP_N], lp[LP_B], dt, c_old, thick, wall, off, c_new, g)
        if t <= 0.0:
            touching = False
            t = 0.0
            flags |= FLAG_SEPARATED
        if frac <= 0.0:  # the contact disk is off the sheet
            touching = False
            t = 0.0
            flags |= FLAG_OFF_SHEET
    nx = 0.0
    ny = 0.0
    nz = 1.0
    fx = 0.0
    fy = 0.0
    fz = 0.0
    dfx = 0.0
    dfy = 0.0
    dfz = 0.0
    if touching:
        flags |= FLAG_CONTACT
        if depth > sp[SP_BOTTOM]:
            flags |= FLAG_BOTTOMED
        force_n = frac * s * t  # the footprint: the load on the part of the disk that lies on the sheet
        # gradient of the normal force: dT = (dd + sum_i H_i dh_i / G_i) / S  (implicit function theorem)
        s_inv = 0.0
        sx = 0.0
        sy = 0.0
        sd = 0.0
        for li in range(nl):
            h = thick[li]
            eps = c_new[li] / h
            if eps > BONE_STRAIN:
                flags |= FLAG_LAYER_BOUND
            phi, dphi = compression_law(eps, lp[LP_N, li], wall)
            hh = -ea_eff[li] * dphi * eps / h  # d(residual)/dh at fixed c
            dhx = (aux[AUX_DBX, li] if li < nl - 1 else 0.0) - (aux[AUX_DBX, li - 1] if li > 0 else 0.0)
            dhy = (aux[AUX_DBY, li] if li < nl - 1 else 0.0) - (aux[AUX_DBY, li - 1] if li > 0 else 0.0)
            dhd = (aux[AUX_DBD, li] if li < nl - 1 else 0.0) - (aux[AUX_DBD, li - 1] if li > 0 else 0.0)
            s_inv += 1.0 / g[li]
            sx += hh * dhx / g[li]
            sy += hh * dhy / g[li]
            sd += hh * dhd / g[li]
        dfx = frac * s * sx / s_inv + s * t * dfrac_x
        dfy = frac * s * sy / s_inv + s * t * dfrac_y
        dfz = -(frac * (ds * t + s * (1.0 + sd) / s_inv) + s * t * dfrac_a * da_dd)
        nx = out[OUT_NX]
        ny = out[OUT_NY]
        nz = out[OUT_NZ]
        if not was_contact:  # a new contact: the skin under the tool is at rest (its anchor at the tool), unless it
            # was released without the tool leaving it (a stall, a teleport) and the tool is back on the same spot
            ex = tool_x - out[OUT_ZX]
            ey = tool_y - out[OUT_ZY]
            ez = tool_z - out[OUT_ZZ]
            en = ex * nx + ey * ny + ez * nz
            ex -= en * nx
            ey -= en * ny
            ez -= en * nz
            keep = out[OUT_HOLD] > 0.0 and out[OUT_ANCHORED] > 0.0 and ex * ex + ey * ey + ez * ez <= a * a
            if not keep:
                out[OUT_ZX] = tool_x
                out[OUT_ZY] = tool_y
                out[OUT_ZZ] = tool_z
        out[OUT_HOLD] = 0.0
        out[OUT_ANCHORED] = 1.0
        zx, zy, zz, ftx, fty, ftz, slip = presliding_step(
            tool_x, tool_y, tool_z, nx, ny, nz, out[OUT_ZX], out[OUT_ZY], out[OUT_ZZ], sp[SP_K_T], sp[SP_MU] * force_n
        )
        out[OUT_ZX] = zx
        out[OUT_ZY] = zy
        out[OUT_ZZ] = zz
        out[OUT_SLIP_M] = slip
        fx = force_n * nx + ftx
        fy = force_n * ny + fty
        fz = force_n * nz + ftz
        out[OUT_T] = t
        dt_eff = max(dt, DT_FLOOR_S)
        cap = RATE_CAP_M_S  # a law of positions: the tool's velocity does not cap it either (issue 30)
        for li in range(nl):
            prony_commit(lp, lstate, li, c_new[li], thick[li], wall, dt, restart)
            if has_memory:  # the layers recover along their law after contact (recover_layers)
                lstate[LS_THICK, li] = thick[li]
            rate = min(cap, max(-cap, (c_new[li] - c_old[li]) / dt_eff))  # each layer its own rate (series chain)
            drive_layer(li, c_new[li], rate, foot_x, foot_y, sp, bmodes, bvec, blev, mstate, lstate, istate)
    else:
        out[OUT_T] = 0.0
        out[OUT_SLIP_M] = 0.0
        # lifted off: the skin lets go of the tool; a release this tick (OUT_HOLD 2: a stall's lifted tick, a teleport)
        # keeps the anchor for the next contact, a tick out of contact without one (a true lift-off) clears it
        if out[OUT_HOLD] >= 2.0:
            out[OUT_HOLD] = 1.0
        else:
            out[OUT_HOLD] = 0.0
            out[OUT_ANCHORED] = 0.0
        a = 0.0
        recover_layers(dt, restart, lp, sp, bmodes, bvec, blev, mstate, lstate, istate, ea_eff, off)
    stress = force_n / (frac * math.pi * a * a) if a > 0.0 and frac > 0.0 else 0.0  # over the disk's part on the sheet
    d_out = depth if touching else 0.0
    n_out = nl if touching else 0
    end_tick(force_n, stress, d_out, n_out, surface, fx, fy, fz, nx, ny, nz, a, sp, lstate, istate, out)
    out[OUT_DFN_DX] = dfx
    out[OUT_DFN_DY] = dfy
    out[OUT_DFN_DZ] = dfz
    return flags


class LayeredForm(Form):
    """The layered form bound to one model's kernel arrays (:class:`~.layout.Form`)."""

    name = "layered"

    def __init__(self, arrays: KernelArrays, cfg: TissueConfig):
        super().__init__(arrays, cfg)
        self._mu = cfg.friction_coefficient
        self._k_t = cfg.tangential_stiffness_n_per_m if cfg.friction_coefficient > 0.0 else 0.0

    def tick(self, x, y, z, vx, vy, vz, dt, restart=False) -> int:
        """:func:`layered_step_kernel` (the velocity is passed on and unused: no part of the force reads it)."""
        return layered_step_kernel(
            float(x), float(y), float(z), float(vx), float(vy), float(vz), float(dt), bool(restart), *self._args
        )

    def tangent(self, flags: int) -> ContactTangent:
        """Force and derivatives of the last tick (``flags``: its flags): :func:`~.friction.presliding_tangent` of its
        force, no ``D`` (no velocity enters the force), and the friction's anchor, stiffness and coefficient."""
        if not flags & FLAG_CONTACT:
            return normal_tangent(0.0, 0.0, 0.0, 0.0)
        o = self._out
        stiffness = np.empty((3, 3))
        normal = o[OUT_NX : OUT_NZ + 1].copy()
        force = o[OUT_FX : OUT_FZ + 1].copy()
        anchor = o[OUT_ZX : OUT_ZZ + 1].copy()
        fn = float(o[OUT_FORCE_N])
        stretch = -(force - fn * normal) / self._k_t if self._k_t > 0.0 else np.zeros(3)
        presliding_tangent(normal, stretch, self._k_t, self._mu, fn, o[OUT_DFN_DX : OUT_DFN_DZ + 1], stiffness)
        return ContactTangent(
            force_n=force,
            stiffness_n_per_m=stiffness,
            damping_n_s_per_m=np.zeros((3, 3)),
            normal=normal,
            contact_radius_m=float(o[OUT_RADIUS_M]),
            friction_coefficient=self._mu,
            tangential_stiffness_n_per_m=self._k_t,
            friction_anchor_m=anchor,
        )
