"""Slow, obviously correct NumPy versions of the kernels, and a NumPy ``SkinModel``.

Used by the tests as the reference for every kernel, and by the micro-benchmark as the
"pure NumPy" baseline of the same step. Written for clarity, not speed.
"""

from __future__ import annotations

import numpy as np
from scipy.linalg import expm

from skin_sim_node.model.config import TissueConfig
from skin_sim_node.model.interfaces import interface_depths_m
from skin_sim_node.model.modal import modal_basis


def reuss_split_ref(n, depth_m, velocity_m_s, k, b, area, thickness):
    """Reuss split (eqs 4, 6) with bound handling; returns (compressions, stress, force, hit)."""
    comp = np.zeros(n)
    fixed = np.zeros(n, dtype=bool)
    sigma = 0.0
    hit = False
    while n and not fixed.all():
        free = ~fixed
        rest = depth_m - comp[fixed].sum()
        sigma = (rest + velocity_m_s * np.sum(b[:n][free] / k[:n][free])) / np.sum(area[:n][free] / k[:n][free])
        trial = (sigma * area[:n] - b[:n] * velocity_m_s) / k[:n]
        excess = np.where(free, np.maximum(-trial, trial - thickness[:n]), 0.0)
        comp[free] = trial[free]
        if excess.max() <= 0.0:
            break
        worst = int(np.argmax(excess))
        hit = True
        fixed[worst] = True
        comp[worst] = 0.0 if trial[worst] < 0.0 else thickness[worst]
    if n and fixed.all():
        sigma = max(0.0, max((k[i] * comp[i] + b[i] * velocity_m_s) / area[i] for i in range(n)))
    force = sigma * area[0] if n else 0.0
    return comp, sigma, force, hit


def propagator_expm(lam, gamma, dt):
    """Transition matrices by the matrix exponential of ``[[0, 1], [-lam^2, -2 gamma]] dt``."""
    out = np.zeros((4, *lam.shape))
    for li in range(lam.shape[0]):
        for kk in range(lam.shape[1]):
            a = np.array([[0.0, 1.0], [-(lam[li, kk] ** 2), -2.0 * gamma[li]]])
            p = expm(a * dt)
            out[:, li, kk] = p.ravel()
    return out


def propagator_ref(lam, gamma, dt):
    """Vectorised closed form with complex frequencies (covers all damping regimes)."""
    g = np.asarray(gamma, dtype=float)[:, None] * np.ones_like(lam)
    w = np.sqrt((lam**2 - g**2).astype(complex))
    w = np.where(np.abs(w) < 1e-300, 1e-300, w)
    e = np.exp(-g * dt)
    ec = (e * np.cos(w * dt)).real
    es = (e * np.sin(w * dt) / w).real
    return np.stack([ec + g * es, es, -(lam**2) * es, ec - g * es])


def layer_field_ref(q_l, cx, cy, mode_m, mode_n, a, b, xs, ys, angle_rad=0.0):
    """Eq 2 summed directly over every mode at every grid cell inside the patch; ``angle_rad`` turns the patch's first
    side from the x axis (the tension lines): a cell's patch coordinates are its offset rotated by ``-angle``."""
    X, Y = np.meshgrid(xs, ys)
    c, s = np.cos(angle_rad), np.sin(angle_rad)
    xi = c * (X - cx) + s * (Y - cy) + a / 2
    eta = -s * (X - cx) + c * (Y - cy) + b / 2
    inside = (xi > 0) & (xi < a) & (eta > 0) & (eta < b)
    u = np.zeros_like(X)
    for qk, m, n in zip(q_l, mode_m, mode_n):
        u += qk * np.sin(m * np.pi * xi / a) * np.sin(n * np.pi * eta / b)
    return np.where(inside, u, 0.0)


def assemble_heights_ref(disp, rest_tops):
    """Interface heights (m) from per-layer displacements: each interface sits at its rest depth moved by every layer below it."""
    below = np.cumsum(disp[::-1], axis=0)[::-1]
    return -rest_tops - below


class NumpySkinModel:
    """The same model as :class:`~skin_sim_node.model.skin_model.SkinModel`, in NumPy."""

    def __init__(self, cfg: TissueConfig):
        self.cfg = cfg
        self.basis = modal_basis(cfg)
        n_l = len(cfg.layers)
        self.k = np.array([la.stiffness_n_per_m for la in cfg.layers])
        self.b = np.array([la.damping_n_s_per_m for la in cfg.layers])
        self.area = np.array([la.area_m2 for la in cfg.layers])
        self.q = np.zeros((n_l, self.basis.n_modes))
        self.v = np.zeros_like(self.q)
        self.centre = np.zeros((n_l, 2))
        self.driven = np.zeros(n_l, dtype=bool)
        self.compression_m = np.zeros(n_l)
        self.level = np.zeros(n_l, dtype=int)
        self.dropped_m = np.zeros(n_l)
        self.force_n = 0.0
        self.n_affected = 0
        self.flags = 0
        ny, nx = cfg.grid_shape
        sx, sy = cfg.sheet_size_m
        self.xs = -0.5 * sx + (np.arange(nx) + 0.5) * sx / nx
        self.ys = -0.5 * sy + (np.arange(ny) + 0.5) * sy / ny

    def _point(self, li, x, y):
        a, b = self.cfg.patch_size_m
        c, s = np.cos(self.cfg.anisotropy_angle_rad), np.sin(self.cfg.anisotropy_angle_rad)  # the patch along the lines
        dx, dy = x - self.centre[li, 0], y - self.centre[li, 1]
        xi = c * dx + s * dy + a / 2
        eta = -s * dx + c * dy + b / 2
        if not (0 < xi < a and 0 < eta < b):
            return 0.0
        bm = self.basis
        return float(np.sum(self.q[li] * np.sin(bm.mode_m * np.pi * xi / a) * np.sin(bm.mode_n * np.pi * eta / b)))

    def step(self, tool_xyz, tool_velocity, dt):
        """One tick: tool at ``tool_xyz`` (m), moving at ``tool_velocity`` (m/s), for ``dt`` (s); NumPy :meth:`SkinModel.step`."""
        x, y, z = (float(c) for c in tool_xyz)
        depth, velocity = -z, -float(tool_velocity[2])
        n_l = self.q.shape[0]
        surface = sum(self._point(li, x, y) for li in range(n_l))
        sx, sy = self.cfg.sheet_size_m
        on_sheet = abs(x) <= sx / 2 and abs(y) <= sy / 2
        touching = on_sheet and depth > 0 and (self.driven.any() or depth >= surface)
        n, force, flags = 0, 0.0, 0 if on_sheet else 16
        if touching:
            tops = np.concatenate([[0.0], interface_depths_m(self.cfg, x, y).ravel(), [self.cfg.total_thickness_m]])
            d_eff = min(depth, tops[-1])
            flags |= 2 if depth > tops[-1] else 0
            n = int(np.sum(d_eff > tops[:-1]))
            comp, sigma, force, hit = reuss_split_ref(n, d_eff, velocity, self.k, self.b, self.area, np.diff(tops))
            flags |= 4 if hit else 0
            if force <= 0 or sigma <= 0:
                touching, force, flags = False, 0.0, flags | 8
        if touching:
            flags |= 1
        else:
            n = 0
        prop = propagator_ref(self.basis.lam, self.basis.gamma, dt)
        lod = self.cfg.lod
        for li in range(n_l):
            if li < n:
                self.compression_m[li] = comp[li]
                bm = self.basis
                lv = 0  # smallest level within tolerance (the last if none is)
                if bm.level_modes.size > 1:
                    ok = np.nonzero(abs(comp[li]) * bm.trunc_err <= lod.tolerance_m)[0]
                    lv = int(ok[0]) if ok.size else bm.level_modes.size - 1
                self.level[li], self.dropped_m[li] = lv, 0.0
                self.q[li] = comp[li] * bm.beta_table[lv]
                self.v[li] = velocity * np.clip(comp[li] / d_eff, 0.0, 1.0) * bm.beta_table[lv]
                self.centre[li] = (x, y)
                self.driven[li] = True
            else:
                self.compression_m[li] = 0.0
                self.driven[li] = False
                q0, v0 = self.q[li].copy(), self.v[li].copy()
                self.q[li] = prop[0, li] * q0 + prop[1, li] * v0
                self.v[li] = prop[2, li] * q0 + prop[3, li] * v0
                bound = np.sum(np.hypot(self.q[li], self.v[li] / self.basis.lam[li]))
                lv = self.level[li]
                if self.basis.level_modes.size > 1 and lv > 0:  # shed the outer shell once negligible
                    shell = slice(self.basis.k_prefix[lv - 1], self.basis.k_prefix[lv])
                    tail = np.sum(np.hypot(self.q[li, shell], self.v[li, shell] / self.basis.lam[li, shell]))
                    if self.dropped_m[li] + tail <= lod.tolerance_m:
                        self.q[li, shell] = 0.0
                        self.v[li, shell] = 0.0
                        self.level[li] -= 1
                        self.dropped_m[li] += tail
                if lod.affected_layers and bound < lod.tolerance_m:  # settled: set to rest
                    self.q[li] = 0.0
                    self.v[li] = 0.0
        self.force_n, self.n_affected, self.flags = force, n, flags
        return force

    def build_grid(self):
        """The height maps of every interface on the output grid: NumPy form of :meth:`SkinModel.build_grid`."""
        a, b = self.cfg.patch_size_m
        bm = self.basis
        disp = np.stack(
            [
                layer_field_ref(
                    self.q[li],
                    self.centre[li, 0],
                    self.centre[li, 1],
                    bm.mode_m,
                    bm.mode_n,
                    a,
                    b,
                    self.xs,
                    self.ys,
                    self.cfg.anisotropy_angle_rad,
                )
                for li in range(self.q.shape[0])
            ]
        )
        X, Y = np.meshgrid(self.xs, self.ys)
        rest = np.concatenate([np.zeros((1, *X.shape)), interface_depths_m(self.cfg, X, Y)])
        return disp, assemble_heights_ref(disp, rest)


# --- layered form (skin_sim_node.model.layered) ------------------------------------------------


def compression_law_ref(eps, n, wall):
    """``phi(eps)`` of the layered form's law, written directly (tangent continuation past ``wall``)."""

    def phi(e):
        return -np.log1p(-e) if n <= 1e-9 else ((1.0 - e) ** (-n) - 1.0) / n

    from skin_sim_node.model.calibration import BONE_STIFFNESS, BONE_STRAIN

    x = min(max(eps - BONE_STRAIN, 0.0), 1.0 - BONE_STRAIN)
    bone = BONE_STIFFNESS * (0.5 * x * x + x * max(eps - 1.0, 0.0))
    if eps <= wall:
        return phi(eps) + bone
    dphi = (1.0 - wall) ** (-n - 1.0)
    return phi(wall) + dphi * (eps - wall) + bone


def chain_solve_ref(d, ea, n, b, dt, c_old, h, wall, off=None):
    """Backward-Euler series chain by bracketing (``scipy.optimize.brentq``), independent of the Newton kernel.

    ``off``: each layer's carried-in viscoelastic arm force (N; default none), added to its law.

    Returns ``(T, c)``; ``T = -1`` when the chain relaxed at zero force is at least ``d`` long.
    """
    from scipy.optimize import brentq

    dt = max(dt, 1e-6)
    off = np.zeros(len(ea)) if off is None else off

    def comp(t, i):
        f = lambda c: ea[i] * compression_law_ref(c / h[i], n[i], wall) + b[i] / dt * (c - c_old[i]) + off[i] - t  # noqa: E731
        lo, hi = -10.0 * h[i] - abs(c_old[i]), 10.0 * h[i] + abs(c_old[i])
        while f(lo) > 0:
            lo *= 2
        while f(hi) < 0:
            hi *= 2
        return brentq(f, lo, hi, xtol=1e-18, rtol=1e-15)

    nl = len(ea)
    if sum(comp(0.0, i) for i in range(nl)) >= d:
        return -1.0, np.array([comp(0.0, i) for i in range(nl)])
    hi = 1.0
    while sum(comp(hi, i) for i in range(nl)) < d:
        hi *= 2
    t = brentq(lambda t: sum(comp(t, i) for i in range(nl)) - d, 0.0, hi, xtol=1e-15, rtol=1e-14)
    return t, np.array([comp(t, i) for i in range(nl)])


def averaged_interface_ref(mean, amp, kx, ky, x0, y0, radius, n=400):
    """Disk average of ``mean - amp cos(kx x) cos(ky y)`` over a disk by Gauss-Legendre quadrature in polar form."""
    r, wr = np.polynomial.legendre.leggauss(n)
    r = 0.5 * radius * (r + 1)
    wr = 0.5 * radius * wr
    th = np.linspace(0, 2 * np.pi, 2 * n, endpoint=False)
    R, TH = np.meshgrid(r, th, indexing="ij")
    vals = mean - amp * np.cos(kx * (x0 + R * np.cos(TH))) * np.cos(ky * (y0 + R * np.sin(TH)))
    integral = np.sum(vals * R * wr[:, None]) * (2 * np.pi / (2 * n))
    return integral / (np.pi * radius**2)


def presliding_tangent_ref(normal, stretch, k_t, mu, force_n, grad):
    """NumPy reference of :func:`skin_sim_node.model.friction.presliding_tangent`: returns ``K``.

    ``K = n grad^T - k_t P`` sticking; slipping (``k_t |s| >= mu F_n``) ``F_t = -mu F_n u``, ``u = s / |s|``:
    ``K = n grad^T - mu u grad^T - (mu F_n / |s|) (P - u u^T)``."""
    normal, stretch, grad = (np.asarray(a, dtype=float) for a in (normal, stretch, grad))
    proj = np.eye(3) - np.outer(normal, normal)
    k = np.outer(normal, grad)
    if k_t <= 0 or mu * force_n <= 0:
        return k
    s = float(np.linalg.norm(stretch))
    if s > 0 and k_t * s >= mu * force_n * (1 - 1e-12):
        u = stretch / s
        return k - mu * np.outer(u, grad) - (mu * force_n / s) * (proj - np.outer(u, u))
    return k - k_t * proj


def footprint_ref(x, y, r, half_x, half_y):
    """NumPy/SciPy reference of :func:`skin_sim_node.model.modal_kernels.footprint`'s fraction and centroid.

    The overlap of the disk (radius ``r`` at ``(x, y)``) with the sheet as 1D integrals over the disk's chords
    (``scipy.integrate.quad``): area ``int L(X) dX``, moments ``int X L(X) dX`` and ``int (hi^2 - lo^2) / 2 dX``.
    Returns ``(frac, cx, cy)``.
    """
    import warnings

    from scipy.integrate import IntegrationWarning, quad

    x0, x1, y0, y1 = -half_x - x, half_x - x, -half_y - y, half_y - y

    def chord(px):
        s = np.sqrt(max(r * r - px * px, 0.0))
        return max(y0, -s), min(y1, s)

    def length(px):
        lo, hi = chord(px)
        return max(0.0, hi - lo)

    def moment_y(px):
        lo, hi = chord(px)
        return 0.5 * (hi * hi - lo * lo) if hi > lo else 0.0

    lo, hi = max(x0, -r), min(x1, r)
    if hi <= lo:
        return 0.0, x, y
    kinks = [sg * np.sqrt(r * r - yy * yy) for yy in (y0, y1) if abs(yy) < r for sg in (-1.0, 1.0)]  # chord meets y0, y1
    pts = [p for p in (x0, x1, *kinks) if lo < p < hi] or None
    kw = dict(points=pts, epsabs=0.0, epsrel=1e-12, limit=200)
    with warnings.catch_warnings():  # quad warns of round-off at 1e-12 relative; the fraction is still ~1e-14
        warnings.simplefilter("ignore", IntegrationWarning)
        area = quad(length, lo, hi, **kw)[0]
        if area <= 0.0:
            return 0.0, x, y
        mx = quad(lambda px: px * length(px), lo, hi, **kw)[0]
        my = quad(moment_y, lo, hi, **kw)[0]
    return area / (np.pi * r * r), x + mx / area, y + my / area
