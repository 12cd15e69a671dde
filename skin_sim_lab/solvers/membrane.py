"""One layer's membrane PDE and its discrete operators, shared by every baseline solver.

The PDE is eq 1 of the paper with the damping of eqs 7-8 and an optional elastic foundation::

    rho_A u_tt + c_A u_t = T (u_xx + u_yy) - k_A u + p(x, y, t),   u = 0 on the rectangle's edges

``rho_A`` areal density (kg/m^2), ``T`` tension (N/m), ``c_A`` damping per area (N*s/m^3),
``k_A`` foundation stiffness per area (N/m^3, 0 for the paper's membrane), ``p`` load (Pa);
``u`` is positive downward (m). Grids hold the interior nodes only, centred on the origin.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
import scipy.sparse as sp
import scipy.sparse.linalg as spla

from skin_sim_node.model import TissueConfig


@dataclass(frozen=True)
class Membrane:
    """Geometry and material of one layer's membrane (SI units, see the module docstring)."""

    size_x_m: float
    size_y_m: float
    areal_density_kg_per_m2: float
    tension_n_per_m: float
    damping_n_s_per_m3: float = 0.0
    foundation_n_per_m3: float = 0.0

    def __post_init__(self):
        for name in ("size_x_m", "size_y_m", "areal_density_kg_per_m2", "tension_n_per_m"):
            v = getattr(self, name)
            if not (math.isfinite(v) and v > 0):
                raise ValueError(f"Membrane.{name} must be finite and > 0, got {v!r}")
        for name in ("damping_n_s_per_m3", "foundation_n_per_m3"):
            v = getattr(self, name)
            if not (math.isfinite(v) and v >= 0):
                raise ValueError(f"Membrane.{name} must be finite and >= 0, got {v!r}")

    @property
    def wave_speed_m_s(self) -> float:
        """``c = sqrt(T / rho_A)`` (eq 1)."""
        return math.sqrt(self.tension_n_per_m / self.areal_density_kg_per_m2)

    @property
    def damping_rate_per_s(self) -> float:
        """``gamma = c_A / (2 rho_A)``: every mode's amplitude decays as ``exp(-gamma t)``."""
        return self.damping_n_s_per_m3 / (2.0 * self.areal_density_kg_per_m2)


def membrane_from_layer(cfg: TissueConfig, layer_index: int, patch: bool = True) -> Membrane:
    """The membrane of one configured layer, with the model's modal damping.

    ``c_A = 2 gamma rho_A`` with ``gamma = b / (2 m11)`` and ``m11 = rho_A a b / 4`` (see
    :mod:`skin_sim_node.model.modal`), so ``c_A = 4 b / (a b)``: every mode decays at the
    model's rate. ``patch=True`` uses the deformation patch, else the whole sheet.
    """
    layer = cfg.layers[layer_index]
    a, b = cfg.patch_size_m if patch else cfg.sheet_size_m
    return Membrane(
        size_x_m=a,
        size_y_m=b,
        areal_density_kg_per_m2=layer.areal_density_kg_per_m2,
        tension_n_per_m=layer.tension_n_per_m,
        damping_n_s_per_m3=4.0 * layer.damping_n_s_per_m / (a * b),
    )


@dataclass(frozen=True)
class GridSpec:
    """Interior nodes of an ``nx`` x ``ny`` grid (edges excluded), centred on 0."""

    nx: int
    ny: int
    dx_m: float
    dy_m: float
    xs_m: np.ndarray
    ys_m: np.ndarray


def grid_spec(mem: Membrane, nx: int, ny: int) -> GridSpec:
    """The :class:`GridSpec` of ``nx`` x ``ny`` interior nodes of ``mem``'s rectangle.

    Raises
    ------
    ValueError
        Fewer than 1 x 1 nodes.
    """
    if nx < 1 or ny < 1:
        raise ValueError(f"grid needs at least 1 x 1 interior nodes, got {nx} x {ny}")
    dx, dy = mem.size_x_m / (nx + 1), mem.size_y_m / (ny + 1)
    xs = -0.5 * mem.size_x_m + dx * np.arange(1, nx + 1)
    ys = -0.5 * mem.size_y_m + dy * np.arange(1, ny + 1)
    return GridSpec(nx, ny, dx, dy, xs, ys)


def laplacian(nx: int, ny: int, dx: float, dy: float) -> sp.csr_matrix:
    """5-point Laplacian on the interior nodes (row-major, y rows), Dirichlet edges."""

    def d2(n, h):
        return sp.diags([np.ones(n - 1), -2.0 * np.ones(n), np.ones(n - 1)], [-1, 0, 1]) / (h * h)

    return (sp.kron(sp.eye(ny), d2(nx, dx)) + sp.kron(d2(ny, dy), sp.eye(nx))).tocsr()


def stiffness_per_area(mem: Membrane, g: GridSpec) -> sp.csr_matrix:
    """``K = -T L + k_A I`` (Pa/m): the discrete elastic operator per unit area."""
    n = g.nx * g.ny
    return (-mem.tension_n_per_m * laplacian(g.nx, g.ny, g.dx_m, g.dy_m) + mem.foundation_n_per_m3 * sp.eye(n)).tocsr()


def discrete_eigen_per_area(g: GridSpec) -> tuple[np.ndarray, np.ndarray]:
    """Eigenvalues ``mu_x (nx,)`` and ``mu_y (ny,)`` of ``-d2/dx2`` and ``-d2/dy2`` on the grid (1/m^2)."""
    mx = np.arange(1, g.nx + 1)
    my = np.arange(1, g.ny + 1)
    mu_x = 4.0 / g.dx_m**2 * np.sin(mx * np.pi / (2 * (g.nx + 1))) ** 2
    mu_y = 4.0 / g.dy_m**2 * np.sin(my * np.pi / (2 * (g.ny + 1))) ** 2
    return mu_x, mu_y


def leapfrog_dt_limit_s(mem: Membrane, nx: int, ny: int) -> float:
    """Largest stable leapfrog step ``2 / omega_max`` (s).

    ``omega_max^2 = (T (mu_x,max + mu_y,max) + k_A) / rho_A``; for ``dx = dy`` and ``k_A = 0`` as
    ``nx -> inf`` this is the CFL condition ``c dt / dx <= 1 / sqrt(2)``. The central damping term
    does not move the limit.
    """
    g = grid_spec(mem, nx, ny)
    mu_x, mu_y = discrete_eigen_per_area(g)
    w2 = (mem.tension_n_per_m * (mu_x.max() + mu_y.max()) + mem.foundation_n_per_m3) / mem.areal_density_kg_per_m2
    return 2.0 / math.sqrt(w2)


def mass_spring_dt_limit_s(mem: Membrane, nx: int, ny: int, edge_damping_n_s_per_m: float = 0.0) -> float:
    """Largest stable semi-implicit Euler step of the mass-spring grid (s).

    Per grid mode the update matrix has ``det = 1 - 2 zeta h`` and ``tr = 2 - h^2 - 2 zeta h``
    (``h = omega dt``); the Jury conditions give ``h <= 2 (sqrt(1 + zeta^2) - zeta)``, i.e.
    ``omega dt < 2`` undamped. Returns the minimum over all grid modes.
    """
    g = grid_spec(mem, nx, ny)
    mu_x, mu_y = discrete_eigen_per_area(g)
    MX, MY = np.meshgrid(mu_x, mu_y)
    rho = mem.areal_density_kg_per_m2
    w = np.sqrt((mem.tension_n_per_m * (MX + MY) + mem.foundation_n_per_m3) / rho)
    c_per_area = mem.damping_n_s_per_m3 + edge_damping_n_s_per_m * (g.dx_m**2 * MX + g.dy_m**2 * MY) / (g.dx_m * g.dy_m)
    zeta = c_per_area / (2.0 * rho * w)
    return float(np.min(2.0 * (np.sqrt(1.0 + zeta**2) - zeta) / w))


def disk_mask(xs_m, ys_m, centre_xy_m, radius_m) -> np.ndarray:
    """Nodes inside the tool disk, shape ``(len(ys), len(xs))``; the nearest node if none is."""
    X, Y = np.meshgrid(np.asarray(xs_m, float), np.asarray(ys_m, float))
    r2 = (X - centre_xy_m[0]) ** 2 + (Y - centre_xy_m[1]) ** 2
    mask = r2 <= radius_m**2
    if not mask.any():
        mask.flat[int(np.argmin(r2))] = True
    return mask


def static_indentation(
    mem: Membrane, nx: int, ny: int, depth_m: float, centre_xy_m=(0.0, 0.0), radius_m: float = 2.5e-3
) -> tuple[float, np.ndarray]:
    """Static equilibrium under a rigid flat punch: nodes in the disk held at ``depth_m``.

    Solves ``K_ff u_f = -K_fc u_c`` with ``K`` the discrete operator of the PDE (the same one
    the explicit and implicit solvers integrate), and returns the reaction force (N) and the
    displacement field ``(ny, nx)`` (m, positive downward).
    """
    g = grid_spec(mem, nx, ny)
    K = stiffness_per_area(mem, g) * (g.dx_m * g.dy_m)
    held = disk_mask(g.xs_m, g.ys_m, centre_xy_m, radius_m).ravel()
    free = ~held
    u = np.zeros(g.nx * g.ny)
    u[held] = depth_m
    if free.any():
        u[free] = spla.spsolve(K[free][:, free].tocsc(), -K[free][:, held] @ u[held])
    force = float((K @ u)[held].sum())
    return force, u.reshape(g.ny, g.nx)


def strain_energy_j(mem: Membrane, g: GridSpec, u: np.ndarray, w: np.ndarray | None = None) -> float:
    """Discrete elastic energy ``a(u, w) / 2`` (J): tension over grid edges plus foundation.

    ``a(u, u)`` is the energy of ``u``; the leapfrog's conserved energy uses ``a(u_n, u_(n+1))``.
    """
    w = u if w is None else w
    up = np.pad(u, 1)
    wp = np.pad(w, 1)
    gx_u, gx_w = np.diff(up[1:-1], axis=1) / g.dx_m, np.diff(wp[1:-1], axis=1) / g.dx_m
    gy_u, gy_w = np.diff(up[:, 1:-1], axis=0) / g.dy_m, np.diff(wp[:, 1:-1], axis=0) / g.dy_m
    dens = mem.tension_n_per_m * ((gx_u * gx_w).sum() + (gy_u * gy_w).sum()) + mem.foundation_n_per_m3 * (u * w).sum()
    return 0.5 * float(dens) * g.dx_m * g.dy_m
