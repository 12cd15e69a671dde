"""The ``layered`` form (issue 11): every layer in series from first contact.

Still the paper's method - iso-stress (Reuss, eq 4) through Kelvin-Voigt layers (eq 6) and a modal
membrane per layer (eqs 1-3) - with four changes (docs/model.md, "The layered form"):

1. All layers under the tool act in series from first contact (no Fig 3 engagement), each with the
   thickness that the egg-carton interfaces (section II.C) have *averaged over the contact disk*
   (:func:`averaged_bounds`), so the heterogeneity is a smooth few-percent modulation, not jumps.
2. A strain-stiffening compression law per layer (:func:`compression_law`),
   ``f_i = EA_i phi(c_i / h_i)``, ``phi(eps) = ((1 - eps)^-n - 1) / n``, which grows without bound
   as the compression ``c_i`` approaches the thickness ``h_i``; past the wall strain it continues
   along its tangent, so the bottom is a stiff wall and never a clamp.
3. A true series Kelvin-Voigt chain: each layer has its own rate, ``F / s = f_i(c_i) + b_i cdot_i``
   for every layer and ``sum c_i = d``, integrated by backward Euler (:func:`chain_solve`), which
   is passive for any ``dt``.
4. Coulomb friction with a viscous regularisation along the tangent plane of the deformed surface,
   and a flat or spherical tip (Hertz contact radius ``a = sqrt(R d)``, load ``C (2/3) sqrt(d/R)`` of the punch's).

The kernels are ``@njit(cache=True, nogil=True)``, allocate nothing and are tested compiled and
as ``.py_func`` against the NumPy/SciPy reference in :mod:`skin_sim_node.model.reference`;
:class:`LayeredForm` binds them to one model's arrays.
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit

from .calibration import BONE_STIFFNESS, BONE_STRAIN
from .config import TissueConfig
from .contact import ContactTangent, normal_tangent
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
    LP_IF_AMP,
    LP_IF_KX,
    LP_IF_KY,
    LP_IF_MEAN,
    LP_N,
    LP_TAU1,
    LP_TAU2,
    LS_COMP,
    LS_CX,
    LS_CY,
    LS_FE,
    LS_H1,
    LS_H2,
    LS_THICK,
    OUT_DFN_DX,
    OUT_DFN_DY,
    OUT_DFN_DZ,
    OUT_FORCE_N,
    OUT_FX,
    OUT_FZ,
    OUT_NX,
    OUT_NY,
    OUT_NZ,
    OUT_RADIUS_M,
    OUT_T,
    SP_BOTTOM,
    SP_HALF_X,
    SP_HALF_Y,
    SP_MODE_TOL,
    SP_MU,
    SP_SPHERE,
    SP_TOOL_R,
    SP_V_SLIP,
    SP_WALL,
    Form,
    KernelArrays,
)
from .modal_kernels import begin_tick_reach, drive_layer, end_tick, footprint, layer_at, relax_layer

RATE_CAP_M_S = 3.0
"""Largest layer rate handed to a membrane (m/s): the node's default tool speed cap (``max_tool_speed_m_s``;
hands rarely exceed 2 m/s). A faster chain rate comes from a pose jump, not motion, and would set a
released membrane ringing; the force path is not capped."""

DT_FLOOR_S = 1e-6
"""Smallest tick the chain integrates (s): a zero ``dt`` would make the dampers rigid; 1 us is far
below any haptic tick and keeps ``b / dt`` finite."""


# Abramowitz & Stegun 9.4.4 (J1(x)/x, in (x/3)^2), 9.4.3 (J0: f0, theta0) and 9.4.6 (J1: f1, theta1), in 3/x.
_J1X = (0.5, -0.56249985, 0.21093573, -0.03954289, 0.00443319, -0.00031761, 0.00001109)
_F0 = (0.79788456, -0.00000077, -0.00552740, -0.00009512, 0.00137237, -0.00072805, 0.00014476)
_T0 = (-0.78539816, -0.04166397, -0.00003954, 0.00262573, -0.00054125, -0.00029333, 0.00013558)
_F1 = (0.79788456, 0.00000156, 0.01659667, 0.00017105, -0.00249511, 0.00113653, -0.00020033)
_T1 = (-2.35619449, 0.12499612, 0.00005650, -0.00637879, 0.00074348, 0.00079824, -0.00029166)


@njit(cache=True, nogil=True)
def _poly(c, u):
    """``sum_i c[i] u^i`` (Horner) and its derivative in ``u`` (the polynomials of :func:`jinc`).

    Parameters
    ----------
    c : tuple of float
        Coefficients, lowest power first.
    u : float
        Argument.

    Returns
    -------
    p, dp : float
        The polynomial and its derivative.
    """
    p = 0.0
    dp = 0.0
    for i in range(len(c) - 1, -1, -1):
        dp = dp * u + p
        p = p * u + c[i]
    return p, dp


@njit(cache=True, nogil=True)
def jinc(x):
    """``2 J1(x) / x`` and its derivative for ``x >= 0``: the disk average of a plane wave (section II.C interfaces).

    Abramowitz & Stegun 9.4.4 (``x <= 3``, differentiated term by term) and 9.4.3, 9.4.6 (``x > 3``):
    absolute error below about 1e-7 (tested against SciPy).

    Parameters
    ----------
    x : float
        Argument, ``>= 0``.

    Returns
    -------
    w, dw : float
        ``2 J1(x) / x`` and its derivative in ``x``.
    """
    if x <= 3.0:
        p, dp = _poly(_J1X, (x / 3.0) ** 2)
        return 2.0 * p, 2.0 * dp * 2.0 * x / 9.0
    u = 3.0 / x
    r = 1.0 / math.sqrt(x)
    j0 = r * _poly(_F0, u)[0] * math.cos(x + _poly(_T0, u)[0])
    j1 = r * _poly(_F1, u)[0] * math.cos(x + _poly(_T1, u)[0])
    return 2.0 * j1 / x, 2.0 * (x * j0 - 2.0 * j1) / (x * x)


@njit(cache=True, nogil=True)
def compression_law(eps, n, wall):
    """``phi(eps)`` and ``phi'(eps)`` of the per-layer compression law (dimensionless).

    ``phi = ((1 - eps)^-n - 1) / n`` (``n = 0``: ``-ln(1 - eps)``, the Hencky strain): ``phi'(0) = 1``
    so a layer's small-strain stiffness is its ``k``; ``phi -> inf`` as ``eps -> 1``; convex for any
    ``n >= 0``. Beyond ``wall`` it continues along its tangent (the fitted law's slope saturates there, as the
    neo-Hookean punch's does); beyond :data:`BONE_STRAIN` the bottom adds ``K_bone (eps - eps_b)^2 / 2``, a steep,
    finite wall, linear past full compression. The layer's spring of eq 6, made strain-stiffening: ``f_i = EA_i phi(c_i / h_i)``.

    Parameters
    ----------
    eps : float
        Strain ``c / h``.
    n : float
        Stiffening exponent (``>= 0``).
    wall : float
        Wall strain.

    Returns
    -------
    phi, dphi : float
        ``phi(eps)`` and ``phi'(eps)``.
    """
    e = eps if eps < wall else wall
    lam = 1.0 - e
    if n > 1e-9:
        p = lam ** (-n)
        phi = (p - 1.0) / n
        dphi = p / lam
    else:
        phi = -math.log(lam)
        dphi = 1.0 / lam
    if eps > wall:
        phi += dphi * (eps - wall)
    if eps > BONE_STRAIN:  # the bottom: a steep, finite, C1 wall, linear past full compression
        x = min(eps, 1.0) - BONE_STRAIN
        phi += BONE_STIFFNESS * x * (0.5 * x + max(eps - 1.0, 0.0))
        dphi += BONE_STIFFNESS * x
    return phi, dphi


@njit(cache=True, nogil=True)
def layer_compression(target, ea, n, beta, c_old, h, wall, c0):
    """Compression ``c`` (m) with ``ea phi(c/h) + beta (c - c_old) = target`` and its slope ``G`` (N/m).

    The left side is convex and increasing in ``c``, so Newton converges from any start (monotone
    after at most one step). Requires ``target >= 0`` or ``beta > 0`` (a solution exists). One layer of the
    series chain (eq 6 with the layer's own rate, backward Euler: ``beta = b / dt``).

    Parameters
    ----------
    target : float
        Force the layer carries (N).
    ea, n : float
        ``EA`` (N) and stiffening exponent of :func:`compression_law`.
    beta : float
        ``b / dt`` (N/m).
    c_old : float
        Compression at the previous tick (m).
    h : float
        Thickness (m).
    wall : float
        Wall strain.
    c0 : float
        Newton start (m).

    Returns
    -------
    c : float
        The compression (m).
    g : float
        Its slope ``d(target)/dc`` (N/m).
    """
    c = c0
    for _ in range(80):
        phi, dphi = compression_law(c / h, n, wall)
        g = ea * phi + beta * (c - c_old) - target
        gp = ea * dphi / h + beta
        dc = g / gp
        c -= dc
        if abs(dc) <= 1e-16 + 1e-14 * abs(c):
            break
    phi, dphi = compression_law(c / h, n, wall)
    return c, ea * dphi / h + beta


@njit(cache=True, nogil=True)
def chain_solve(d, t0, ea, n, b, dt, c_old, h, wall, off, out_c, out_g):
    """Backward-Euler step of the series Kelvin-Voigt chain under the tool.

    Solves ``T = ea_i phi(c_i/h_i) + (b_i/dt) (c_i - c_old_i) + off_i`` for every layer (iso-stress, eq 4,
    with each layer's own rate; ``off_i`` the force its viscoelastic arms carry in, :func:`prony_prepare`) and
    ``sum_i c_i = d``. ``sum_i c_i(T)`` is concave and increasing in
    ``T`` (the inverse of convex increasing maps), so Newton on ``T`` started at or left of the root
    converges monotonically. Returns ``T`` (N), or ``-1.0`` when the chain relaxed with ``T = 0``
    is already at least ``d`` long (the tool is above the relaxing surface: no contact); writes the
    compressions ``out_c`` and slopes ``out_g = dT/dc_i``.

    Parameters
    ----------
    d : float
        Tool depth (m).
    t0 : float
        Newton start for ``T`` (N): the previous tick's (``OUT_T``).
    ea, n, b : ndarray, shape (L,)
        ``EA`` (N), stiffening exponents and dampers (N s/m) of the layers.
    dt : float
        Step (s), floored at :data:`DT_FLOOR_S`.
    c_old : ndarray, shape (L,)
        Compressions at the previous tick (m).
    h : ndarray, shape (L,)
        Thicknesses under the tool (m).
    wall : float
        Wall strain.
    off : ndarray, shape (L,)
        Force each layer's Prony arms carry into the step (N, ``<= 0`` after loading from rest; 0: elastic).
    out_c, out_g : ndarray, shape (L,)
        Written: compressions (m) and slopes (N/m).

    Returns
    -------
    float
        ``T`` (N), or -1.0 for no contact.
    """
    nl = c_old.shape[0]
    dt_eff = max(dt, DT_FLOOR_S)
    free = 0.0
    for i in range(nl):
        c, g = layer_compression(-off[i], ea[i], n[i], b[i] / dt_eff, c_old[i], h[i], wall, c_old[i])
        out_c[i] = c
        out_g[i] = g
        free += c
    if free >= d:
        return -1.0
    t = max(t0, 0.0)
    for _ in range(100):
        total = 0.0
        s = 0.0
        for i in range(nl):
            c, g = layer_compression(t - off[i], ea[i], n[i], b[i] / dt_eff, c_old[i], h[i], wall, out_c[i])
            out_c[i] = c
            out_g[i] = g
            total += c
            s += 1.0 / g
        res = total - d
        if abs(res) <= 1e-16 + 1e-13 * d:
            break
        t = max(t - res / s, 0.0)
    return t


@njit(cache=True, nogil=True)
def prony_weights(lp, li, dt, restart):
    """Backward-Euler weights ``a_j = tau_j / (tau_j + dt)`` of layer ``li``'s two Prony arms (0 on a restart).

    Quasi-linear viscoelasticity (Fung) with a two-term Prony series: the layer's force is its elastic
    (equilibrium) law plus two arms, ``f = f_e(c) + H_1 + H_2``, ``dH_j/dt = -H_j / tau_j + g_j df_e/dt``, so a
    held compression relaxes as ``G(t) = 1 + g_1 e^{-t/tau_1} + g_2 e^{-t/tau_2}`` times ``f_e`` (relative to
    equilibrium). Backward Euler: ``H_j' = a_j (H_j + g_j (f_e' - f_e))``, dissipative for any ``dt``. A contact
    restart (the tool has been where it is for an unknown time) takes the arms as relaxed: ``a_j = 0``.

    Parameters
    ----------
    lp : ndarray, shape (LP_SIZE, L)
        Its ``LP_G*``, ``LP_TAU*`` rows (:mod:`.layout`).
    li : int
        Layer.
    dt : float
        Step (s).
    restart : bool
        The arms are relaxed (contact restart).

    Returns
    -------
    a1, a2 : float
        The two weights.
    """
    if restart:
        return 0.0, 0.0
    t1 = lp[LP_TAU1, li]
    t2 = lp[LP_TAU2, li]
    return t1 / (t1 + dt), t2 / (t2 + dt)


@njit(cache=True, nogil=True)
def prony_prepare(lp, lstate, dt, restart, out_ea, out_off):
    """Each layer's instantaneous ``EA`` and carried-in arm force for this tick's backward-Euler step.

    With the weights of :func:`prony_weights`, the layer's force is
    ``f_e(c) (1 + a_1 g_1 + a_2 g_2) + sum_j a_j (H_j - g_j f_e,old)``: the chain (:func:`chain_solve`) sees a
    stiffer law, ``EA (1 + a_1 g_1 + a_2 g_2) phi(c / h)`` (``out_ea``), and an offset (``out_off``).

    Parameters
    ----------
    lp : ndarray, shape (LP_SIZE, L)
        Layer properties (:mod:`.layout`).
    lstate : ndarray, shape (LS_SIZE, L)
        Its ``LS_FE``, ``LS_H1``, ``LS_H2`` rows: the arms' state.
    dt : float
        Step (s).
    restart : bool
        The arms are relaxed (contact restart).
    out_ea, out_off : ndarray, shape (>= L,)
        Written: ``EA`` of the step (N) and the arms' carried-in force (N).
    """
    for li in range(lstate.shape[1]):
        a1, a2 = prony_weights(lp, li, dt, restart)
        g1 = lp[LP_G1, li]
        g2 = lp[LP_G2, li]
        fe = lstate[LS_FE, li]
        out_ea[li] = lp[LP_EA, li] * (1.0 + a1 * g1 + a2 * g2)
        out_off[li] = a1 * (lstate[LS_H1, li] - g1 * fe) + a2 * (lstate[LS_H2, li] - g2 * fe)


@njit(cache=True, nogil=True)
def prony_commit(lp, lstate, li, c, h, wall, dt, restart):
    """Advance layer ``li``'s arms over the step to compression ``c`` (m) at thickness ``h`` (m): the update of
    :func:`prony_weights`, and the new elastic force ``f_e = EA phi(c / h)`` kept in ``LS_FE``.

    Parameters
    ----------
    lp, lstate : ndarray
        As :func:`prony_prepare`; ``lstate``'s arm rows are written.
    li : int
        Layer.
    c, h : float
        The step's compression and thickness (m).
    wall : float
        Wall strain of :func:`compression_law`.
    dt : float
        Step (s).
    restart : bool
        The arms are relaxed (contact restart).
    """
    phi, _ = compression_law(c / h, lp[LP_N, li], wall)
    fe = lp[LP_EA, li] * phi
    a1, a2 = prony_weights(lp, li, dt, restart)
    dfe = fe - lstate[LS_FE, li]
    lstate[LS_H1, li] = a1 * (lstate[LS_H1, li] + lp[LP_G1, li] * dfe)
    lstate[LS_H2, li] = a2 * (lstate[LS_H2, li] + lp[LP_G2, li] * dfe)
    lstate[LS_FE, li] = fe


@njit(cache=True, nogil=True)
def clear_memory(lstate, li):
    """Forget layer ``li``'s viscoelastic memory and recovery: arms, elastic force and compression to zero."""
    lstate[LS_FE, li] = 0.0
    lstate[LS_H1, li] = 0.0
    lstate[LS_H2, li] = 0.0
    lstate[LS_THICK, li] = 0.0
    lstate[LS_COMP, li] = 0.0


@njit(cache=True, nogil=True)
def averaged_bounds(x, y, radius, dradius_dd, lp, bottom, bounds, dbx, dby, dbd):
    """Layer tops under a contact disk of ``radius`` centred at ``(x, y)``: egg-carton interfaces
    averaged over the disk (section II.C), and their derivatives.

    The disk average of ``cos(kx x) cos(ky y)`` is ``cos(kx x0) cos(ky y0) 2 J1(kappa a) / (kappa a)``
    with ``kappa = sqrt(kx^2 + ky^2)`` (each product term is a plane wave ``cos(k . r)``, whose disk
    average is its centre value times ``jinc(|k| a)``). ``bounds[0] = 0`` (surface), ``bounds[L]``
    the bottom; ``dbx``/``dby``/``dbd`` the derivatives of interface ``j`` w.r.t. x, y and the
    tool depth (through ``radius``, ``dradius_dd`` = da/dd).

    Parameters
    ----------
    x, y : float
        Disk centre (m).
    radius : float
        Contact radius ``a`` (m).
    dradius_dd : float
        ``da/dd`` (the sphere's; 0 for a flat punch).
    lp : ndarray, shape (LP_SIZE, L)
        Its interface rows ``LP_IF_*`` (:mod:`.layout`).
    bottom : float
        Depth of the bottom (m).
    bounds : ndarray, shape (L + 1,)
        Written: layer tops and the bottom (m, down).
    dbx, dby, dbd : ndarray, shape (>= L - 1,)
        Written: derivatives of each interface's averaged depth w.r.t. x, y (dimensionless) and the tool depth.
    """
    nif = bounds.shape[0] - 2
    bounds[0] = 0.0
    for j in range(nif):
        kx = lp[LP_IF_KX, j]
        ky = lp[LP_IF_KY, j]
        amp = lp[LP_IF_AMP, j]
        kappa = math.sqrt(kx * kx + ky * ky)
        w, dw = jinc(kappa * radius)
        cx = math.cos(kx * x)
        cy = math.cos(ky * y)
        bounds[j + 1] = lp[LP_IF_MEAN, j] - amp * cx * cy * w
        dbx[j] = amp * kx * math.sin(kx * x) * cy * w
        dby[j] = amp * ky * cx * math.sin(ky * y) * w
        dbd[j] = -amp * cx * cy * dw * kappa * dradius_dd
    bounds[nif + 1] = bottom


SPHERE_MIN_DEPTH_M = 1e-15
"""Depth floor of the sphere's contact radius: ``R d`` underflows to 0 for a subnormal depth (found by the property
test at d = 5e-324), and ``da/dd = R / 2a`` would divide by it. Far below any resolvable indentation."""

SPHERE_LOAD_FACTOR = 0.567
"""``C`` of the sphere's load scale ``s = C (2/3) sqrt(d / R)`` (:func:`contact_geometry`): the sphere's force over the
flat punch's of the same radius at the same depth, in units of Hertz's half-space ratio ``(2/3) a / R``. 1 on a
half-space; on the default stack the neo-Hookean sphere reference over the flat-punch reference is
0.55-0.61 of Hertz's ratio at every depth from 0.05 to 3 mm (docs/validation.md, "Tip shapes"): the stiff epidermis
shrinks the contact below ``sqrt(R d)`` at small depth (0.6 of it at 0.05 mm), the sphere's lower strains stiffen it
less than the punch at large depth. Fitted to the model's own chain force against the sphere reference
(least squares in ``log F`` at the check depths; ``python -m skin_sim_node.validation.tip_check --fit-sphere``)."""


@njit(cache=True, nogil=True)
def contact_geometry(depth, radius, sphere):
    """Contact radius ``a`` (m), load scale ``s`` and their depth derivatives for a tool ``depth`` > 0.

    Flat punch: ``a = R``, ``s = 1``. Sphere of radius ``R`` (docs/model.md, "Tip"): contact radius ``a = sqrt(R d)``
    (Hertz) up to ``d = R``, then ``R`` (the tool's shaft). The load scale follows Hertz's ratio of a sphere's
    force to the flat punch's of its radius on a half-space, ``F_sphere / F_punch = (4/3) E* sqrt(R) d^1.5 /
    (2 E* R d) = (2/3) sqrt(d / R)``, times the stack's factor :data:`SPHERE_LOAD_FACTOR`:
    ``s = C (2/3) sqrt(d / R)``, capped at 1 (the punch) far below the stack. The chain force ``T(d)`` (the punch's,
    eq 4) is linear at small depth, so ``F = s T ~ d^1.5`` (Hertz's exponent), and carries the stack's stiffening at
    depth. Scales the chain force of eq 4.

    Parameters
    ----------
    depth : float
        Tool depth (m), ``> 0``.
    radius : float
        Tool radius ``R`` (m).
    sphere : bool
        Spherical tip (else a flat punch).

    Returns
    -------
    a, s, ds_dd, da_dd : float
        Contact radius (m), load scale, and their derivatives in the depth (1/m, dimensionless).
    """
    if not sphere:
        return radius, 1.0, 0.0, 0.0
    d = max(depth, SPHERE_MIN_DEPTH_M)
    c = SPHERE_LOAD_FACTOR * 2.0 / 3.0
    s = c * math.sqrt(d / radius)
    ds_dd = 0.5 * s / d
    if s >= 1.0:
        s, ds_dd = 1.0, 0.0
    if depth >= radius:
        return radius, s, ds_dd, 0.0
    a = math.sqrt(radius * d)
    return a, s, ds_dd, 0.5 * radius / a


@njit(cache=True, nogil=True)
def contact_jacobians(normal, grad, velocity, mu, slip_speed_m_s, force_n, out_k, out_d):
    """``K = dF/dx`` and ``D = dF/dv`` of ``F = F_n (n - mu g)`` into ``out_k``, ``out_d`` (3 x 3 each).

    ``g = v_t / r``, ``r = sqrt(|v_t|^2 + v_s^2)``, ``v_t = P v``, ``P = I - n n^T``:
    ``K = (n - mu g) grad(F_n)^T`` and ``D = -mu F_n (I / r - v_t v_t^T / r^3) P``
    (see :meth:`skin_sim_node.model.skin_model.SkinModel.tangent`).

    Parameters
    ----------
    normal : ndarray, shape (3,)
        Unit contact normal ``n``.
    grad : ndarray, shape (3,)
        Gradient of the normal force magnitude w.r.t. the tool position (N/m).
    velocity : ndarray, shape (3,)
        Tool velocity (m/s).
    mu : float
        Friction coefficient.
    slip_speed_m_s : float
        Regularisation speed ``v_s`` (m/s).
    force_n : float
        Normal force magnitude ``F_n`` (N).
    out_k, out_d : ndarray, shape (3, 3)
        Written: ``K`` (N/m) and ``D`` (N s/m).
    """
    vn = normal[0] * velocity[0] + normal[1] * velocity[1] + normal[2] * velocity[2]
    vt0 = velocity[0] - vn * normal[0]
    vt1 = velocity[1] - vn * normal[1]
    vt2 = velocity[2] - vn * normal[2]
    r = math.sqrt(vt0 * vt0 + vt1 * vt1 + vt2 * vt2 + slip_speed_m_s * slip_speed_m_s)
    vt = (vt0, vt1, vt2)
    r3 = r * r * r
    for i in range(3):
        a = normal[i] - mu * vt[i] / r
        for j in range(3):
            out_k[i, j] = a * grad[j]
    for i in range(3):
        for j in range(3):
            s = 0.0
            for k in range(3):
                m_ik = (1.0 / r if i == k else 0.0) - vt[i] * vt[k] / r3
                p_kj = (1.0 if k == j else 0.0) - normal[k] * normal[j]
                s += m_ik * p_kj
            out_d[i, j] = -mu * force_n * s


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

    Arguments as :func:`~.paper.paper_step_kernel` plus the tool's lateral velocity. Contact is unilateral
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
    under the tool starts with no viscoelastic memory. Writes ``out`` (``OUT_*``: force vector, normal, contact
    radius, gradient of the normal force, and ``OUT_T``/normal carried to the next tick).

    Parameters
    ----------
    tool_vx, tool_vy, tool_vz : float
        Tool velocity (m/s): the friction's slip velocity and the cap of the membranes' rates.
    restart : bool
        Contact restarts (the first pose, after a stale spell or a teleport): the Prony arms are relaxed.
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
        vn = tool_vx * nx + tool_vy * ny + tool_vz * nz
        vtx = tool_vx - vn * nx
        vty = tool_vy - vn * ny
        vtz = tool_vz - vn * nz
        vs = sp[SP_V_SLIP]
        r = math.sqrt(vtx * vtx + vty * vty + vtz * vtz + vs * vs)
        mu = sp[SP_MU]
        fx = force_n * (nx - mu * vtx / r)
        fy = force_n * (ny - mu * vty / r)
        fz = force_n * (nz - mu * vtz / r)
        out[OUT_T] = t
        dt_eff = max(dt, DT_FLOOR_S)
        cap = max(RATE_CAP_M_S, math.sqrt(tool_vx * tool_vx + tool_vy * tool_vy + tool_vz * tool_vz))
        for li in range(nl):
            prony_commit(lp, lstate, li, c_new[li], thick[li], wall, dt, restart)
            if has_memory:  # the layers recover along their law after contact (recover_layers)
                lstate[LS_THICK, li] = thick[li]
            rate = min(cap, max(-cap, (c_new[li] - c_old[li]) / dt_eff))  # each layer its own rate (series chain)
            drive_layer(li, c_new[li], rate, foot_x, foot_y, sp, bmodes, bvec, blev, mstate, lstate, istate)
    else:
        out[OUT_T] = 0.0
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
        self._last_velocity = np.zeros(3)  # the tick's tool velocity, for the friction's Jacobian
        self._mu = cfg.friction_coefficient
        self._slip = cfg.slip_speed_m_s

    def tick(self, x, y, z, vx, vy, vz, dt, restart=False) -> int:
        """:func:`layered_step_kernel`; the velocity is kept for :meth:`tangent` (the friction's Jacobian)."""
        vx, vy, vz = float(vx), float(vy), float(vz)
        v = self._last_velocity  # by item: a slice assignment from a tuple costs several times more
        v[0] = vx
        v[1] = vy
        v[2] = vz
        return layered_step_kernel(float(x), float(y), float(z), vx, vy, vz, float(dt), bool(restart), *self._args)

    def tangent(self, flags: int) -> ContactTangent:
        """Force and derivatives of the last tick (``flags``: its flags): :func:`contact_jacobians` of its force."""
        if not flags & FLAG_CONTACT:
            return normal_tangent(0.0, 0.0, 0.0, 0.0)
        o = self._out
        stiffness = np.empty((3, 3))
        damping = np.empty((3, 3))
        normal = o[OUT_NX : OUT_NZ + 1].copy()
        contact_jacobians(
            normal,
            o[OUT_DFN_DX : OUT_DFN_DZ + 1],
            self._last_velocity,
            self._mu,
            self._slip,
            float(o[OUT_FORCE_N]),
            stiffness,
            damping,
        )
        return ContactTangent(
            force_n=o[OUT_FX : OUT_FZ + 1].copy(),
            stiffness_n_per_m=stiffness,
            damping_n_s_per_m=damping,
            normal=normal,
            contact_radius_m=float(o[OUT_RADIUS_M]),
        )
