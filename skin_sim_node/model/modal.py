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

**Foundation** (``patch.foundation_length_m = l``, layered default). Each membrane rests on the
tissue below it, an elastic (Winkler) foundation of stiffness ``k_A = T / l^2`` per unit area:
eq 1 becomes ``rho_A u_tt = T lap(u) - (T / l^2) u`` (a Pasternak foundation: the membrane's
tension is its shear layer). Eq 3 keeps its sine modes; ``kappa^2`` becomes ``kappa^2 + 1/l^2``
in the static shape (``W_mn = p_mn / (T (kappa^2 + 1/l^2))``) and in the modal frequencies
(``lambda_mn = c sqrt(kappa^2 + 1/l^2)``). The dent then decays over about ``l`` from the tool,
as a layered solid's surface does, instead of spreading over the whole patch; ``l = 0`` (the
``paper`` preset) is the paper's bare membrane. ``l`` is fitted to the large-deformation
reference's surface fields (``skin-sim calibrate``).

**Tension lines** (``anisotropy.ratio = r``, ``anisotropy.angle_rad``; docs/model.md, "Tension lines"). The patch's
first side ``a`` is laid along the lines (the kernels rotate ``(x - cx, y - cy)`` into the patch frame), and the
membrane is ``rho_A u_tt = T_x u_xx + T_y u_yy - (T / l^2) u`` in that frame with ``T_x = T sqrt(r)``,
``T_y = T / sqrt(r)`` (geometric mean ``T``, the layer's ``tension_n_per_m``). The sine modes stay exact; ``kappa^2``
becomes ``sqrt(r) (m pi / a)^2 + (n pi / b)^2 / sqrt(r)`` (:func:`membrane_wavenumber2`) in ``W_mn`` and in
``lambda_mn^2 = (T_x kx^2 + T_y ky^2 + T / l^2) / rho_A``. The foundation ``k_A = T / l^2`` keeps the geometric
mean: it is the tissue below, pressed normally, not the membrane's in-plane coefficient. ``r = 1`` is the isotropic
membrane, bit for bit. ``T`` still cancels from ``beta`` (one ``r`` for every layer).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from scipy.special import j1

from .config import TissueConfig


def foundation_wavenumber2(foundation_length_m: float) -> float:
    """``1 / l^2`` (1/m^2) of a foundation of decay length ``l``; 0 for none (``l = 0``, the bare membrane)."""
    return 1.0 / foundation_length_m**2 if foundation_length_m > 0 else 0.0


def membrane_wavenumber2(m, n, a, b, ratio=1.0):
    """``(sqrt(r) (m pi / a)^2 + (n pi / b)^2 / sqrt(r)``: the anisotropic membrane's ``kappa^2`` (1/m^2).

    The wave operator ``T_x u_xx + T_y u_yy`` with ``T_x = T sqrt(r)`` along the patch's first side (the tension lines)
    and ``T_y = T / sqrt(r)`` across, over the geometric mean ``T``; ``r = 1`` is ``pi^2 (m^2/a^2 + n^2/b^2)``.
    """
    sr = float(np.sqrt(ratio))
    return np.pi**2 * (sr * (m / a) ** 2 + (n / b) ** 2 / sr)


def disk_load_coefficients(m_max, n_max, a, b, r0, xc=None, yc=None, foundation_length_m=0.0, ratio=1.0) -> np.ndarray:
    """Unnormalised static-deflection coefficients ``T W_mn / p`` (units m^2), shape (M, N); ``ratio``: the
    tension ratio along / across the patch's first side (:func:`membrane_wavenumber2`)."""
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
    k2 = kappa**2 if ratio == 1.0 else membrane_wavenumber2(m, n, a, b, ratio)  # the disk's load stays isotropic
    return load * sin_x * sin_y / (k2 + foundation_wavenumber2(foundation_length_m))


def shape_coefficients(m_max: int, n_max: int, a: float, b: float, r0: float, foundation_length_m=0.0, ratio=1.0) -> np.ndarray:
    """``beta_mn``: eq 3 coefficients of the unit-depth indentation shape, shape (M, N)."""
    w = disk_load_coefficients(m_max, n_max, a, b, r0, foundation_length_m=foundation_length_m, ratio=ratio)
    m = np.arange(1, m_max + 1)[:, None]
    n = np.arange(1, n_max + 1)[None, :]
    centre = np.sin(m * np.pi / 2) * np.sin(n * np.pi / 2)
    return w / np.sum(w * centre)


def truncation_bound(w: np.ndarray, m_max: int | np.integer, n_max: int | np.integer) -> float:
    """Sup-norm bound on ``|u_MN - u_ref|`` per metre of compression, from the coefficients alone.

    ``w`` (P, Q) are the reference coefficients (:func:`disk_load_coefficients`); ``u_ref`` is
    the unit-normalised series over all of them and ``u_MN`` the one truncated to ``m <= M,
    n <= N`` and renormalised to 1 at the contact. Since ``|sin| <= 1``::

        |u_MN - u_ref| <= sum_tail |w| / |S_ref| + sum_MN |w| |1/S_MN - 1/S_ref|

    with ``S = sum w sin(m pi/2) sin(n pi/2)`` the series at the contact (the normalisation).
    """
    p, q = w.shape
    centre = np.outer(np.sin(np.arange(1, p + 1) * np.pi / 2), np.sin(np.arange(1, q + 1) * np.pi / 2))
    s_ref = float(np.sum(w * centre))
    head = np.abs(w[:m_max, :n_max])
    s_mn = float(np.sum(w[:m_max, :n_max] * centre[:m_max, :n_max]))
    return float((np.abs(w).sum() - head.sum()) / abs(s_ref) + head.sum() * abs(1.0 / s_mn - 1.0 / s_ref))


REFERENCE_MODES = 60
"""Modes per axis of the reference solution the adaptive count is measured against (issue 7)."""


@dataclass(frozen=True)
class ModalBasis:
    """The active modes (nonzero ``beta``) and per-layer ``lambda`` and damping.

    Modes are stored in shells of ``max(m, n)``, so that the first ``k_prefix[i]`` modes are
    exactly the odd modes of the square ``level_modes[i] x level_modes[i]``: a layer with
    fewer modes uses a prefix. ``beta_table[i]`` is the shape normalised for that prefix
    (zeros beyond it) and ``trunc_err[i]`` its bound against the reference (per metre of
    compression). With a fixed mode count (``lod.adaptive_modes`` off) there is one level.
    """

    mode_m: np.ndarray  # (K,) int64, 1-based
    mode_n: np.ndarray  # (K,) int64
    beta: np.ndarray  # (K,) shape coefficients of the full basis, dimensionless
    lam: np.ndarray  # (L, K) rad/s, eq 3: c sqrt(pi^2 (m^2/a^2 + n^2/b^2) + 1/l^2)
    gamma: np.ndarray  # (L,) 1/s, modal damping rate from each layer's b
    m_used: np.ndarray  # distinct mode_m values, for the separable grid sum
    n_used: np.ndarray  # distinct mode_n values
    level_modes: np.ndarray  # (V,) int64, modes per axis of each level
    k_prefix: np.ndarray  # (V,) int64, modes in each level's prefix
    m_lim: np.ndarray  # (V,) int64, largest m or n in each level
    beta_table: np.ndarray  # (V, K) beta of each level, zero beyond its prefix
    trunc_err: np.ndarray  # (V,) truncation bound per metre of compression (0: the reference itself)

    @property
    def n_modes(self) -> int:
        """Number of modal terms (``M x N`` in eq 2)."""
        return int(self.beta.shape[0])


def _shell_modes(m_max: int, n_max: int):
    """Odd (m, n) with m <= m_max, n <= n_max, ordered by shell max(m, n), then m, then n."""
    pairs = [(m, n) for m in range(1, m_max + 1, 2) for n in range(1, n_max + 1, 2)]
    pairs.sort(key=lambda p: (max(p), p[0], p[1]))
    return np.array([p[0] for p in pairs], dtype=np.int64), np.array([p[1] for p in pairs], dtype=np.int64)


def modal_basis(cfg: TissueConfig, radius_m: float | None = None) -> ModalBasis:
    """Build the basis for ``cfg``: only modes with a nonzero coefficient are kept.

    Damping: the layer's Kelvin-Voigt damper ``b`` acts on the fundamental mode's modal
    mass ``m11 = rho_A a b / 4``, so every mode decays at ``gamma = b / (2 m11)``
    (uniform viscous damping of the membrane). A foundation raises every ``lambda`` (module
    docstring); it is taken as viscoelastic, with a dashpot that keeps the (1,1) mode's damping
    ratio ``gamma / lambda_11`` (the default ``b`` critically damps it, ``msgs_schema.tissue``), so
    ``gamma`` grows by the factor ``lambda_11`` grows and the released dent does not overshoot.
    With ``lod.adaptive_modes`` the basis holds the odd modes up to :data:`REFERENCE_MODES` per
    axis, in levels of 1, 3, 5, ... modes per axis; otherwise the fixed ``modes.m x modes.n``.
    ``radius_m``: the loaded disk's radius (the indenter's, :class:`~.contact.Indenter`); default ``cfg.tool_radius_m``.
    """
    a, b = cfg.patch_size_m
    r0 = cfg.tool_radius_m if radius_m is None else radius_m
    ell = cfg.foundation_length_m
    adaptive = cfg.lod.adaptive_modes
    m_max, n_max = (REFERENCE_MODES, REFERENCE_MODES) if adaptive else cfg.modes
    mode_m, mode_n = _shell_modes(m_max, n_max)
    ratio = cfg.anisotropy_ratio
    w = disk_load_coefficients(m_max, n_max, a, b, r0, foundation_length_m=ell, ratio=ratio)
    centre = np.sin(mode_m * np.pi / 2) * np.sin(mode_n * np.pi / 2)
    w_k = w[mode_m - 1, mode_n - 1]
    beta_k = np.ascontiguousarray(w_k / np.sum(w_k * centre))
    if adaptive:
        levels = np.arange(1, m_max + 1, 2, dtype=np.int64)
        w_ref = disk_load_coefficients(REFERENCE_MODES, REFERENCE_MODES, a, b, r0, foundation_length_m=ell, ratio=ratio)
        k_prefix = np.array([((lv + 1) // 2) ** 2 for lv in levels], dtype=np.int64)
        table = np.zeros((levels.size, beta_k.size))
        for i, k in enumerate(k_prefix):
            table[i, :k] = w_k[:k] / np.sum(w_k[:k] * centre[:k])
        err = np.array([truncation_bound(w_ref, lv, lv) for lv in levels])
        m_lim = levels.copy()
    else:
        levels = np.array([max(m_max, n_max)], dtype=np.int64)
        k_prefix = np.array([beta_k.size], dtype=np.int64)
        table = beta_k[None, :].copy()
        err = np.zeros(1)  # not used: a fixed count is not chosen by tolerance
        m_lim = levels.copy()
    kappa2 = membrane_wavenumber2(mode_m, mode_n, a, b, ratio)
    kappa = np.sqrt(kappa2 + foundation_wavenumber2(ell))
    lam = np.array([layer.wave_speed_m_per_s * kappa for layer in cfg.layers])
    # the foundation's dashpot keeps the fundamental's damping ratio: gamma scales as its lambda does (over the bare
    # isotropic membrane's, which the default b critically damps); so does the tension lines' change of lambda_11
    k11_iso = np.pi**2 * (1 / a**2 + 1 / b**2)
    if ratio == 1.0:
        found = float(np.sqrt(1.0 + foundation_wavenumber2(ell) / k11_iso))
    else:
        found = float(np.sqrt((membrane_wavenumber2(1, 1, a, b, ratio) + foundation_wavenumber2(ell)) / k11_iso))
    gamma = np.array([found * layer.damping_n_s_per_m / (2 * layer.areal_density_kg_per_m2 * a * b / 4) for layer in cfg.layers])
    return ModalBasis(
        mode_m, mode_n, beta_k, lam, gamma, np.unique(mode_m), np.unique(mode_n), levels, k_prefix, m_lim, table, err
    )


def level_for(basis: ModalBasis, compression_m: float, tolerance_m: float) -> int:
    """Index of the smallest level whose truncation error at ``compression_m`` is within ``tolerance_m``."""
    for i in range(basis.level_modes.size):
        if abs(compression_m) * basis.trunc_err[i] <= tolerance_m:
            return i
    return basis.level_modes.size - 1
