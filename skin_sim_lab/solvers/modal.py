"""The exact modal integrator of the membrane PDE (eq 2 with eq 3's frequencies), on a grid.

The grid state is projected on the continuum sine modes ``sin(m pi (x + a/2) / a) sin(n pi (y + b/2) / b)``
by a DST-I (exact for the modes the grid carries), each mode is advanced by the closed-form damped
propagator (:func:`skin_sim_node.model.modal_kernels.modal_propagator`), and the field is synthesised
back. Exact in time for any ``dt``; with all ``nx x ny`` modes it is the exact solution of the
same PDE for the grid's trigonometric interpolant, the reference for the release charts.
"""

from __future__ import annotations

import math

import numpy as np
from scipy.fft import dstn, idstn

from skin_sim_node.model.modal_kernels import modal_propagator

from .base import MembraneSolver
from .membrane import Membrane


class ModalSolver(MembraneSolver):
    """Exact-in-time modal solution, optionally truncated to the first ``modes = (M, N)``."""

    def __init__(self, mem: Membrane, nx: int, ny: int, modes: tuple[int, int] | None = None):
        m_max, n_max = (nx, ny) if modes is None else (min(int(modes[0]), nx), min(int(modes[1]), ny))
        if m_max < 1 or n_max < 1:
            raise ValueError(f"modes must be >= 1 x 1, got {modes!r}")
        self.modes = (m_max, n_max)
        self.name = "exact modal" if modes is None else f"modal {m_max}x{n_max}"
        mm, nn = np.meshgrid(np.arange(1, nx + 1), np.arange(1, ny + 1))
        self._keep = (mm <= m_max) & (nn <= n_max)
        kappa2 = math.pi**2 * ((mm / mem.size_x_m) ** 2 + (nn / mem.size_y_m) ** 2)
        self._stiff = mem.tension_n_per_m * kappa2 + mem.foundation_n_per_m3  # Pa/m per mode
        self._lam = np.sqrt(self._stiff / mem.areal_density_kg_per_m2).reshape(1, -1)
        self._gamma = np.array([mem.damping_rate_per_s])
        self._prop = np.zeros((4, 1, nx * ny))
        self._prop_dt = None
        self._norm = (nx + 1) * (ny + 1)  # dstn(u) / norm = sine coefficients
        super().__init__(mem, nx, ny)

    def set_state(self, u0_m, v0_m_s=None) -> None:
        """Set ``u`` and ``v``: their sine-transform coefficients, truncated to the kept modes."""
        super().set_state(u0_m, v0_m_s)
        self._qu = dstn(self.u_m, type=1) * self._keep
        self._qv = dstn(self.v_m_s, type=1) * self._keep
        self._sync()

    def _sync(self) -> None:
        self.u_m = idstn(self._qu, type=1)
        self.v_m_s = idstn(self._qv, type=1)

    def _advance_coeffs(self, dt: float, n_steps: int, load_pa) -> None:
        if self._prop_dt != dt:
            modal_propagator(self._lam, self._gamma, dt, self._prop)
            self._prop_dt = dt
        shape = self._qu.shape
        p11, p12, p21, p22 = (self._prop[i, 0].reshape(shape) for i in range(4))
        q_static = 0.0 if load_pa is None else dstn(self._check_field(load_pa, "load_pa"), type=1) * self._keep / self._stiff
        qu, qv = self._qu - q_static, self._qv
        for _ in range(int(n_steps)):
            qu, qv = p11 * qu + p12 * qv, p21 * qu + p22 * qv
        self._qu, self._qv = qu + q_static, qv

    def step(self, dt_s: float, load_pa=None) -> None:
        """One exact modal step (eqs 2-3, damped)."""
        self.advance(dt_s, 1, load_pa)

    def advance(self, dt_s: float, n_steps: int, load_pa=None) -> None:
        """``n_steps`` exact modal steps of ``dt_s`` (s) under a constant load, then the grid fields."""
        self._advance_coeffs(float(dt_s), n_steps, load_pa)
        self._sync()

    def energy_j(self) -> float:
        """Continuum energy of the modal state: ``sum (a b / 8) (rho_A qdot^2 + K_mn q^2)`` (J)."""
        m = self.mem
        qu, qv = self._qu / self._norm, self._qv / self._norm
        area_factor = m.size_x_m * m.size_y_m / 8.0
        return float(area_factor * (m.areal_density_kg_per_m2 * qv**2 + self._stiff * qu**2).sum())
