"""Common state handling of the baseline membrane solvers."""

from __future__ import annotations

import numpy as np

from .membrane import GridSpec, Membrane, grid_spec


class MembraneSolver:
    """Base: a membrane, its interior grid, and the state ``u`` (m) and ``v`` (m/s), shape (ny, nx).

    Subclasses implement :meth:`step` and :meth:`energy_j`; :meth:`advance` loops :meth:`step`
    unless a subclass has a faster path.
    """

    name = "solver"

    def __init__(self, mem: Membrane, nx: int, ny: int):
        self.mem = mem
        self.grid: GridSpec = grid_spec(mem, nx, ny)
        self._zero_load = np.zeros((ny, nx))
        self.set_state(np.zeros((ny, nx)))

    # geometry shortcuts
    @property
    def xs_m(self) -> np.ndarray:
        """x of the interior grid columns (m)."""
        return self.grid.xs_m

    @property
    def ys_m(self) -> np.ndarray:
        """y of the interior grid rows (m)."""
        return self.grid.ys_m

    @property
    def dx_m(self) -> float:
        """Grid spacing along x (m)."""
        return self.grid.dx_m

    @property
    def dy_m(self) -> float:
        """Grid spacing along y (m)."""
        return self.grid.dy_m

    def _check_field(self, a, what: str) -> np.ndarray:
        a = np.asarray(a, dtype=float)
        shape = (self.grid.ny, self.grid.nx)
        if a.shape != shape:
            raise ValueError(f"{what} must have shape {shape} (ny, nx), got {a.shape}")
        return a

    def _load(self, load_pa) -> np.ndarray:
        return self._zero_load if load_pa is None else self._check_field(load_pa, "load_pa")

    def set_state(self, u0_m, v0_m_s=None) -> None:
        """Set displacement ``u0_m`` (m, shape (ny, nx)) and velocity ``v0_m_s`` (m/s; default 0)."""
        self.u_m = self._check_field(u0_m, "u0_m").copy()
        self.v_m_s = np.zeros_like(self.u_m) if v0_m_s is None else self._check_field(v0_m_s, "v0_m_s").copy()

    def step(self, dt_s: float, load_pa=None) -> None:
        """Advance one step of ``dt_s`` (s) under the load ``load_pa`` (Pa, shape (ny, nx); default none)."""
        raise NotImplementedError

    def advance(self, dt_s: float, n_steps: int, load_pa=None) -> None:
        """``n_steps`` steps of ``dt_s`` (s) under a constant load ``load_pa`` (Pa)."""
        for _ in range(int(n_steps)):
            self.step(dt_s, load_pa)

    def energy_j(self) -> float:
        """Kinetic plus strain energy of the membrane (J): what damping must make decay."""
        raise NotImplementedError
