"""Implicit baselines: backward Euler and Crank-Nicolson, unconditionally stable, sparse LU."""

from __future__ import annotations

import scipy.sparse as sp
import scipy.sparse.linalg as spla

from .base import MembraneSolver
from .membrane import Membrane, stiffness_per_area, strain_energy_j

SCHEMES = ("crank_nicolson", "backward_euler")


class ImplicitSolver(MembraneSolver):
    """First-order form ``u' = v``, ``rho v' = -K u - c v + p``, solved for ``v_(n+1)``.

    Crank-Nicolson (trapezoidal, second order, energy-conserving undamped)::

        (rho + dt c / 2 + dt^2 K / 4) v+ = (rho - dt c / 2) v - dt K u - dt^2 K v / 4 + dt p
        u+ = u + dt (v + v+) / 2

    Backward Euler (first order, numerically dissipative)::

        (rho + dt c + dt^2 K) v+ = rho v - dt K u + dt p,   u+ = u + dt v+

    The LU factorisation is cached per ``dt``.
    """

    def __init__(self, mem: Membrane, nx: int, ny: int, scheme: str = "crank_nicolson"):
        if scheme not in SCHEMES:
            raise ValueError(f"scheme must be one of {SCHEMES}, got {scheme!r}")
        self.scheme = scheme
        self.name = "Crank-Nicolson" if scheme == "crank_nicolson" else "backward Euler"
        super().__init__(mem, nx, ny)
        self._K = stiffness_per_area(mem, self.grid)
        self._lu = {}

    def _factor(self, dt: float):
        lu = self._lu.get(dt)
        if lu is None:
            n = self._K.shape[0]
            rho, c = self.mem.areal_density_kg_per_m2, self.mem.damping_n_s_per_m3
            if self.scheme == "crank_nicolson":
                A = (rho + 0.5 * dt * c) * sp.eye(n) + 0.25 * dt * dt * self._K
            else:
                A = (rho + dt * c) * sp.eye(n) + dt * dt * self._K
            lu = spla.splu(A.tocsc())
            if len(self._lu) > 8:
                self._lu.clear()
            self._lu[dt] = lu
        return lu

    def step(self, dt_s: float, load_pa=None) -> None:
        """One Crank-Nicolson or backward Euler step of eq 1 (a sparse LU per ``dt``, cached)."""
        dt = float(dt_s)
        p = self._load(load_pa).ravel()
        u, v = self.u_m.ravel(), self.v_m_s.ravel()
        rho, c = self.mem.areal_density_kg_per_m2, self.mem.damping_n_s_per_m3
        Ku = self._K @ u
        if self.scheme == "crank_nicolson":
            rhs = (rho - 0.5 * dt * c) * v - dt * Ku - 0.25 * dt * dt * (self._K @ v) + dt * p
            v1 = self._factor(dt).solve(rhs)
            u1 = u + 0.5 * dt * (v + v1)
        else:
            v1 = self._factor(dt).solve(rho * v - dt * Ku + dt * p)
            u1 = u + dt * v1
        shape = self.u_m.shape
        self.u_m, self.v_m_s = u1.reshape(shape), v1.reshape(shape)

    def energy_j(self) -> float:
        """Kinetic plus strain energy on the finite-difference grid (J)."""
        g = self.grid
        kin = 0.5 * self.mem.areal_density_kg_per_m2 * float((self.v_m_s**2).sum()) * g.dx_m * g.dy_m
        return kin + strain_energy_j(self.mem, g, self.u_m)


__all__ = ["ImplicitSolver", "SCHEMES"]
