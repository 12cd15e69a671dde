"""Linear elasticity of the layered block, semi-analytic: the surface under a rigid flat punch, and two punches' coupling.

The project's linear 3D FEM (:mod:`.fem`) and the layers of the config, solved exactly in the wavenumber: the three
layers (flat interfaces at their mean depths; the FEM's egg-carton interfaces are left out) bonded to each other and
to a rigid base, their top free of shear, each isotropic with the moduli of :func:`.hyperelastic.layer_moduli_pa` and
Poisson's ratio :data:`~skin_sim_node.model.calibration.POISSON_RATIO`. For a surface pressure ``p cos(k x)`` each
layer's displacement ``(U(z) sin kx, W(z) cos kx)`` obeys Navier's equations, a linear first-order system in
``y = (U, W, tau, sigma)`` (``tau``, ``sigma`` the shear and normal tractions on a horizontal plane, continuous across
an interface): the layers' transfer matrices ``expm(A_i h_i)`` carry ``y`` from the base (``U = W = 0``) to the top
(``tau = 0``, ``sigma = -p``), and the surface compliance ``C(k) = -W(top) / p`` follows. An axisymmetric pressure
``p(r)`` lowers the surface by ``w(r) = int_0^inf C(k) p^(k) J_0(k r) k dk``, ``p^(k) = int_0^inf p(r) J_0(k r) r dr``
(the Hankel pair of the 2D Fourier transform of a radial function).

A rigid flat punch (radius ``a``, depth 1): rings of uniform pressure over the disk, graded toward the rim where the
pressure is singular, whose sum lowers each ring's mid-radius by 1 (collocation). Two rigid punches ``i``, ``j``: by
Betti's theorem the force ``j``'s unit depth takes from ``i`` held at its depth is ``int p_i u_j dA``, and the lowering
under ``i`` that the coupling's ``w_i = G e_j`` stands for is that over ``i``'s force,
``G_ij(s) = int C p^_i p^_j J_0(k s) k dk / p^_i(0)`` (first order in the coupling: the two contacts' pressures
unchanged by each other).

This is the regime of the linear FEM, not of the neo-Hookean reference: it checks the one and measures how far the
other has left it (``skin-sim two-punch``, "Linear elasticity of the layers"). Lab only; the model never imports it.
"""

from __future__ import annotations

from dataclasses import dataclass
from functools import lru_cache

import numpy as np
from scipy import linalg, special
from scipy.sparse import linalg as sparse_linalg

from skin_sim_node.model import TissueConfig
from skin_sim_node.model.calibration import POISSON_RATIO

from .hyperelastic import layer_moduli_pa

CUT_DEPTH_WAVES = 18.0
"""Below ``18 / k`` the stack is cut and the cut taken as the rigid base: a mode of wavenumber ``k`` decays by
``exp(-k z)``, so the base's effect on the surface is ``exp(-36)``, and the transfer matrices stay below ``e^18`` (no
overflow, 1e-8 of double precision lost)."""

K_LOG = np.logspace(-1, 7, 400)
"""Wavenumbers (1/m) where the compliance is solved; between them it is interpolated in log-log (it is smooth: ``h / M``
at ``k -> 0``, ``(1 - nu) / (mu_top k)`` at ``k -> inf``). 1e7 / m resolves 0.1 um; the epidermis is 75 um thick."""

K_STEP = 2.0
"""Step (1/m) of the Hankel integrals' trapezoid rule: the profile is read to 45 mm, where ``J_0(k r)``'s period in ``k``
is 140 / m, 70 steps."""

K_MAX = 4e5
"""Their upper end (1/m): 2.5 um at the punch's scale, so the pressure's rise toward the rim is resolved down to the
outer rings' widths of 10-20 um (the outermost, 3 um, is not: its ring averages the singularity); beyond, the
integrand of the far profile has decayed as ``k^-2``."""

RINGS = 30
"""Rings of uniform pressure across the punch (edges at ``a sin(pi t / 2)``, ``t`` uniform: graded toward the rim).
The stiffness moves by 0.11 % from 20 to 30 rings and 0.08 % from 30 to 40 (on a half-space it stays 0.5-0.6 % above
Sneddon's), the profile beyond 4 mm by under 1e-3 of the depth."""


def layers(cfg: TissueConfig, poisson: float = POISSON_RATIO) -> tuple[tuple[float, float], ...]:
    """``(thickness_m, youngs_modulus_pa)`` per layer of ``cfg``, from the top."""
    return tuple((la.thickness_m, e) for la, e in zip(cfg.layers, layer_moduli_pa(cfg, poisson)))


def _system(k: float, e: float, nu: float) -> np.ndarray:
    """``A`` of ``y' = A y`` for one layer (Young's modulus ``e``) at wavenumber ``k``, ``y = (U, W, tau, sigma)``.

    ``tau = mu (U' - k W)``, ``sigma = lam k U + (lam + 2 mu) W'`` (the tractions of ``u = (U sin kx, W cos kx)``); the
    two equilibrium equations give ``tau' = k ((lam + 2 mu) k U + lam W')`` and ``sigma' = -k tau``.
    """
    mu = e / (2 * (1 + nu))
    lam = 2 * mu * nu / (1 - 2 * nu)
    m = lam + 2 * mu
    a = np.zeros((4, 4))
    a[0, 1], a[0, 2] = k, 1 / mu
    a[1, 0], a[1, 3] = -lam * k / m, 1 / m
    a[2, 0], a[2, 3] = k * k * (m - lam * lam / m), k * lam / m
    a[3, 2] = -k
    return a


def surface_compliance(k, stack: tuple[tuple[float, float], ...], poisson: float = POISSON_RATIO) -> np.ndarray:
    """The surface's lowering per unit pressure at wavenumber ``k`` (m/Pa), ``C(k)``.

    Parameters
    ----------
    k : array_like
        Wavenumbers (1/m), > 0.
    stack : tuple of (float, float)
        ``(thickness_m, youngs_modulus_pa)`` per layer from the top; the last lies on the rigid base.
    poisson : float
        Poisson's ratio of every layer.

    Returns
    -------
    numpy.ndarray
        ``C(k)``; for one thick layer ``(1 - nu) / (mu k)`` (a half-space), for a thin incompressible one
        ``k^2 h^3 / (3 mu)`` (lubrication).
    """
    ks = np.atleast_1d(np.asarray(k, float))
    out = np.empty_like(ks)
    for n, kk in enumerate(ks):
        cut, z = [], 0.0
        for h, e in stack:
            hh = min(h, CUT_DEPTH_WAVES / kk - z)
            if hh <= 0:
                break
            cut.append((hh, e))
            z += hh
        p = np.eye(4)
        for h, e in reversed(cut):  # from the base up
            p = linalg.expm(_system(kk, e, poisson) * h) @ p
        ab = np.linalg.solve(p[2:, 2:], np.array([0.0, -1.0]))  # y(base) = (0, 0, a, b): tau = 0, sigma = -1 on top
        out[n] = -(p[1, 2:] @ ab)
    return out


@dataclass(frozen=True)
class Punch:
    """A rigid flat punch at unit depth on the layered block: its pressure's Hankel transform on :func:`k_grid`."""

    radius_m: float
    stiffness_n_per_m: float  # the force at unit depth
    pressure_hat: np.ndarray  # p^(k) on k_grid(), per metre of depth (N/m^3 times m^2: the ring sums of p r dr)
    compliance: np.ndarray  # C(k) on k_grid()

    def profile(self, radius_m) -> np.ndarray:
        """The surface's lowering over the depth at ``radius_m`` (+ lowered, - raised)."""
        k = k_grid()
        r = np.atleast_1d(np.asarray(radius_m, float))
        return (special.j0(np.outer(r, k)) @ (self.compliance * k * self.pressure_hat)) * K_STEP

    def coupling(self, source: Punch, distance_m) -> np.ndarray:
        """``G(s)``: the lowering under this punch, over ``source``'s depth, that carries ``source``'s force on it
        (Betti; first order), at centre distances ``distance_m``."""
        k = k_grid()
        s = np.atleast_1d(np.asarray(distance_m, float))
        g = special.j0(np.outer(s, k)) @ (self.compliance * k * self.pressure_hat * source.pressure_hat) * K_STEP
        return g / self.pressure_hat[0]


@lru_cache(maxsize=1)
def k_grid() -> np.ndarray:
    """The Hankel integrals' wavenumbers: :data:`K_STEP` to :data:`K_MAX` (the ``k = 0`` end carries no weight: the
    integrand has the factor ``k``)."""
    return np.arange(K_STEP, K_MAX, K_STEP)


def _compliance_at(k: np.ndarray, stack, poisson: float) -> np.ndarray:
    """``C(k)`` interpolated in log-log between its solves at :data:`K_LOG` (held at ``K_LOG[0]`` below it)."""
    c = surface_compliance(K_LOG, stack, poisson)
    return np.exp(np.interp(np.log(np.maximum(k, K_LOG[0])), np.log(K_LOG), np.log(c)))


@lru_cache(maxsize=8)
def rigid_punch(stack: tuple[tuple[float, float], ...], radius_m: float, poisson: float = POISSON_RATIO) -> Punch:
    """Solve the rigid flat punch of ``radius_m`` on ``stack`` (:data:`RINGS` rings, collocation at their mid-radii).

    Parameters
    ----------
    stack : tuple of (float, float)
        :func:`layers`.
    radius_m : float
        The punch's radius (m).
    poisson : float
        Poisson's ratio.

    Returns
    -------
    Punch
    """
    k = k_grid()
    comp = _compliance_at(k, stack, poisson)
    edges = radius_m * np.sin(0.5 * np.pi * np.linspace(0.0, 1.0, RINGS + 1))
    mids = 0.5 * (edges[1:] + edges[:-1])
    prim = edges[:, None] * special.j1(np.outer(edges, k)) / k  # int_0^r J_0(k r') r' dr'
    ring_hat = prim[1:] - prim[:-1]
    lowering = (special.j0(np.outer(mids, k)) * (comp * k)) @ ring_hat.T * K_STEP  # at mid i, per unit ring-j pressure
    pressure = np.linalg.solve(lowering, np.ones(RINGS))
    p_hat = pressure @ ring_hat
    force = float(np.pi * np.sum(pressure * (edges[1:] ** 2 - edges[:-1] ** 2)))
    return Punch(radius_m, force, p_hat, comp)


PAIR_CELL_M = 0.1e-3
"""Grid step of :func:`rigid_pair_interaction` (m): 25 cells across a 2.5 mm punch's radius (the footprint's staircase
edge is the error: the 4 mm pair's interaction was -0.0909 at 0.2 mm and -0.0936 at 0.1 mm)."""

PAIR_DOMAIN_M = 100e-3
"""Side of its periodic domain (m): one punch's surface is 1e-4 of its depth 50 mm out, so its images move the check
by a few 1e-4 of the single force at most."""


def rigid_pair_interaction(
    stack: tuple[tuple[float, float], ...],
    radius_m: float,
    distance_m: float,
    poisson: float = POISSON_RATIO,
    cell_m: float = PAIR_CELL_M,
    domain_m: float = PAIR_DOMAIN_M,
) -> float:
    """Two equal rigid flat punches pressed to one depth, their footprints overlapping or not: one punch's force over
    the single punch's, minus 1 (the interaction over the single force).

    The footprint (the union of the two disks; one disk for the single punch) on a square grid of cells of uniform
    pressure; the surface's lowering at each cell's centre from every cell's pressure by the 2D FFT with ``C(|k|)`` and
    each cell's transform (``sinc^2`` in both directions, cell average in and out); the pressures that lower every
    footprint cell by 1 by conjugate gradients (the operator is symmetric positive definite). A punch's force is
    half the union's force (the two are mirror images: splitting the cells by the midline would hand the midline's
    column, 1 % of the force at 4 mm on a 0.2 mm grid, to one of them).

    Parameters
    ----------
    stack : tuple of (float, float)
        :func:`layers`.
    radius_m : float
        Each punch's radius (m).
    distance_m : float
        Their centres' distance (m); below ``2 radius_m`` the footprints overlap, as the reference's pair does (one
        rigid body of the union footprint).
    poisson, cell_m, domain_m : float
        Poisson's ratio, :data:`PAIR_CELL_M`, :data:`PAIR_DOMAIN_M`.

    Returns
    -------
    float
        ``F_pair / F_single - 1`` per punch.
    """
    n = int(round(domain_m / cell_m))
    n += n % 2
    k1 = 2 * np.pi * np.fft.fftfreq(n, d=cell_m)
    kx, ky = np.meshgrid(k1, k1, indexing="ij")
    comp = _compliance_at(np.hypot(kx, ky), stack, poisson)
    comp *= (np.sinc(kx * cell_m / (2 * np.pi)) * np.sinc(ky * cell_m / (2 * np.pi))) ** 2
    x = (np.arange(n) - n // 2) * cell_m
    gx, gy = np.meshgrid(x, x, indexing="ij")

    def force(centres: list[float]) -> float:
        mask = np.zeros((n, n), bool)
        for cx in centres:
            mask |= (gx - cx) ** 2 + gy**2 <= radius_m**2
        full = np.zeros((n, n))

        def op(p: np.ndarray) -> np.ndarray:
            full[:] = 0.0
            full[mask] = p
            return np.fft.ifft2(np.fft.fft2(full) * comp).real[mask]

        m = int(mask.sum())
        p, info = sparse_linalg.cg(sparse_linalg.LinearOperator((m, m), matvec=op, dtype=float), np.ones(m), rtol=1e-9)
        if info != 0:
            raise RuntimeError(f"the pair's pressures did not converge ({info} iterations)")
        return float(p.sum()) * cell_m**2 / len(centres)  # two equal punches carry half the union's force

    half = 0.5 * distance_m
    return force([-half, half]) / force([half]) - 1.0
