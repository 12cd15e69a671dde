"""Large-deformation reference: layered compressible neo-Hookean skin under a rigid flat punch.

Model (axisymmetric, flat layers)
---------------------------------
The three layers of a :class:`~skin_sim_node.model.TissueConfig` as flat slabs (thicknesses
``layers.*.thickness_m``, the interfaces at their mean depths), a cylinder of radius
``extent_m`` around the tool axis, z up, rest surface z = 0, bottom z = -H. Material per layer:
the compressible neo-Hookean strain energy (Bonet & Wood, *Nonlinear Continuum Mechanics for
Finite Element Analysis*, 2nd ed., eq 6.27)::

    W = mu/2 (I1 - 3) - mu ln J + lam/2 (ln J)^2,   P = mu (F - F^-T) + lam ln J F^-T

with ``mu, lam`` the Lame constants of the layer's Young's modulus and the Poisson ratio, so the
small-strain limit is the linear FEM of :mod:`.fem` exactly (same E, same nu). Ogden is not
fitted: the in-vivo skin indentation data at hand are force-depth curves at one tool, which fix
one modulus per layer and cannot separate Ogden's extra exponents (stated, not guessed).

Axisymmetric kinematics, total Lagrangian: with ``(R, Z)`` the reference position and
``u = (u_r, u_z)``, ``F = [[1 + du_r/dR, du_r/dZ, 0], [du_z/dR, 1 + du_z/dZ, 0], [0, 0, 1 + u_r/R]]``;
volume element ``2 pi R dR dZ``. Element: 9-node biquadratic quads (``ElementQuad2``) with 4x4
Gauss points (quadratic elements do not lock at nu = 0.48, see :mod:`.fem`).

Boundary conditions: bottom fixed (fat bonded to fascia, rigid); outer cylinder rollers
(``u_r = 0``); axis ``u_r = 0``; tool: a rigid frictionless flat punch of radius ``r0``,
displacement controlled: ``u_z = -depth`` on the surface nodes with ``R <= r0``, ``u_r`` free.
The contact set is the punch face in the reference configuration (the radial slip of the punch
edge node is returned, ``edge_slip_m``, so its size can be judged against the mesh).

Solver: Newton-Raphson on the free DOFs, the exact consistent tangent (``dP/dF``), load steps
in depth with step halving when an iteration diverges or a Gauss point inverts (J <= 0). The
reaction is the sum of the internal nodal z-forces on the punch DOFs. Results are cached in
``docs/validation/hyper_cache/<hash>.npz`` (a few kB: the force-depth curve and surface profiles),
so charts and tests run from the cache; a fresh solve shows a tqdm bar over depth.
"""

from __future__ import annotations

import hashlib
import json
import time
from dataclasses import asdict, dataclass, replace
from pathlib import Path

import numpy as np
import scipy.sparse as sp
import scipy.sparse.linalg as spla
from skfem import Basis, ElementQuad2, ElementVector, MeshQuad
from tqdm import tqdm

from skin_sim_node.model.calibration import POISSON_RATIO, layer_moduli_pa
from skin_sim_node.model.config import TissueConfig, preset

from .cache import cached
from .fem import axis_nodes

HYPER_VERSION = 1  # bump when the discretisation or solver changes: part of the cache key
CACHE_DIR = Path(__file__).resolve().parents[2] / "docs" / "validation" / "hyper_cache"
SAVE_DEPTHS_M = (0.1e-3, 0.5e-3, 1e-3, 2e-3, 3e-3)  # depths whose surface profile is stored


@dataclass(frozen=True)
class AxiSetup:
    """One axisymmetric punch solve (lengths in m, moduli in Pa).

    ``n_tool`` elements span the tool radius (then 3 more of that size, then ``n_out`` graded
    ones to ``extent_m``); ``nz`` elements over (epidermis, dermis, fat), the fat graded finer
    near the dermis. ``law`` is ``"neo-hookean"`` or ``"linear"`` (small strain, one solve).
    """

    thickness_m: tuple[float, float, float]
    moduli_pa: tuple[float, float, float]
    tool_radius_m: float
    poisson: float = POISSON_RATIO
    extent_m: float = 0.03
    n_tool: int = 8
    n_out: int = 12
    nz: tuple[int, int, int] = (2, 8, 10)
    max_depth_m: float = 3e-3
    n_steps: int = 30
    law: str = "neo-hookean"

    def key(self) -> str:
        """Cache key: a hash of the setup and :data:`HYPER_VERSION`."""
        blob = json.dumps({"v": HYPER_VERSION, **asdict(self)}, sort_keys=True)
        return hashlib.sha256(blob.encode()).hexdigest()[:16]


def setup_from_config(cfg: TissueConfig | None = None, level: int = 0, **kw) -> AxiSetup:
    """The axisymmetric problem of ``cfg`` (default preset) at mesh ``level`` (counts x 1.5**level)."""
    cfg = cfg or preset("default")
    base = AxiSetup(tuple(la.thickness_m for la in cfg.layers), layer_moduli_pa(cfg), cfg.tool_radius_m)
    f = 1.5**level
    base = replace(
        base,
        n_tool=max(2, round(base.n_tool * f)),
        n_out=max(3, round(base.n_out * f)),
        nz=tuple(max(1, round(n * f)) for n in base.nz),
    )
    return replace(base, **kw)


@dataclass
class AxiResult:
    """Force-depth curve and surface profiles of one solve."""

    setup: AxiSetup
    depths_m: np.ndarray  # converged load steps (0 excluded)
    forces_n: np.ndarray  # punch reaction, positive pushing up on the tool
    surface_r_m: np.ndarray  # reference radius of the surface nodes (sorted)
    profile_depths_m: np.ndarray  # depths of the stored profiles (those reached of SAVE_DEPTHS_M)
    surface_ur_m: np.ndarray  # (n_profiles, n_surface) radial displacement
    surface_down_m: np.ndarray  # (n_profiles, n_surface) downward displacement
    edge_slip_m: np.ndarray  # radial displacement of the punch-edge node at each depth
    n_dofs: int
    newton_iterations: int
    solve_s: float

    def force_n(self, depth_m):
        """Force at ``depth_m`` (linear interpolation between load steps, 0 at 0)."""
        d = np.concatenate([[0.0], self.depths_m])
        f = np.concatenate([[0.0], self.forces_n])
        return np.interp(depth_m, d, f, right=np.nan)

    def field_down_at(self, depth_m: float, r_m) -> np.ndarray:
        """Downward surface displacement at current radius ``r_m`` (Eulerian) at a stored depth."""
        i = int(np.argmin(np.abs(self.profile_depths_m - depth_m)))
        if abs(self.profile_depths_m[i] - depth_m) > 1e-9:
            raise KeyError(f"no stored profile at {depth_m * 1e3:g} mm (stored: {self.profile_depths_m * 1e3} mm)")
        r_cur = self.surface_r_m + self.surface_ur_m[i]
        order = np.argsort(r_cur)
        return np.interp(r_m, r_cur[order], self.surface_down_m[i][order])


# --- kinematics and material -------------------------------------------------------------------------------------
# The five non-zero entries of an axisymmetric 3x3 gradient, in this order: (rr, rz, zr, zz, tt).
_IDX = ((0, 0), (0, 1), (1, 0), (1, 1), (2, 2))


def _lame(e, nu):
    return e * nu / ((1 + nu) * (1 - 2 * nu)), e / (2 * (1 + nu))


def gradient_components(grad, value, r):
    """The 5 displacement-gradient components ``H`` (shape (5, ...)) from a 2D vector field in (r, z)."""
    return np.stack([grad[0, 0], grad[0, 1], grad[1, 0], grad[1, 1], value[0] / r])


def neo_hookean(H, lam, mu):
    """First Piola stress ``P`` (5, ...) and tangent ``A = dP/dF`` (5, 5, ...) at gradient ``H``; also ``J``.

    ``P = mu (F - F^-T) + lam ln J F^-T``; ``A_iJkL = mu d_ik d_JL + (mu - lam ln J) Fi_Li Fi_Jk + lam Fi_Ji Fi_Lk``.
    """
    f11, f12, f21, f22, f33 = 1 + H[0], H[1], H[2], 1 + H[3], 1 + H[4]
    j2 = f11 * f22 - f12 * f21
    J = j2 * f33
    Fi = np.zeros((3, 3) + H.shape[1:])  # F^-1 (garbage where J <= 0: the caller rejects the state)
    with np.errstate(divide="ignore", invalid="ignore"):
        Fi[0, 0], Fi[0, 1], Fi[1, 0], Fi[1, 1] = f22 / j2, -f12 / j2, -f21 / j2, f11 / j2
        Fi[2, 2] = 1 / f33
    F = np.zeros_like(Fi)
    F[0, 0], F[0, 1], F[1, 0], F[1, 1], F[2, 2] = f11, f12, f21, f22, f33
    lnJ = np.log(np.where(J > 0, J, 1.0))
    with np.errstate(invalid="ignore", over="ignore"):
        P = np.stack([mu * (F[i, j] - Fi[j, i]) + lam * lnJ * Fi[j, i] for i, j in _IDX])
        A = np.empty((5, 5) + H.shape[1:])
        for a, (i, J_) in enumerate(_IDX):
            for b, (k, L) in enumerate(_IDX):
                A[a, b] = mu * float(i == k and J_ == L) + (mu - lam * lnJ) * Fi[L, i] * Fi[J_, k] + lam * Fi[J_, i] * Fi[L, k]
    return P, A, J


def linear_elastic(H, lam, mu):
    """Small-strain stress (5, ...) and constant tangent: the neo-Hookean tangent at ``F = I``."""
    _, A, _ = neo_hookean(np.zeros_like(H), lam, mu)
    return np.einsum("ab...,b...->a...", A, H), A, np.ones(H.shape[1:])


# --- assembly --------------------------------------------------------------------------------------------------------
class AxiProblem:
    """Mesh, basis, boundary DOFs and assembly of one :class:`AxiSetup`."""

    def __init__(self, s: AxiSetup):
        self.s = s
        r0 = s.tool_radius_m
        if s.extent_m <= r0 * (1 + 1e-12):  # the punch covers the whole top: a confined column (closed-form check)
            rs = np.linspace(0.0, s.extent_m, s.n_tool + 1)
        else:
            rs = axis_nodes(r0, s.n_tool, s.extent_m, s.n_out)
        he, hd, hf = s.thickness_m
        ne, nd, nf = s.nz
        t = np.linspace(0, 1, nf + 1)[1:]
        depth = np.concatenate([np.linspace(0, he, ne + 1), np.linspace(he, he + hd, nd + 1)[1:], he + hd + hf * t**1.5])
        self.H = he + hd + hf
        self.mesh = MeshQuad.init_tensor(rs, -depth[::-1])
        self.basis = Basis(self.mesh, ElementVector(ElementQuad2()), intorder=4)
        b = self.basis
        x = np.asarray(b.global_coordinates())  # (2, ne, nq)
        self.r_q = x[0]
        zc = -x[1]
        e = np.where(zc < he, s.moduli_pa[0], np.where(zc < he + hd, s.moduli_pa[1], s.moduli_pa[2]))
        self.lam, self.mu = _lame(e, s.poisson)
        self.wdx = 2 * np.pi * self.r_q * b.dx  # axisymmetric volume weights
        # B: (5, n_local, ne, nq), the gradient components of each local basis function
        self.B = np.stack([gradient_components(phi[0].grad, np.asarray(phi[0]), self.r_q) for phi in b.basis], axis=1)
        self.edofs = b.element_dofs  # (n_local, ne)
        nl = self.edofs.shape[0]
        self.rows = np.repeat(self.edofs[:, None, :], nl, axis=1).ravel()
        self.cols = np.repeat(self.edofs[None, :, :], nl, axis=0).ravel()
        tol = 1e-12
        top = b.get_dofs(lambda p: np.abs(p[1]) < tol)
        self.tool = b.get_dofs(lambda p: (np.abs(p[1]) < tol) & (p[0] <= r0 * (1 + 1e-9))).all("u^2")
        fixed = [
            b.get_dofs(lambda p: np.abs(p[1] + self.H) < tol).all(),
            b.get_dofs(lambda p: np.abs(p[0]) < tol).all("u^1"),
            b.get_dofs(lambda p: np.abs(p[0] - s.extent_m) < tol).all("u^1"),
        ]
        self.fixed = np.setdiff1d(np.unique(np.concatenate(fixed)), self.tool)
        self.known = np.concatenate([self.fixed, self.tool])
        self.free = np.setdiff1d(np.arange(b.N), self.known)
        top_r = top.all("u^1")
        top_z = top.all("u^2")
        ro = np.argsort(b.doflocs[0, top_r])
        zo = np.argsort(b.doflocs[0, top_z])
        self.surf_r_dofs, self.surf_z_dofs = top_r[ro], top_z[zo]
        self.surface_r = b.doflocs[0, self.surf_z_dofs]
        self.edge_r_dof = self.surf_r_dofs[int(np.argmin(np.abs(b.doflocs[0, self.surf_r_dofs] - r0)))]
        self.law = neo_hookean if s.law == "neo-hookean" else linear_elastic
        self.u = np.zeros(b.N)

    def gradient(self, u):
        """Displacement gradient at every quadrature point of every element, from the nodal ``u``."""
        ue = u[self.edofs]  # (n_local, ne)
        return np.einsum("aine,in->ane", self.B, ue)

    def assemble(self, u, tangent: bool = True):
        """Internal force vector, tangent matrix (CSR) and min J over the Gauss points."""
        P, A, J = self.law(self.gradient(u), self.lam, self.mu)
        Pw = P * self.wdx
        fe = np.einsum("aine,ane->in", self.B, Pw)
        f = np.bincount(self.edofs.ravel(), fe.ravel(), minlength=self.basis.N)
        if not tangent:
            return f, None, float(J.min())
        AB = np.einsum("abne,bjne->ajne", A * self.wdx, self.B)
        ke = np.einsum("aine,ajne->ijn", self.B, AB)
        K = sp.coo_matrix((ke.ravel(), (self.rows, self.cols)), shape=(self.basis.N,) * 2).tocsr()
        return f, K, float(J.min())


def solve(s: AxiSetup, progress: bool = True) -> AxiResult:
    """Newton with load steps to ``s.max_depth_m`` (no cache; see :func:`reference`)."""
    t0 = time.perf_counter()
    pb = AxiProblem(s)
    N = pb.basis.N
    saves = [d for d in SAVE_DEPTHS_M if d <= s.max_depth_m * (1 + 1e-12)]
    stops = np.unique(np.round(np.concatenate([np.linspace(0, s.max_depth_m, s.n_steps + 1)[1:], saves]), 12))
    depths, forces, slips, prof_d, prof_ur, prof_dn = [], [], [], [], [], []
    iters = 0
    bar = tqdm(total=len(stops), desc=f"{s.law} axisym {s.key()[:8]} ({N} dofs)", disable=not progress, leave=False)

    def record(d, f_int):
        u = pb.u
        depths.append(d)
        forces.append(float(f_int[pb.tool].sum()))
        slips.append(float(u[pb.edge_r_dof]))
        if any(abs(d - sd) < 1e-12 for sd in saves):
            prof_d.append(d)
            prof_ur.append(u[pb.surf_r_dofs].copy())
            prof_dn.append(-u[pb.surf_z_dofs].copy())

    if s.law == "linear":  # one solve at unit depth, scaled
        _, K, _ = pb.assemble(pb.u)
        u1 = np.zeros(N)
        u1[pb.tool] = -1.0
        u1[pb.free] = spla.spsolve(K[pb.free][:, pb.free].tocsc(), -K[pb.free][:, pb.known] @ u1[pb.known])
        f1 = K @ u1
        for d in stops:
            pb.u = u1 * d
            record(d, f1 * d)
            bar.update()
        bar.close()
        return _result(s, pb, depths, forces, prof_d, prof_ur, prof_dn, slips, 1, time.perf_counter() - t0)

    iters = march(
        pb,
        stops,
        lambda d, f: (record(d, f), bar.update(), bar.set_postfix(depth_mm=f"{d * 1e3:.2f}", force_n=f"{-forces[-1]:.3g}")),
        s.max_depth_m,
    )
    bar.close()
    return _result(s, pb, depths, forces, prof_d, prof_ur, prof_dn, slips, iters, time.perf_counter() - t0)


def march(pb, stops, on_stop, depth_range_m: float, solver=None, min_step_m: float | None = None) -> int:
    """Load steps through ``stops`` (depths, m) with step halving; ``on_stop(depth, internal_force)`` at each.

    ``pb`` has ``assemble(u, tangent)``, ``tool`` (punch z DOFs), ``free``, ``n_dofs`` and a mutable
    ``u``. Returns the total Newton iterations. Without ``min_step_m`` a step halved below 1e-5 of the
    range raises; with it, the march stops at the deepest converged stop once the step would fall below
    ``min_step_m`` (``pb.u`` stays the converged state; the caller reads how deep it got from ``on_stop``).
    """
    d_done, du_prev, iters = 0.0, None, 0
    for d_target in stops:
        while d_done < d_target - 1e-15:
            step = d_target - d_done
            while True:
                d_try = d_done + step
                u_try = pb.u.copy()
                if du_prev is not None:  # linear extrapolation of the last increment
                    u_try += du_prev[0] * (step / du_prev[1])
                else:  # first step: the tangent (linear) solution, so no element starts inverted
                    _, K, _ = pb.assemble(pb.u)
                    du = np.zeros_like(u_try)
                    du[pb.tool] = -d_try - pb.u[pb.tool]
                    du[pb.free] = (solver or _superlu)(K[pb.free][:, pb.free], -K[pb.free][:, pb.tool] @ du[pb.tool])
                    u_try += du
                u_try[pb.tool] = -d_try
                ok, n_it, u_try = _newton(pb, u_try, solver=solver)
                iters += n_it
                if ok:
                    break
                step *= 0.5
                if min_step_m is not None and step < min_step_m:
                    return iters  # deepest converged stop already reported
                if step < depth_range_m * 1e-5:
                    raise RuntimeError(f"Newton failed at depth {d_done * 1e3:.4f} mm (step < 1e-5 of the range)")
            du_prev = (u_try - pb.u, step)
            pb.u, d_done = u_try, d_try
        f_int, _, _ = pb.assemble(pb.u, tangent=False)
        on_stop(d_target, f_int)
    return iters


def _superlu(a, b):
    return spla.spsolve(a.tocsc(), b)


def _newton(pb, u, max_it: int = 15, rtol: float = 1e-9, solver=None):
    """Newton on the free DOFs; returns (converged, iterations, u). ``solver(A, b)``: sparse solve (SuperLU)."""
    solver = solver or _superlu
    fr = pb.free
    scale = None
    for it in range(1, max_it + 1):
        f, K, jmin = pb.assemble(u)
        if not np.isfinite(jmin) or jmin <= 0:
            return False, it, u
        r = f[fr]
        if scale is None:
            scale = max(np.abs(f[pb.tool]).sum(), 1e-30)
        if np.linalg.norm(r) <= rtol * scale:
            return True, it, u
        du = solver(K[fr][:, fr], -r)
        if not np.all(np.isfinite(du)):
            return False, it, u
        u = u.copy()
        u[fr] += du
    f, _, jmin = pb.assemble(u, tangent=False)
    return bool(jmin > 0 and np.linalg.norm(f[fr]) <= rtol * 1e3 * scale), max_it, u


def _result(s, pb, depths, forces, prof_d, prof_ur, prof_dn, slips, iters, wall):
    return AxiResult(
        s,
        np.array(depths),
        -np.array(forces),
        pb.surface_r,
        np.array(prof_d),
        np.array(prof_ur),
        np.array(prof_dn),
        np.array(slips),
        pb.basis.N,
        iters,
        wall,
    )


def reference(s: AxiSetup, cache_dir: Path | None = CACHE_DIR, progress: bool = True, fresh: bool = False) -> AxiResult:
    """:func:`solve` with an on-disk cache keyed by the hash of ``s`` (``fresh``: solve and overwrite)."""
    path = None if cache_dir is None else Path(cache_dir) / f"{s.key()}.npz"
    return cached(
        path,
        fresh,
        lambda: solve(s, progress),
        lambda z: AxiResult(
            s,
            z["depths"],
            z["forces"],
            z["surface_r"],
            z["profile_depths"],
            z["surface_ur"],
            z["surface_down"],
            z["edge_slip"],
            int(z["n_dofs"]),
            int(z["iters"]),
            float(z["solve_s"]),
        ),
        lambda res: dict(
            depths=res.depths_m,
            forces=res.forces_n,
            surface_r=res.surface_r_m,
            profile_depths=res.profile_depths_m,
            surface_ur=res.surface_ur_m.astype(np.float32),
            surface_down=res.surface_down_m.astype(np.float32),
            edge_slip=res.edge_slip_m,
            n_dofs=res.n_dofs,
            iters=res.newton_iterations,
            solve_s=res.solve_s,
            setup=json.dumps(asdict(s)),
        ),
    )
