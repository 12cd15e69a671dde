"""Large-deformation reference in 3D: the egg-carton layered block of :mod:`.fem`, compressible neo-Hookean.

Same mesh, elements (20-node serendipity hexes, 3x3x3 Gauss points), material-by-quadrature-point
egg-carton layering, symmetry and boundary conditions as the linear 3D FEM (:mod:`.fem`); the
material law, Newton solver and load stepping of the axisymmetric reference
(:mod:`.hyperelastic`, Bonet & Wood eq 6.27). Moduli and geometry come from the config
(:func:`.hyperelastic.layer_moduli_pa`). The reaction is the sum of the internal z-forces on the
punch DOFs times the symmetry factor; the surface field at the deepest point is the downward
displacement at the current (deformed) positions of a fine grid of surface points, interpolated
onto the linear FEM's sample grid so both are scored the same way.

Cost: a Newton iteration at mesh level -2 (about 9k DOFs) is ~2 s here (assembly + PARDISO),
~40-60 iterations to 3 mm, so a few minutes per scenario; results are cached in
``docs/validation/hyper_cache/3d-<hash>.npz``.
"""

from __future__ import annotations

import hashlib
import json
import time
from dataclasses import asdict, dataclass, replace
from pathlib import Path

import numpy as np
import scipy.sparse as sp
from scipy.interpolate import griddata
from skfem import Basis, ElementHexS2, ElementVector
from tqdm import tqdm

from skin_sim_node.model import TissueConfig, preset

from .cache import cached
from .fem import FemSetup, _geometry_key, _modulus_field, build_mesh, build_offset_mesh, mesh_levels, sparse_solve
from .hyperelastic import CACHE_DIR, HYPER_VERSION, _lame, layer_moduli_pa, march

N_STEPS_3D = 10  # load steps to the scenario's depth (the predictor and step halving do the rest)
MIN_STEP_FRACTION = 1 / 32
"""Smallest load increment, as a fraction of one load step (9.4 um of 0.3 mm), before the 3D march stops at the
deepest converged stop: at this mesh level the elements at the punch rim invert near 3 mm (Newton's J <= 0), and
halving further only spends Newton iterations (stated choice; the result records how deep it got)."""


def neo_hookean_3d(G, lam, mu):
    """``P`` (3, 3, ...), ``A = dP/dF`` (3, 3, 3, 3, ...) and ``J`` at displacement gradient ``G`` (3, 3, ...)."""
    F = np.moveaxis(G, (0, 1), (-2, -1)) + np.eye(3)
    J = np.linalg.det(F)
    ok = J > 0
    Fi = np.linalg.inv(np.where(ok[..., None, None], F, np.eye(3)))
    FiT = np.swapaxes(Fi, -1, -2)
    lnJ = np.log(np.where(ok, J, 1.0))
    P = mu[..., None, None] * (F - FiT) + (lam * lnJ)[..., None, None] * FiT
    eye = np.eye(3)
    A = (
        mu[..., None, None, None, None] * np.einsum("ik,JL->iJkL", eye, eye)
        + (mu - lam * lnJ)[..., None, None, None, None] * np.einsum("...Li,...Jk->...iJkL", Fi, Fi)
        + lam[..., None, None, None, None] * np.einsum("...Ji,...Lk->...iJkL", Fi, Fi)
    )
    return np.moveaxis(P, (-2, -1), (0, 1)), np.moveaxis(A, (-4, -3, -2, -1), (0, 1, 2, 3)), np.where(ok, J, -1.0)


@dataclass(frozen=True)
class PunchLayout:
    """A punch off the block's centre, with or without a mirrored partner (issue 32, :mod:`.two_punch`).

    The punch is centred at ``(centre_x_m, 0)`` in the frame of the mesh (the tissue frame shifted by the FEM setup's
    ``contact_xy_m``). With ``partner`` a second, equal punch at ``(-centre_x_m, 0)`` presses to the same depth, and
    the problem is the quarter ``x, y >= 0`` (symmetry planes ``x = 0`` and ``y = 0``); without it, the half ``y >= 0``
    on the mirrored mesh (:func:`.fem.build_offset_mesh`), so the single punch and the pair share one mesh (except
    where the pair's disks overlap: the single then has a mesh conforming to its own disk). The force
    is one punch's: twice the quarter's reaction (the pair's total is four quarters, two per punch), or twice the
    half's.
    """

    centre_x_m: float
    partner: bool


@dataclass(frozen=True)
class Setup3D:
    """The 3D neo-Hookean run: the FEM mesh and geometry, the deepest indentation and the number of load steps;
    ``layout`` places the punch off the block's centre (None: centred on the mesh, the setups of the scenarios)."""

    fem: FemSetup
    max_depth_m: float
    n_steps: int = N_STEPS_3D
    layout: PunchLayout | None = None

    def key(self) -> str:
        """Cache key: a hash of the setup and :data:`HYPER_VERSION` (a centred setup keeps its key from before
        ``layout`` existed)."""
        d = asdict(self)
        if d["layout"] is None:
            del d["layout"]
        elif not self.layout.partner and self.layout.centre_x_m < self.fem.tissue[2]:
            d["mesh"] = "single-overlap"  # its own conforming mesh (fem._single_overlap_mesh), not the pair's mirror
        blob = json.dumps({"v": HYPER_VERSION, "3d": 1, **d}, sort_keys=True, default=str)
        return hashlib.sha256(blob.encode()).hexdigest()[:16]


def setup_for(sc, cfg: TissueConfig | None = None, level: int = -2) -> Setup3D:
    """The 3D neo-Hookean problem of scenario ``sc`` for ``cfg`` (default preset) at linear-FEM mesh ``level``."""
    cfg = cfg or preset("default")
    base = replace(mesh_levels(level, FemSetup()), moduli_pa=layer_moduli_pa(cfg), tissue=_geometry_key(cfg))
    return Setup3D(sc.fem_setup(base), sc.max_depth_m)


class Problem3D:
    """Mesh, basis, BCs and assembly (9 gradient components per Gauss point); ``layout``: :class:`PunchLayout`."""

    def __init__(self, s: FemSetup, layout: PunchLayout | None = None):
        self.s = s
        self.layout = layout
        if layout is None:
            self.mesh = build_mesh(s)
        else:
            self.mesh = build_offset_mesh(s, layout.centre_x_m, mirror=not layout.partner)
        b = self.basis = Basis(self.mesh, ElementVector(ElementHexS2()), intorder=3)
        xc, yc = s.contact_xy_m
        x = np.asarray(b.global_coordinates())
        e = _modulus_field(s, x[0] + xc, x[1] + yc, x[2])
        self.lam, self.mu = _lame(e, s.poisson)
        self.wdx = np.asarray(b.dx)
        nl = len(b.basis)
        ne, nq = self.wdx.shape
        self.B = np.empty((ne, nq, 9, nl))  # (element, point, component, local dof)
        for i, phi in enumerate(b.basis):
            self.B[:, :, :, i] = np.moveaxis(np.asarray(phi[0].grad).reshape(9, ne, nq), 0, -1)
        self.edofs = b.element_dofs
        self.rows = np.repeat(self.edofs[:, None, :], nl, axis=1).ravel()
        self.cols = np.repeat(self.edofs[None, :, :], nl, axis=0).ravel()
        r0 = s.tissue[2]
        bottom = self.mesh.p[2].min()
        far = s.half_width_m * (1 - 1e-9)
        tol = 1e-12
        fixed = [b.get_dofs(lambda p: np.abs(p[2] - bottom) < tol).all(), b.get_dofs(lambda p: np.abs(p[1]) < tol).all("u^2")]
        centres = [(0.0, 0.0)]
        if layout is not None:
            a = layout.centre_x_m
            centres = [(a, 0.0), (-a, 0.0)] if layout.partner else [(a, 0.0)]
            if layout.partner:
                fixed.append(b.get_dofs(lambda p: np.abs(p[0]) < tol).all("u^1"))
            fixed.append(b.get_dofs(lambda p: np.abs(p[0]) > far).all("u^1"))
        elif s.edge_distance_m is None:
            fixed.append(b.get_dofs(lambda p: np.abs(p[0]) < tol).all("u^1"))
            fixed.append(b.get_dofs(lambda p: np.abs(p[0]) > far).all("u^1"))
        else:
            fixed.append(b.get_dofs(lambda p: p[0] < -far).all("u^1"))
        fixed.append(b.get_dofs(lambda p: p[1] > far).all("u^2"))

        def on_tool(p):
            inside = np.zeros(p.shape[1:], dtype=bool)
            for cx, cy in centres:
                inside |= np.hypot(p[0] - cx, p[1] - cy) <= r0 * (1 + 1e-9)
            return (np.abs(p[2]) < tol) & inside

        self.tool = b.get_dofs(on_tool).all("u^3")
        self.fixed = np.setdiff1d(np.unique(np.concatenate(fixed)), self.tool)
        self.free = np.setdiff1d(np.arange(b.N), np.concatenate([self.fixed, self.tool]))
        self.u = np.zeros(b.N)
        self.sym = 2.0 if layout is not None or s.edge_distance_m is not None else 4.0

    def assemble(self, u, tangent: bool = True):
        """Internal force vector, tangent stiffness (None unless ``tangent``) and the smallest ``J`` at ``u``."""
        ue = u[self.edofs].T  # (ne, nl)
        G = np.einsum("nqai,ni->anq", self.B, ue).reshape(3, 3, *self.wdx.shape)
        P, A, J = neo_hookean_3d(G, self.lam, self.mu)
        Pw = (P.reshape(9, *self.wdx.shape) * self.wdx).transpose(1, 2, 0)  # (ne, nq, 9)
        fe = np.einsum("nqa,nqai->in", Pw, self.B)
        f = np.bincount(self.edofs.ravel(), fe.ravel(), minlength=self.basis.N)
        if not tangent:
            return f, None, float(J.min())
        ne, nq = self.wdx.shape
        Aw = (A.reshape(9, 9, ne, nq) * self.wdx).transpose(2, 3, 0, 1)  # (ne, nq, 9, 9)
        AB = np.matmul(Aw, self.B)  # (ne, nq, 9, nl)
        nl = self.B.shape[-1]
        ke = np.matmul(self.B.reshape(ne, nq * 9, nl).transpose(0, 2, 1), AB.reshape(ne, nq * 9, nl))  # (ne, nl, nl)
        K = sp.coo_matrix((ke.transpose(1, 2, 0).ravel(), (self.rows, self.cols)), shape=(self.basis.N,) * 2).tocsr()
        return f, K, float(J.min())


@dataclass
class Result3D:
    """3D neo-Hookean reference: force against depth and the surface field at the deepest step."""

    setup: Setup3D
    depths_m: np.ndarray
    forces_n: np.ndarray
    sample_x_m: np.ndarray  # global
    sample_y_m: np.ndarray
    field_down_m: np.ndarray  # (ny, nx) at max depth, Eulerian
    n_dofs: int
    newton_iterations: int
    solve_s: float

    def force_n(self, depth_m):
        """Force at ``depth_m`` (N), interpolated between the load steps (0 at 0)."""
        return np.interp(depth_m, np.concatenate([[0.0], self.depths_m]), np.concatenate([[0.0], self.forces_n]))


def solve(s3: Setup3D, progress: bool = True, sample_step_m: float = 0.5e-3) -> Result3D:
    """Solve the 3D neo-Hookean indentation in load steps (Newton per step); surface sampled every ``sample_step_m``."""
    t0 = time.perf_counter()
    s = s3.fem
    pb = Problem3D(s, s3.layout)
    stops = np.linspace(0, s3.max_depth_m, s3.n_steps + 1)[1:]
    depths, forces = [], []
    bar = tqdm(total=len(stops), desc=f"neo-Hookean 3D {s3.key()[:8]} ({pb.basis.N} dofs)", disable=not progress, leave=False)

    def on_stop(d, f_int):
        depths.append(d)
        forces.append(-float(f_int[pb.tool].sum()) * pb.sym)
        bar.update()
        bar.set_postfix(depth_mm=f"{d * 1e3:.2f}", force_n=f"{forces[-1]:.3g}")

    iters = march(
        pb, stops, on_stop, s3.max_depth_m, solver=sparse_solve, min_step_m=MIN_STEP_FRACTION * s3.max_depth_m / s3.n_steps
    )
    if depths and depths[-1] < s3.max_depth_m - 1e-12:
        tqdm.write(f"neo-Hookean 3D {s3.key()[:8]}: stopped at {depths[-1] * 1e3:.2f} mm (deepest converged load step)")
    bar.close()
    # surface field at the deepest point, at deformed positions, onto the linear FEM's sample grid (local coords)
    quarter = s.edge_distance_m is None and (s3.layout is None or s3.layout.partner)
    xmax = s.edge_distance_m or s.half_width_m
    xlo = 0.0 if quarter else -s.half_width_m
    sx = np.clip(np.arange(xlo, xmax + 1e-12, sample_step_m), -s.half_width_m * (1 - 1e-9), xmax * (1 - 1e-9))
    sy = np.clip(np.arange(0.0, s.half_width_m + 1e-12, sample_step_m), 0.0, s.half_width_m * (1 - 1e-9))
    top = pb.basis.get_dofs(lambda p: np.abs(p[2]) < 1e-12)  # surface nodes: the serendipity DOFs are nodal values
    dx_, dy_, dz_ = (top.all(c) for c in ("u^1", "u^2", "u^3"))
    X0, Y0 = pb.basis.doflocs[0, dz_], pb.basis.doflocs[1, dz_]
    ux, uy, uz = pb.u[dx_], pb.u[dy_], pb.u[dz_]
    cur = np.stack([X0 + ux, Y0 + uy], 1)
    if quarter:  # mirror across the symmetry planes so the interpolation sees both sides
        cur = np.concatenate([cur, cur * [-1, 1], cur * [1, -1], cur * [-1, -1]])
        down = np.tile(-uz, 4)
    else:
        cur = np.concatenate([cur, cur * [1, -1]])
        down = np.tile(-uz, 2)
    SX, SY = np.meshgrid(sx, sy)
    field = griddata(cur, down, (SX, SY), method="linear", fill_value=0.0)
    xc, yc = s.contact_xy_m
    return Result3D(s3, np.array(depths), np.array(forces), sx + xc, sy + yc, field, pb.basis.N, iters, time.perf_counter() - t0)


def reference(s3: Setup3D, cache_dir: Path | None = CACHE_DIR, progress: bool = True, fresh: bool = False) -> Result3D:
    """:func:`solve` with the on-disk cache (``3d-<hash>.npz``)."""
    path = None if cache_dir is None else Path(cache_dir) / f"3d-{s3.key()}.npz"
    return cached(
        path,
        fresh,
        lambda: solve(s3, progress),
        lambda z: Result3D(
            s3, z["depths"], z["forces"], z["sx"], z["sy"], z["field"], int(z["n_dofs"]), int(z["iters"]), float(z["solve_s"])
        ),
        lambda res: dict(
            depths=res.depths_m,
            forces=res.forces_n,
            sx=res.sample_x_m,
            sy=res.sample_y_m,
            field=res.field_down_m.astype(np.float32),
            n_dofs=res.n_dofs,
            iters=res.newton_iterations,
            solve_s=res.solve_s,
            setup=json.dumps(asdict(s3), default=str),
        ),
    )
