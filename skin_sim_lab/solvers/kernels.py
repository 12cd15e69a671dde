"""numba kernels of the explicit baseline solvers: leapfrog finite differences and the mass-spring grid.

One layer's PDE (eq 1 with damping and a foundation, :mod:`.membrane`),
``rho u_tt + c u_t = T (u_xx + u_yy) - k u + p``, on the interior nodes of a rectangle with
``u = 0`` on the edges. Used for the accuracy and stability comparisons, not by the haptic model.
Kernel style as :mod:`skin_sim_node.model.modal_kernels` (``@njit(cache=True, nogil=True)``, in place);
each is tested compiled and as ``.py_func`` against :mod:`.reference`.
"""

from __future__ import annotations

from numba import njit


@njit(cache=True, nogil=True)
def leapfrog_membrane_steps(u, u_prev, load, n_steps, dt, rho, tension, damping, foundation, dx, dy, tmp):
    """``n_steps`` of the explicit central-difference (leapfrog) scheme of eq 1, in place.

    ``u`` holds t_n and ``u_prev`` t_(n-1) on entry, t_(n+k) and t_(n+k-1) on exit. The damping
    term is central, ``c (u+ - u-) / (2 dt)``, so the limit is ``omega_max dt <= 2`` for any ``c``.

    Parameters
    ----------
    u, u_prev : ndarray, shape (ny, nx)
        Displacements (m) at the last two steps; overwritten.
    load : ndarray, shape (ny, nx)
        Pressure ``p`` (Pa).
    n_steps : int
        Steps to take.
    dt : float
        Step (s).
    rho, tension, damping, foundation : float
        ``rho_A`` (kg/m^2), ``T`` (N/m), ``c_A`` (N s/m^3), ``k_A`` (N/m^3).
    dx, dy : float
        Node spacing (m).
    tmp : ndarray, shape (ny, nx)
        Scratch.
    """
    ny, nx = u.shape
    a = rho / (dt * dt) + damping / (2.0 * dt)
    bm = rho / (dt * dt) - damping / (2.0 * dt)
    two_rho = 2.0 * rho / (dt * dt)
    idx2 = 1.0 / (dx * dx)
    idy2 = 1.0 / (dy * dy)
    for _ in range(n_steps):
        for j in range(ny):
            for i in range(nx):
                c = u[j, i]
                left = u[j, i - 1] if i > 0 else 0.0
                right = u[j, i + 1] if i < nx - 1 else 0.0
                down = u[j - 1, i] if j > 0 else 0.0
                up = u[j + 1, i] if j < ny - 1 else 0.0
                lap = (left - 2.0 * c + right) * idx2 + (down - 2.0 * c + up) * idy2
                tmp[j, i] = (two_rho * c - bm * u_prev[j, i] + tension * lap - foundation * c + load[j, i]) / a
        for j in range(ny):
            for i in range(nx):
                u_prev[j, i] = u[j, i]
                u[j, i] = tmp[j, i]


@njit(cache=True, nogil=True)
def mass_spring_steps(u, v, load, n_steps, dt, mass, k_x, k_y, k_ground, c_ground, c_edge, acc):
    """``n_steps`` of a Kelvin-Voigt mass-spring grid (the paper's named baseline to eq 1) by semi-implicit Euler.

    Node forces: neighbour springs ``k_x``/``k_y`` (N/m), ground spring ``k_ground`` and damper
    ``c_ground``, edge dampers ``c_edge`` (N*s/m), external ``load`` (N). Fixed edge nodes sit
    outside the array (u = v = 0). ``v += dt a(u, v)``, then ``u += dt v``: damping is explicit.

    Parameters
    ----------
    u, v : ndarray, shape (ny, nx)
        Node displacements (m) and velocities (m/s); overwritten.
    load : ndarray, shape (ny, nx)
        Node forces (N).
    n_steps : int
        Steps to take.
    dt : float
        Step (s).
    mass : float
        Node mass (kg).
    k_x, k_y, k_ground : float
        Springs along x, y and to the ground (N/m).
    c_ground, c_edge : float
        Dampers to the ground and along each spring (N s/m).
    acc : ndarray, shape (ny, nx)
        Scratch.
    """
    ny, nx = u.shape
    inv_m = 1.0 / mass
    for _ in range(n_steps):
        for j in range(ny):
            for i in range(nx):
                c = u[j, i]
                cv = v[j, i]
                left = u[j, i - 1] if i > 0 else 0.0
                right = u[j, i + 1] if i < nx - 1 else 0.0
                down = u[j - 1, i] if j > 0 else 0.0
                up = u[j + 1, i] if j < ny - 1 else 0.0
                vl = v[j, i - 1] if i > 0 else 0.0
                vr = v[j, i + 1] if i < nx - 1 else 0.0
                vd = v[j - 1, i] if j > 0 else 0.0
                vu = v[j + 1, i] if j < ny - 1 else 0.0
                f = k_x * (left - 2.0 * c + right) + k_y * (down - 2.0 * c + up) - k_ground * c - c_ground * cv
                f += c_edge * (vl + vr + vd + vu - 4.0 * cv) + load[j, i]
                acc[j, i] = f * inv_m
        for j in range(ny):
            for i in range(nx):
                v[j, i] += dt * acc[j, i]
                u[j, i] += dt * v[j, i]
