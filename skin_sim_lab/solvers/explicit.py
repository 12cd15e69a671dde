"""Explicit baselines: leapfrog finite differences and the Kelvin-Voigt mass-spring grid.

Both are conditionally stable (:func:`.membrane.leapfrog_dt_limit_s`,
:func:`.membrane.mass_spring_dt_limit_s`); their numba loops live in
:mod:`.kernels`.
"""

from __future__ import annotations

import numpy as np

from .base import MembraneSolver
from .kernels import leapfrog_membrane_steps, mass_spring_steps
from .membrane import Membrane, stiffness_per_area, strain_energy_j


class LeapfrogSolver(MembraneSolver):
    """Central differences in time and space (5-point Laplacian) of the membrane PDE.

    Holds ``u`` at t_n and t_(n-1). :meth:`set_state` starts from ``(u0, v0)`` with the
    second-order Taylor start ``u_(-1) = u0 - dt v0 + dt^2 a0 / 2`` on the first step; a
    change of ``dt`` keeps the backward-difference velocity.
    """

    name = "leapfrog FD"

    def set_state(self, u0_m, v0_m_s=None) -> None:
        """Set ``u`` and ``v``; the leapfrog's previous level is rebuilt at the next step."""
        super().set_state(u0_m, v0_m_s)
        self._u_prev = None
        self._dt = None
        self._tmp = np.zeros_like(self.u_m)

    def _accel(self, u, v, load):
        m = self.mem
        K = stiffness_per_area(m, self.grid)
        return (-(K @ u.ravel()).reshape(u.shape) - m.damping_n_s_per_m3 * v + load) / m.areal_density_kg_per_m2

    def _prepare(self, dt, load):
        if self._u_prev is None:
            a0 = self._accel(self.u_m, self.v_m_s, load)
            self._u_prev = self.u_m - dt * self.v_m_s + 0.5 * dt * dt * a0
        elif dt != self._dt:
            v = (self.u_m - self._u_prev) / self._dt
            self._u_prev = self.u_m - dt * v
        self._dt = dt

    def advance(self, dt_s: float, n_steps: int, load_pa=None) -> None:
        """``n_steps`` leapfrog (central difference) steps of eq 1 in one compiled loop."""
        load = self._load(load_pa)
        dt = float(dt_s)
        self._prepare(dt, load)
        m = self.mem
        leapfrog_membrane_steps(
            self.u_m,
            self._u_prev,
            load,
            int(n_steps),
            dt,
            m.areal_density_kg_per_m2,
            m.tension_n_per_m,
            m.damping_n_s_per_m3,
            m.foundation_n_per_m3,
            self.dx_m,
            self.dy_m,
            self._tmp,
        )
        self.v_m_s = (self.u_m - self._u_prev) / dt

    def step(self, dt_s: float, load_pa=None) -> None:
        """One leapfrog step."""
        self.advance(dt_s, 1, load_pa)

    def energy_j(self) -> float:
        """The scheme's conserved energy (undamped, unloaded): kinetic of the half-step velocity
        plus ``a(u_(n-1), u_n) / 2``. Constant while stable; grows without bound past the limit."""
        g = self.grid
        if self._u_prev is None:
            kin = 0.5 * self.mem.areal_density_kg_per_m2 * float((self.v_m_s**2).sum()) * g.dx_m * g.dy_m
            return kin + strain_energy_j(self.mem, g, self.u_m)
        kin = 0.5 * self.mem.areal_density_kg_per_m2 * float((self.v_m_s**2).sum()) * g.dx_m * g.dy_m
        return kin + strain_energy_j(self.mem, g, self.u_m, self._u_prev)


class MassSpringSolver(MembraneSolver):
    """Kelvin-Voigt mass-spring grid (the paper's named baseline), semi-implicit Euler.

    Node mass ``rho_A dx dy``; springs ``T dy / dx`` along x and ``T dx / dy`` along y (so the
    static operator equals the 5-point membrane); ground spring ``k_A dx dy`` and damper
    ``c_A dx dy``; optional dampers ``edge_damping_n_s_per_m`` in parallel with every spring.
    """

    name = "mass-spring"

    def __init__(self, mem: Membrane, nx: int, ny: int, edge_damping_n_s_per_m: float = 0.0):
        if not edge_damping_n_s_per_m >= 0:
            raise ValueError(f"edge_damping_n_s_per_m must be >= 0, got {edge_damping_n_s_per_m!r}")
        self.edge_damping_n_s_per_m = float(edge_damping_n_s_per_m)
        super().__init__(mem, nx, ny)
        self._acc = np.zeros((ny, nx))

    def advance(self, dt_s: float, n_steps: int, load_pa=None) -> None:
        """``n_steps`` semi-implicit Euler steps of the lumped masses and springs in one compiled loop."""
        load = self._load(load_pa)
        m, g = self.mem, self.grid
        area = g.dx_m * g.dy_m
        mass_spring_steps(
            self.u_m,
            self.v_m_s,
            load * area,
            int(n_steps),
            float(dt_s),
            m.areal_density_kg_per_m2 * area,
            m.tension_n_per_m * g.dy_m / g.dx_m,
            m.tension_n_per_m * g.dx_m / g.dy_m,
            m.foundation_n_per_m3 * area,
            m.damping_n_s_per_m3 * area,
            self.edge_damping_n_s_per_m,
            self._acc,
        )

    def step(self, dt_s: float, load_pa=None) -> None:
        """One mass-spring step."""
        self.advance(dt_s, 1, load_pa)

    def energy_j(self) -> float:
        """Kinetic energy of the lumped masses plus the springs' strain energy (J)."""
        g = self.grid
        kin = 0.5 * self.mem.areal_density_kg_per_m2 * float((self.v_m_s**2).sum()) * g.dx_m * g.dy_m
        return kin + strain_energy_j(self.mem, g, self.u_m)
