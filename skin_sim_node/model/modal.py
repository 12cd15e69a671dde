"""Modal coefficients of the indentation shape (eqs 2-3), closed form.

The initial shape ``f`` of eq 3 is the membrane's own static deflection under the
tool: a uniform pressure ``p`` on a disk of radius ``r0`` centred at ``(xc, yc)`` on an
``a x b`` patch with fixed edges, i.e. the solution of ``-T lap(w) = p``. Its sine
coefficients follow exactly from eq 3 applied to the load::

    p_mn = (4 / ab) p * 2 pi r0 J1(kappa r0) / kappa * sin(m pi xc / a) sin(n pi yc / b)
    W_mn = p_mn / (T kappa^2),   kappa_mn = pi sqrt(m^2/a^2 + n^2/b^2) = lambda_mn / c

using ``int_disk sin(alpha x) sin(beta y) dA = 2 pi r0 J1(kappa r0)/kappa sin(alpha xc)
sin(beta yc)``. The shape is normalised so the truncated series is exactly 1 at the
contact point: a layer compressed by ``dx`` has ``B_mn = dx * beta_mn``. ``T`` and ``p``
cancel, so ``beta`` depends only on the geometry, and with the contact at the patch
centre only odd ``m`` and odd ``n`` survive.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from scipy.special import j1

from .config import TissueConfig


def disk_load_coefficients(m_max, n_max, a, b, r0, xc=None, yc=None) -> np.ndarray:
    """Unnormalised static-deflection coefficients ``T W_mn / p`` (units m^2), shape (M, N)."""
    xc = a / 2 if xc is None else xc
    yc = b / 2 if yc is None else yc
    m = np.arange(1, m_max + 1)[:, None]
    n = np.arange(1, n_max + 1)[None, :]
    kappa = np.pi * np.sqrt((m / a) ** 2 + (n / b) ** 2)
    load = (4.0 / (a * b)) * 2 * np.pi * r0 * j1(kappa * r0) / kappa
    sin_x = np.sin(m * np.pi * xc / a)
    sin_y = np.sin(n * np.pi * yc / b)
    sin_x[np.abs(sin_x) < 1e-12] = 0.0  # exact nodes, e.g. even modes of a centred load
    sin_y[np.abs(sin_y) < 1e-12] = 0.0
    return load * sin_x * sin_y / kappa**2


def shape_coefficients(m_max: int, n_max: int, a: float, b: float, r0: float) -> np.ndarray:
    """``beta_mn``: eq 3 coefficients of the unit-depth indentation shape, shape (M, N)."""
    w = disk_load_coefficients(m_max, n_max, a, b, r0)
    m = np.arange(1, m_max + 1)[:, None]
    n = np.arange(1, n_max + 1)[None, :]
    centre = np.sin(m * np.pi / 2) * np.sin(n * np.pi / 2)
    return w / np.sum(w * centre)


@dataclass(frozen=True)
class ModalBasis:
    """The active modes (nonzero ``beta``) and per-layer ``lambda`` and damping."""

    mode_m: np.ndarray  # (K,) int64, 1-based
    mode_n: np.ndarray  # (K,) int64
    beta: np.ndarray  # (K,) shape coefficients, dimensionless
    lam: np.ndarray  # (L, K) rad/s, eq 3: c pi sqrt(m^2/a^2 + n^2/b^2)
    gamma: np.ndarray  # (L,) 1/s, modal damping rate from each layer's b
    m_used: np.ndarray  # distinct mode_m values, for the separable grid sum
    n_used: np.ndarray  # distinct mode_n values

    @property
    def n_modes(self) -> int:
        return int(self.beta.shape[0])


def modal_basis(cfg: TissueConfig) -> ModalBasis:
    """Build the basis for ``cfg``: only modes with a nonzero coefficient are kept.

    Damping: the layer's Kelvin-Voigt damper ``b`` acts on the fundamental mode's modal
    mass ``m11 = rho_A a b / 4``, so every mode decays at ``gamma = b / (2 m11)``
    (uniform viscous damping of the membrane).
    """
    a, b = cfg.patch_size_m
    m_max, n_max = cfg.modes
    beta = shape_coefficients(m_max, n_max, a, b, cfg.tool_radius_m)
    keep = beta != 0.0
    mm, nn = np.nonzero(keep)
    mode_m = (mm + 1).astype(np.int64)
    mode_n = (nn + 1).astype(np.int64)
    kappa = np.pi * np.sqrt((mode_m / a) ** 2 + (mode_n / b) ** 2)
    lam = np.array([layer.wave_speed_m_per_s * kappa for layer in cfg.layers])
    gamma = np.array([layer.damping_n_s_per_m / (2 * layer.areal_density_kg_per_m2 * a * b / 4) for layer in cfg.layers])
    beta_k = np.ascontiguousarray(beta[keep])
    return ModalBasis(mode_m, mode_n, beta_k, lam, gamma, np.unique(mode_m), np.unique(mode_n))
