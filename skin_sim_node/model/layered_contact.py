"""The layered form's contact (issue 11): the tip's geometry and the force's Jacobians.

- :func:`averaged_bounds`: each layer's thickness averaged over the contact disk (the egg-carton interfaces of section
  II.C seen through the disk's ``2 J1(x) / x``, :func:`jinc`);
- :func:`contact_geometry`: a flat punch, or a sphere's Hertz contact radius ``a = sqrt(R d)`` and load
  ``C (2/3) sqrt(d / R)`` of the punch's;
- :func:`contact_jacobians`: ``K = dF/dx`` and ``D = dF/dv`` of ``F = F_n (n - mu g)``, the normal force along the
  deformed surface plus the regularised Coulomb friction.

Split out of :mod:`.layered` by job. ``@njit(cache=True, nogil=True)``, allocation free.
"""

from __future__ import annotations

import math

from numba import njit

from .layout import (
    LP_IF_AMP,
    LP_IF_KX,
    LP_IF_KY,
    LP_IF_MEAN,
)

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
(least squares in ``log F`` at the check depths; ``python -m skin_sim_lab.validation.tip_check --fit-sphere``)."""


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
