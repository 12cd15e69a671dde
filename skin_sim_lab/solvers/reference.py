"""Slow, obviously correct NumPy versions of the explicit solver kernels (for the tests)."""

from __future__ import annotations

import numpy as np


def _lap_terms(u):
    p = np.pad(u, 1)
    return p[1:-1, :-2] - 2 * u + p[1:-1, 2:], p[:-2, 1:-1] - 2 * u + p[2:, 1:-1]


def leapfrog_step(u, u_prev, load, dt, rho, tension, damping, foundation, dx, dy):
    """One central-difference step: returns ``(u_next, u)``."""
    d2x, d2y = _lap_terms(u)
    lap = d2x / dx**2 + d2y / dy**2
    rhs = 2 * rho / dt**2 * u - (rho / dt**2 - damping / (2 * dt)) * u_prev + tension * lap - foundation * u + load
    return rhs / (rho / dt**2 + damping / (2 * dt)), u.copy()


def mass_spring_step(u, v, load, dt, mass, k_x, k_y, k_ground, c_ground, c_edge):
    """One semi-implicit Euler step of the mass-spring grid: returns ``(u_next, v_next)``."""
    d2x, d2y = _lap_terms(u)
    v2x, v2y = _lap_terms(v)
    f = k_x * d2x + k_y * d2y - k_ground * u - c_ground * v + c_edge * (v2x + v2y) + load
    v1 = v + dt * f / mass
    return u + dt * v1, v1
