"""The layered form's constitutive chain (issue 11, issue 20): each layer's strain-stiffening compression law and
the series Kelvin-Voigt chain solved by backward Euler, with the Prony arms of its quasi-linear viscoelasticity.

- :func:`compression_law`: ``f_i = EA_i phi(c_i / h_i)``, ``phi(eps) = ((1 - eps)^-n - 1) / n``, continued along its
  tangent past the wall strain, plus the bottom's term past :data:`~.calibration.BONE_STRAIN`;
- :func:`layer_compression`, :func:`chain_solve`: ``F / s = f_i(c_i) + b_i cdot_i`` for every layer with
  ``sum c_i = d`` (eq 6 in series), passive for any ``dt``;
- :func:`prony_weights`, :func:`prony_prepare`, :func:`prony_commit`, :func:`clear_memory`: the reduced relaxation
  ``G(t) = 1 + g1 exp(-t/tau1) + g2 exp(-t/tau2)`` integrated exactly over a tick.

Split out of :mod:`.layered` by job (the step kernel there composes this chain with the contact of
:mod:`.layered_contact` and the membranes of :mod:`.modal_kernels`). ``@njit(cache=True, nogil=True)``, allocation free;
tested compiled and as ``.py_func`` against :mod:`skin_sim_lab.oracles.reference`.
"""

from __future__ import annotations

import math

from numba import njit

from .calibration import BONE_STIFFNESS, BONE_STRAIN
from .layout import (
    LP_EA,
    LP_G1,
    LP_G2,
    LP_N,
    LP_TAU1,
    LP_TAU2,
    LS_COMP,
    LS_FE,
    LS_H1,
    LS_H2,
    LS_THICK,
)

DT_FLOOR_S = 1e-6
"""Smallest tick the chain integrates (s): a zero ``dt`` would make the dampers rigid; 1 us is far
below any haptic tick and keeps ``b / dt`` finite."""


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
