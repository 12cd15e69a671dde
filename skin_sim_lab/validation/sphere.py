"""Large-deformation reference for a round tip: a rigid frictionless sphere on the layered neo-Hookean stack.

Issue 20, item 2. The axisymmetric problem of :mod:`.hyperelastic` (same layers, moduli, elements, material,
boundary conditions and Newton solver) with the flat punch's displacement constraint replaced by unilateral
contact with a rigid sphere of radius ``R`` (the config's ``tool.radius_m``) whose lowest point is at depth ``d``;
above its equator the tool continues as a cylinder of radius ``R`` (the probe's shaft), so depths past ``R``
are defined.

Contact: node-to-rigid-surface **penalty**, evaluated at the deformed position of every surface node. For a node
at ``x = (r, z)`` (current) and the sphere centre ``c = (0, R - d)``, the penetration is ``p = R - |x - c|`` below
the centre and ``p = R - r`` above it (the shaft), with the outward normal ``n``; the contact energy is
``k_i p^2 / 2`` for ``p > 0`` (its kink rounded, :data:`SMOOTHING`), so the nodal contact force ``k_i p n``
always pushes the surface away from the
tool (compressive; no adhesion) and every node that penetrates is in the contact set. Newton uses the exact
tangent ``k n n^T - k p / rho (I - n n^T)`` (the sphere's curvature term; none on the shaft), so the active set is
updated at every iteration (semi-smooth Newton). The penalty ``k_i = PENALTY x`` the node's own diagonal stiffness
at rest, so the penetration is about 1/PENALTY of the node's displacement; the solve reports the largest
penetration over all surface nodes and the check asks it to be a small fraction of the depth
(:func:`contact_checks`).

Mesh: the flat punch's radial mesh with ``R`` as the fine-zone radius (uniform elements of ``R / n_tool`` out to
``R + 3 h``, then geometric to ``extent_m``), with ``n_tool`` large enough that the Hertz contact radius
``sqrt(R d)`` at 0.05 mm spans several elements. Load stops are geometric at small depth (the force there goes as
``d^1.5``). Results are cached in ``docs/validation/hyper_cache/sphere-<hash>.npz`` like the punch's.
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
from tqdm import tqdm

from skin_sim_node.model.calibration import POISSON_RATIO
from skin_sim_node.model.config import TissueConfig, preset

from .cache import cached
from .hyperelastic import CACHE_DIR, HYPER_VERSION, AxiProblem, AxiSetup, layer_moduli_pa

SPHERE_VERSION = 3  # bump when the contact treatment changes: part of the cache key
PENALTY = 1e2
"""Contact penalty over each surface node's own rest stiffness: the penetration is about 1e-2 of the nodal
displacement (checked after each solve, :func:`contact_checks`)."""
SMOOTHING = 1e-3
"""The penalty's kink is rounded over ``|p| < delta = SMOOTHING x depth`` (force ``k (p + delta)^2 / 4 delta`` there,
``k p`` beyond, zero for ``p <= -delta``), so Newton's residual is C1 and the active set does not cycle; the contact
surface is thereby uncertain by ``delta``, 0.1 % of the depth (force error ~0.15 %)."""
CHECK_DEPTHS_M = (0.05e-3, 0.1e-3, 0.2e-3, 0.5e-3, 1e-3, 2e-3, 3e-3)
"""Depths of the issue-20 table (and load stops of every solve)."""


def default_stops(max_depth_m: float = 3e-3) -> tuple[float, ...]:
    """Load stops: geometric from 10 um to 0.5 mm (``F ~ d^1.5`` there), then every 0.1 mm, plus :data:`CHECK_DEPTHS_M`."""
    d = np.concatenate([np.geomspace(1e-5, 5e-4, 15), np.arange(6e-4, max_depth_m + 1e-9, 1e-4), CHECK_DEPTHS_M])
    return tuple(float(x) for x in np.unique(np.round(d[d <= max_depth_m * (1 + 1e-12)], 9)))


@dataclass(frozen=True)
class SphereSetup:
    """One axisymmetric sphere solve: the punch problem ``axi`` (its ``tool_radius_m`` is the sphere's radius,
    its ``n_tool`` the elements across it) and the load stops."""

    axi: AxiSetup
    stops_m: tuple[float, ...]
    penalty: float = PENALTY

    def key(self) -> str:
        """Cache key: a hash of the setup, :data:`~.hyperelastic.HYPER_VERSION` and :data:`SPHERE_VERSION`."""
        blob = json.dumps({"v": HYPER_VERSION, "sphere": SPHERE_VERSION, **asdict(self)}, sort_keys=True)
        return hashlib.sha256(blob.encode()).hexdigest()[:16]


SPHERE_LEVEL_BASE = dict(n_tool=24, n_out=12, nz=(3, 10, 10))
"""Mesh of level 0: 24 uniform elements across the tool radius (0.10 mm at R = 2.5 mm; the Hertz contact radius at
0.05 mm, 0.35 mm, spans 3.4 of them, 7 nodes), the punch's graded outer mesh and layer counts (epidermis finer)."""
SPHERE_REFERENCE_LEVEL = 1
"""The sphere reference's mesh level (the convergence study, :func:`convergence`, docs/validation.md)."""


def sphere_setup(cfg: TissueConfig | None = None, level: int = SPHERE_REFERENCE_LEVEL, **kw) -> SphereSetup:
    """The sphere problem of ``cfg`` (default preset; its tool radius and layers) at mesh ``level`` (x 1.5**level)."""
    cfg = cfg or preset("default")
    f = 1.5**level
    b = SPHERE_LEVEL_BASE
    axi = AxiSetup(
        tuple(la.thickness_m for la in cfg.layers),
        layer_moduli_pa(cfg),
        cfg.tool_radius_m,
        n_tool=max(4, round(b["n_tool"] * f)),
        n_out=max(3, round(b["n_out"] * f)),
        nz=tuple(max(1, round(n * f)) for n in b["nz"]),
    )
    stops = kw.pop("stops_m", default_stops(axi.max_depth_m))
    return SphereSetup(replace(axi, **kw), stops)


def homogeneous_setup(level: int = 0, modulus_pa: float = 20e3, law: str = "linear") -> SphereSetup:
    """The Hertz check: one material (all three layers ``modulus_pa``) 40 mm deep and 80 mm wide, sphere of the
    default radius, to 0.5 mm (``a / H < 0.03``: a half-space within Dimitriadis' ``1 + 1.133 a/H`` ~ 3 %)."""
    cfg = preset("default")
    s = sphere_setup(cfg, level, extent_m=0.08, thickness_m=(0.5e-3, 2.0e-3, 37.5e-3), moduli_pa=(modulus_pa,) * 3, law=law)
    n = s.axi.nz
    axi = replace(s.axi, nz=(n[0], n[1], 2 * n[2]), n_out=2 * s.axi.n_out, max_depth_m=0.5e-3)
    return SphereSetup(axi, tuple(d for d in s.stops_m if d <= 0.5e-3 * (1 + 1e-12)))


@dataclass
class SphereResult:
    """Force-depth curve, contact radius and contact checks of one sphere solve."""

    setup: SphereSetup
    depths_m: np.ndarray
    forces_n: np.ndarray  # upward on the tool
    contact_radius_m: np.ndarray  # largest current radius of a node in contact (penetration > -SMOOTHING x depth)
    max_penetration_m: np.ndarray  # over every surface node
    free_surface_force_n: np.ndarray  # largest |internal z-force| on a surface node out of contact (should be ~0)
    n_dofs: int
    newton_iterations: int
    solve_s: float

    def force_n(self, depth_m):
        """Force at ``depth_m``: exact at load stops; between stops, interpolated in ``(log d, log F)``."""
        d = np.asarray(depth_m, dtype=float)
        return np.exp(np.interp(np.log(d), np.log(self.depths_m), np.log(self.forces_n), right=np.nan))

    def stiffness_n_per_m(self, depth_m):
        """``dF/dd`` at ``depth_m``: the slope of the local quadratic through the three nearest load stops."""
        out = []
        for d in np.atleast_1d(depth_m):
            i = int(np.clip(np.searchsorted(self.depths_m, d), 1, len(self.depths_m) - 2))
            x, y = self.depths_m[i - 1 : i + 2], self.forces_n[i - 1 : i + 2]
            c = np.polyfit(x - d, y, 2)
            out.append(c[1])
        return np.array(out) if np.ndim(depth_m) else float(out[0])


class SphereProblem(AxiProblem):
    """:class:`~.hyperelastic.AxiProblem` with every surface DOF free and the sphere's penalty contact added."""

    def __init__(self, s: SphereSetup):
        super().__init__(s.axi)
        self.R = s.axi.tool_radius_m
        self.tool = np.array([], dtype=int)
        self.known = self.fixed
        self.free = np.setdiff1d(np.arange(self.basis.N), self.known)
        self.r0 = self.basis.doflocs[0, self.surf_z_dofs]
        assert np.allclose(self.r0, self.basis.doflocs[0, self.surf_r_dofs])
        _, K, _ = super().assemble(self.u)
        diag = K.diagonal()
        self.k = s.penalty * np.maximum(diag[self.surf_z_dofs], diag[self.surf_r_dofs])
        self.depth = 0.0

    def contact(self, u):
        """Penetration ``p``, outward normal ``(n_r, n_z)`` and ``rho = |x - c|`` (inf on the shaft) per surface node."""
        r = self.r0 + u[self.surf_r_dofs]
        z = u[self.surf_z_dofs]
        cz = self.R - self.depth
        dz = z - cz
        rho = np.hypot(r, dz)
        below = dz <= 0.0
        with np.errstate(invalid="ignore", divide="ignore"):
            nr = np.where(below, r / rho, 1.0)
            nz = np.where(below, dz / rho, 0.0)
        p = np.where(below, self.R - rho, self.R - r)
        return p, nr, nz, np.where(below, rho, np.inf)

    def contact_force(self, p):
        """Nodal contact force magnitude and its slope in ``p``: ``k p`` past ``delta``, ``k (p + delta)^2 / 4 delta``
        within ``|p| < delta`` (C1, zero at ``p = -delta``: compact support, no force on a node off the sphere)."""
        delta = SMOOTHING * max(self.depth, 1e-9)
        q = np.clip(p + delta, 0.0, None)
        band = p < delta
        force = np.where(band, q * q / (4 * delta), p) * self.k
        slope = np.where(band, q / (2 * delta), 1.0) * self.k
        return force, slope

    def assemble(self, u, tangent: bool = True):
        """Internal minus contact force (the residual), its tangent and min J."""
        f, K, jmin = super().assemble(u, tangent)
        p, nr, nz, rho = self.contact(u)
        kp, dkp = self.contact_force(p)
        act = kp > 1e-30 * self.k
        f = f.copy()
        np.add.at(f, self.surf_r_dofs, -kp * nr)
        np.add.at(f, self.surf_z_dofs, -kp * nz)
        if tangent:
            ia = np.flatnonzero(act)
            k = dkp[ia]
            curv = kp[ia] / rho[ia]  # 0 on the shaft (rho = inf)
            n = (nr[ia], nz[ia])
            dofs = (self.surf_r_dofs[ia], self.surf_z_dofs[ia])
            rows, cols, vals = [], [], []
            for a in range(2):
                for b in range(2):
                    rows.append(dofs[a])
                    cols.append(dofs[b])
                    vals.append(k * n[a] * n[b] - curv * (float(a == b) - n[a] * n[b]))
            K = K + sp.coo_matrix((np.concatenate(vals), (np.concatenate(rows), np.concatenate(cols))), shape=K.shape).tocsr()
        return f, K, jmin

    def reaction(self, u) -> tuple[float, float, float, float]:
        """Tool force (N, up), contact radius (m), largest penetration (m), largest free-surface z-force (N)."""
        p, nr, nz, _ = self.contact(u)
        act = p > -SMOOTHING * self.depth  # in contact: carries force (within the rounded kink or deeper)
        force = float(np.sum(-self.contact_force(p)[0] * nz))
        r = self.r0 + u[self.surf_r_dofs]
        a = float(r[act].max()) if act.any() else 0.0
        f_int, _, _ = AxiProblem.assemble(self, u, tangent=False)
        out = ~act & (r > a + 1e-12)
        free_f = float(np.abs(f_int[self.surf_z_dofs[out]]).max()) if out.any() else 0.0
        return force, a, float(max(p.max(), 0.0)), free_f


def _newton(pb: SphereProblem, u, max_it: int = 25, rtol: float = 1e-8):
    fr = pb.free
    for it in range(1, max_it + 1):
        f, K, jmin = pb.assemble(u)
        if not np.isfinite(jmin) or jmin <= 0:
            return False, it, u
        scale = max(pb.reaction_estimate(u), 1e-12)
        r = f[fr]
        if np.linalg.norm(r) <= rtol * scale and it > 1:
            return True, it, u
        du = spla.spsolve(K[fr][:, fr].tocsc(), -r)
        if not np.all(np.isfinite(du)):
            return False, it, u
        # backtracking on the residual norm: a node entering or leaving the contact set can make the full step
        # overshoot (the penalty's kink); halve it until the residual falls (at most 6 times)
        rn = np.linalg.norm(r)
        for _ in range(6):
            u_new = u.copy()
            u_new[fr] += du
            f_new, _, j_new = pb.assemble(u_new, tangent=False)
            if np.isfinite(j_new) and j_new > 0 and np.linalg.norm(f_new[fr]) < rn:
                break
            du = 0.5 * du
        u = u_new
        if np.abs(du).max() <= 1e-10 * pb.depth and np.linalg.norm(r) <= 1e-6 * scale:
            return True, it, u  # at round-off: the penalty's stiff rows floor the residual near 1e-13 of k p
    return False, max_it, u


def _reaction_estimate(self, u) -> float:
    p, _, nz, _ = self.contact(u)
    return float(np.sum(-self.contact_force(p)[0] * nz))


SphereProblem.reaction_estimate = _reaction_estimate  # type: ignore[attr-defined]


def solve(s: SphereSetup, progress: bool = True) -> SphereResult:
    """Load steps through ``s.stops_m`` with step halving (no cache; see :func:`reference`)."""
    t0 = time.perf_counter()
    pb = SphereProblem(s)
    rows = []
    iters = 0
    d_done, du_prev = 0.0, None
    bar = tqdm(total=len(s.stops_m), desc=f"sphere {s.key()[:8]} ({pb.basis.N} dofs)", disable=not progress, leave=False)
    for d_target in s.stops_m:
        while d_done < d_target - 1e-15:
            step = d_target - d_done
            while True:
                pb.depth = d_done + step
                u_try = pb.u.copy()
                if du_prev is not None:
                    u_try += du_prev[0] * (step / du_prev[1])
                ok, n_it, u_try = _newton(pb, u_try)
                iters += n_it
                if ok:
                    break
                step *= 0.5
                if step < 1e-9:
                    raise RuntimeError(f"sphere: Newton failed at depth {d_done * 1e3:.4f} mm")
            du_prev = (u_try - pb.u, step)
            pb.u, d_done = u_try, d_done + step
        rows.append((d_target, *pb.reaction(pb.u)))
        bar.update()
        bar.set_postfix(depth_mm=f"{d_target * 1e3:.3f}", force_n=f"{rows[-1][1]:.4g}")
    bar.close()
    a = np.array(rows)
    return SphereResult(s, a[:, 0], a[:, 1], a[:, 2], a[:, 3], a[:, 4], pb.basis.N, iters, time.perf_counter() - t0)


def reference(s: SphereSetup, cache_dir: Path | None = CACHE_DIR, progress: bool = True, fresh: bool = False) -> SphereResult:
    """:func:`solve` with an on-disk cache (``sphere-<key>.npz``; ``fresh``: solve and overwrite)."""
    path = None if cache_dir is None else Path(cache_dir) / f"sphere-{s.key()}.npz"
    return cached(
        path,
        fresh,
        lambda: solve(s, progress),
        lambda z: SphereResult(
            s,
            z["depths"],
            z["forces"],
            z["contact_radius"],
            z["max_penetration"],
            z["free_surface_force"],
            int(z["n_dofs"]),
            int(z["iters"]),
            float(z["solve_s"]),
        ),
        lambda res: dict(
            depths=res.depths_m,
            forces=res.forces_n,
            contact_radius=res.contact_radius_m,
            max_penetration=res.max_penetration_m,
            free_surface_force=res.free_surface_force_n,
            n_dofs=res.n_dofs,
            iters=res.newton_iterations,
            solve_s=res.solve_s,
            setup=json.dumps(asdict(s)),
        ),
    )


def hertz_force_n(depth_m, radius_m: float, modulus_pa: float, poisson: float = POISSON_RATIO):
    """Hertz: ``F = 4/3 E* sqrt(R) d^1.5``, ``E* = E / (1 - nu^2)`` (rigid sphere on an elastic half-space)."""
    return 4.0 / 3.0 * modulus_pa / (1.0 - poisson**2) * np.sqrt(radius_m) * np.asarray(depth_m) ** 1.5


def contact_checks(res: SphereResult) -> dict[str, float]:
    """The contact's own checks: largest penetration over the depth (any surface node), largest force on a free
    surface node over the tool force (no traction outside the contact), smallest force (compressive: > 0)."""
    return {
        "max_penetration_over_depth": float(np.max(res.max_penetration_m / res.depths_m)),
        "free_surface_force_over_force": float(np.max(res.free_surface_force_n / res.forces_n)),
        "min_force_n": float(res.forces_n.min()),
    }


STUDY_LEVELS = (0, 1)
"""Mesh levels of the sphere's convergence study (level 2, ~17k DOFs, did not fit the time on the shared machine)."""


def study(fresh: bool = False, progress: bool = True) -> str:
    """The sphere reference's checks, as markdown: mesh convergence over :data:`STUDY_LEVELS` (force at the check
    depths), the contact checks of each solve, and Hertz on a homogeneous block (linear law, level 0)."""
    out = ["| level | DOFs | " + " | ".join(f"F {d * 1e3:g} mm (N)" for d in CHECK_DEPTHS_M) + " | a / sqrt(R d) at 0.05, 1 mm |"]
    out.append("|---" * (len(CHECK_DEPTHS_M) + 3) + "|")
    checks = []
    for lvl in STUDY_LEVELS:
        r = reference(sphere_setup(None, lvl), progress=progress, fresh=fresh)
        rad = [
            r.contact_radius_m[np.argmin(np.abs(r.depths_m - d))] / np.sqrt(r.setup.axi.tool_radius_m * d)
            for d in (0.05e-3, 1e-3)
        ]
        out.append(
            f"| {lvl} | {r.n_dofs} | "
            + " | ".join(f"{float(r.force_n(d)):.5g}" for d in CHECK_DEPTHS_M)
            + f" | {rad[0]:.2f}, {rad[1]:.2f} |"
        )
        checks.append((lvl, contact_checks(r), r.newton_iterations, r.solve_s))
    out.append("")
    for lvl, c, it, s in checks:
        out.append(
            f"- level {lvl}: largest penetration {c['max_penetration_over_depth']:.1e} of the depth, largest force on a free "
            f"surface node {c['free_surface_force_over_force']:.1e} of the tool force, smallest force {c['min_force_n']:.3g} N "
            f"(compressive); {it} Newton iterations, {s:.0f} s"
        )
    h = reference(homogeneous_setup(), progress=progress, fresh=fresh)
    ax = h.setup.axi
    dd = np.array([0.05e-3, 0.1e-3, 0.2e-3, 0.5e-3])
    ratio = h.force_n(dd) / hertz_force_n(dd, ax.tool_radius_m, ax.moduli_pa[0], ax.poisson)
    out.append(
        f"- Hertz check (one material E = {ax.moduli_pa[0] / 1e3:g} kPa, {sum(ax.thickness_m) * 1e3:g} mm deep, linear law, "
        "level 0): F / F_Hertz at " + ", ".join(f"{d * 1e3:g} mm: {x:.3f}" for d, x in zip(dd, ratio))
    )
    return "\n".join(out)


def main(argv=None) -> int:
    import argparse

    ap = argparse.ArgumentParser(description="the sphere reference: convergence, contact checks, Hertz (cached solves)")
    ap.add_argument("--fresh", action="store_true", help="solve again and overwrite the cache")
    a = ap.parse_args(argv)
    print(study(a.fresh))
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
