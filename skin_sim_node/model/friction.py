"""Presliding skin friction from tool positions (issue 30): Hayward and Armstrong's adhesion point.

The skin under the tool sticks to it and stretches tangentially with it, a spring of stiffness ``k_t`` between the
tool ``p`` and an *anchor* ``z`` (the rest position of the skin point under the tool), until the spring's force reaches
the slip level ``mu F_n``; from then the anchor is dragged along behind the tool at the slip distance
``r = mu F_n / k_t`` (slip). Reversing, the tool first unloads the spring elastically over ``2 r`` before it slips the
other way: hysteresis (docs/model.md, "Friction"). In the tangent plane of the contact normal ``n``
(``P = I - n n^T``)::

    s = P (p - z)                         the stretch (m)
    if k_t |s| > mu F_n:  z <- z + (|s| - r) s / |s|,  s <- r s / |s|      the slip update (radial return)
    F_t = -k_t s                          |F_t| <= mu F_n always

Hayward V, Armstrong B (2000) "A new computational model of friction applied to haptic rendering", Experimental
Robotics VI, LNCIS 250: 403-412 (their adhesion-point model with ``z_stick = z_max``: the breakaway and the slip
distance coincide). A law of positions only: no velocity enters, so the same poses give the same force bit for bit
whatever the velocity estimate, and a tool that holds still holds its force (no drift under tremor, which Dahl and
LuGre show: Dupont et al. 2002, IEEE TAC 47:787). Passive: the update moves ``z`` only along ``s`` and only outward,
so ``k_t s . dz = k_t r (|s_trial| - r) >= 0`` is the energy each step dissipates (:func:`presliding_step`).

The kernels are compiled with :data:`JIT_OPTIONS` (numba's ``cache`` and ``nogil``, as the model's other kernels),
return scalars or write preallocated arrays, and are tested compiled and as ``.py_func`` against the NumPy reference
:func:`presliding_reference`. :func:`regularised_coulomb` is the velocity law this replaced, kept as the baseline
of the figures (``skin-sim friction``), never on the force path.
"""

from __future__ import annotations

import math
from typing import Any

import numpy as np
from numba import njit

JIT_OPTIONS: dict[str, Any] = {"cache": True, "nogil": True}
"""numba options of every kernel of this module (defined once)."""


@njit(**JIT_OPTIONS)
def presliding_step(px, py, pz, nx, ny, nz, zx, zy, zz, k_t, limit_n):
    """One update of the adhesion point and the friction force it gives, for the tool at ``p``.

    Parameters
    ----------
    px, py, pz : float
        Tool position (m).
    nx, ny, nz : float
        Unit contact normal (out of the tissue).
    zx, zy, zz : float
        The anchor before the update (m).
    k_t : float
        Tangential (presliding) stiffness of the skin (N/m); ``<= 0``: no friction (the anchor follows the tool).
    limit_n : float
        Slip level ``mu F_n`` (N); ``<= 0``: no friction.

    Returns
    -------
    zx, zy, zz : float
        The anchor after the update (m); it moves only in the tangent plane, along the stretch.
    fx, fy, fz : float
        The friction force on the tool, ``-k_t s`` (N), tangential, ``|F_t| <= limit_n``.
    slip_m : float
        How far the anchor moved (m, ``>= 0``; 0 while the skin sticks).
    """
    dx = px - zx
    dy = py - zy
    dz = pz - zz
    dn = dx * nx + dy * ny + dz * nz
    sx = dx - dn * nx
    sy = dy - dn * ny
    sz = dz - dn * nz
    s = math.sqrt(sx * sx + sy * sy + sz * sz)
    if k_t <= 0.0 or limit_n <= 0.0:  # no friction: the skin does not hold the tool
        return zx + sx, zy + sy, zz + sz, 0.0, 0.0, 0.0, s
    r = limit_n / k_t
    slip = 0.0
    if s > r:  # beyond the slip level: the anchor is dragged to the slip distance behind the tool
        slip = s - r
        w = slip / s
        zx += w * sx
        zy += w * sy
        zz += w * sz
        w = r / s
        sx *= w
        sy *= w
        sz *= w
    return zx, zy, zz, -k_t * sx, -k_t * sy, -k_t * sz, slip


@njit(**JIT_OPTIONS)
def presliding_tangent(normal, stretch, k_t, mu, force_n, grad, out_k):
    """``K = dF/dx`` of ``F = F_n n + F_t`` (N/m) at a stretch ``s``, written to ``out_k`` (3 x 3).

    Sticking (``k_t |s| < mu F_n``): ``F_t = -k_t s``, ``dF_t/dx = -k_t P``. Slipping (at the slip level, the tool
    moving on): ``F_t = -mu F_n s / |s|``, ``dF_t/dx = -mu (s / |s|) grad(F_n)^T - (mu F_n / |s|) (P - s s^T / |s|^2)``
    (no stiffness along the slip; ``mu F_n / |s| = k_t`` at the slip distance). The law has no ``D``: no velocity
    enters.

    Parameters
    ----------
    normal : ndarray, shape (3,)
        Unit contact normal ``n``.
    stretch : ndarray, shape (3,)
        The tick's stretch ``s = P (p - z)`` after the update (m).
    k_t, mu, force_n : float
        Tangential stiffness (N/m), friction coefficient and normal force ``F_n`` (N).
    grad : ndarray, shape (3,)
        Gradient of ``F_n`` w.r.t. the tool position (N/m).
    out_k : ndarray, shape (3, 3)
        Written: ``K`` (N/m).
    """
    s = math.sqrt(stretch[0] * stretch[0] + stretch[1] * stretch[1] + stretch[2] * stretch[2])
    slipping = k_t > 0.0 and s > 0.0 and k_t * s >= mu * force_n * (1.0 - 1e-12)
    for i in range(3):
        for j in range(3):
            p_ij = (1.0 if i == j else 0.0) - normal[i] * normal[j]
            kij = normal[i] * grad[j]
            if k_t > 0.0 and mu * force_n > 0.0:
                if slipping:
                    u_i = stretch[i] / s
                    u_j = stretch[j] / s
                    kij += -mu * u_i * grad[j] - (mu * force_n / s) * (p_ij - u_i * u_j)
                else:
                    kij -= k_t * p_ij
            out_k[i, j] = kij


def presliding_reference(p, n, z, k_t: float, limit_n: float):
    """The slow reference of :func:`presliding_step` (NumPy, another formulation): the new anchor is the point
    nearest the old one, moved within the tangent plane, whose stretch lies in the disk of radius ``limit_n / k_t``
    (a projection onto a cylinder about the normal through ``p``).

    Returns
    -------
    z : ndarray, shape (3,)
        The new anchor (m).
    f : ndarray, shape (3,)
        The friction force ``-k_t P (p - z)`` (N).
    slip_m : float
        ``|z - z_old|`` (m).
    """
    p, n, z = (np.asarray(a, dtype=float) for a in (p, n, z))
    proj = np.eye(3) - np.outer(n, n)
    s = proj @ (p - z)
    if k_t <= 0 or limit_n <= 0:
        return z + s, np.zeros(3), float(np.linalg.norm(s))
    r = limit_n / k_t
    norm = float(np.linalg.norm(s))
    s_new = s if norm <= r else s * (r / norm)
    z_new = z + (s - s_new)
    return z_new, -k_t * s_new, float(np.linalg.norm(z_new - z))


def regularised_coulomb(normal, force_n: float, mu: float, slip_speed_m_s: float, v) -> np.ndarray:
    """The velocity law this module replaced, ``-mu F_n v_t / sqrt(|v_t|^2 + v_s^2)`` (N), tangential: kept only as
    the baseline of the figures (``skin-sim friction``: "today's law in the same run"), never on the force path."""
    n = np.asarray(normal, dtype=float)
    v = np.asarray(v, dtype=float)
    vt = v - float(n @ v) * n
    r = math.sqrt(float(vt @ vt) + slip_speed_m_s * slip_speed_m_s)
    return -(mu * force_n / r) * vt if r > 0.0 else np.zeros(3)
