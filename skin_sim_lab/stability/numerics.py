"""Numerical stability and accuracy maps of the shared layer-PDE solvers over ``dt`` and ``dx``.

Same PDE for every method (:mod:`skin_sim_lab.solvers`): the default dermis membrane on the
paper's 60 mm patch (``c = 2.2 m/s``), undamped so that a stable scheme's energy cannot grow and
the explicit limits are the textbook ones. Initial state: the static indentation of the 5 mm tool
to 1 mm, released at rest (the model's release-and-return; the disk edge excites every grid mode).

Per (method, grid, dt):

- **energy grows**: the solver's own discrete energy exceeds 100 x its initial value within
  ``max(t_end / dt, MIN_STEPS)`` steps (a stable explicit scheme keeps it bounded; past the limit
  the highest grid mode grows geometrically from round-off);
- **error** (of the time integration): max |u - u_ref| at ``t_end`` over the initial peak, with
  ``u_ref`` the exact-in-time solution of the same spatially discrete system: the 5-point operator's
  own sine modes and frequencies (:func:`semi_discrete_reference`) for the grid methods (leapfrog,
  implicit, mass-spring: all integrate that operator), the continuum modes (:class:`ModalSolver` with
  every mode the grid carries) for the modal method. The spatial error of the 5-point grid against
  the continuum is separate (:func:`spatial_error`): it does not depend on ``dt``.

Theory: leapfrog ``dt < 2 / omega_max`` (``c dt / dx <= 1 / sqrt(2)`` as the grid refines), mass-spring
semi-implicit Euler ``omega dt < 2``; both are ``2 / omega_max`` of the same 5-point operator.
``skin-sim stability-numerics`` prints the measured CFL boundaries (``main``).
"""

from __future__ import annotations

import argparse
import math
import warnings
from dataclasses import dataclass

import numpy as np
from tqdm import tqdm

from skin_sim_node.model import preset

from ..solvers import (
    ImplicitSolver,
    LeapfrogSolver,
    MassSpringSolver,
    Membrane,
    ModalSolver,
    leapfrog_dt_limit_s,
    mass_spring_dt_limit_s,
    membrane_from_layer,
    static_indentation,
)

T_END_S = 0.04
"""Error time: about one period of the dermis fundamental (2 pi / lambda_11 = 38.5 ms)."""
MIN_STEPS = 1000
"""Steps for the energy test: just past the limit the top mode grows ~1.2x per step, from 1e-16 to
visible in ~200 steps."""
GROWTH = 100.0
DEPTH_M = 1e-3
GRIDS = (7, 11, 15, 23, 31, 47)  # interior nodes per side: dx = 7.5 .. 1.25 mm
STEP_COUNTS = (1, 2, 3, 5, 8, 13, 20, 32, 50, 80, 128, 200, 320, 500, 800, 1280, 2000)  # dt = T_END / count
METHODS = ("exact modal", "leapfrog", "crank_nicolson", "backward_euler", "mass-spring")


def dermis_membrane() -> Membrane:
    """The default dermis layer on the 60 mm patch, without damping (see the module docstring)."""
    m = membrane_from_layer(preset("default"), 1)
    return Membrane(m.size_x_m, m.size_y_m, m.areal_density_kg_per_m2, m.tension_n_per_m)


def make_solver(method: str, mem: Membrane, n: int):
    """The baseline solver ``method`` (``exact modal``, ``leapfrog``, ``mass-spring``, an implicit scheme) on ``n x n`` nodes."""
    if method == "exact modal":
        return ModalSolver(mem, n, n)
    if method == "leapfrog":
        return LeapfrogSolver(mem, n, n)
    if method == "mass-spring":
        return MassSpringSolver(mem, n, n)
    return ImplicitSolver(mem, n, n, scheme=method)


def dt_limit_s(method: str, mem: Membrane, n: int) -> float:
    """Theoretical stability limit (s); inf for the unconditionally stable methods."""
    if method == "leapfrog":
        return leapfrog_dt_limit_s(mem, n, n)
    if method == "mass-spring":
        return mass_spring_dt_limit_s(mem, n, n)
    return math.inf


def initial_state(mem: Membrane, n: int) -> np.ndarray:
    """The static indentation of ``mem`` to :data:`DEPTH_M` under the tool: the released start of every run (m)."""
    return static_indentation(mem, n, n, DEPTH_M)[1]


@dataclass(frozen=True)
class Point:
    """One sweep point: method, grid, time step, Courant number ``c dt / dx`` and the largest energy ratio ``E / E0``."""

    method: str
    n: int
    dx_m: float
    dt_s: float
    courant: float  # c dt / dx
    energy_ratio: float  # max over the run of E / E0
    error: float  # at T_END_S, relative to the initial peak (nan if not reached finite)

    @property
    def grows(self) -> bool:
        """True if the energy grew past :data:`GROWTH` (or became non-finite): the method is unstable here."""
        return not (self.energy_ratio <= GROWTH)


def energy_growth(solver, dt_s: float, n_steps: int, chunks: int = 20) -> float:
    """Max of E / E0 over ``n_steps`` steps, sampled every ``n_steps / chunks`` steps."""
    e0 = solver.energy_j()
    worst = 1.0
    done = 0
    with np.errstate(over="ignore", invalid="ignore"), warnings.catch_warnings():
        warnings.simplefilter("ignore")
        for c in range(chunks):
            k = (n_steps * (c + 1)) // chunks - done
            if k > 0:
                solver.advance(dt_s, k)
                done += k
            e = solver.energy_j()
            if not math.isfinite(e) or e > GROWTH * e0:
                return math.inf
            worst = max(worst, e / e0)
    return worst


def reference(mem: Membrane, n: int, u0: np.ndarray) -> np.ndarray:
    """Exact continuum modal solution at ``T_END_S`` from rest (every mode the grid carries)."""
    ref = ModalSolver(mem, n, n)
    ref.set_state(u0)
    ref.advance(T_END_S, 1)
    return ref.u_m.copy()


def semi_discrete_reference(mem: Membrane, n: int, u0: np.ndarray, t_s: float = T_END_S) -> np.ndarray:
    """Exact-in-time solution of the 5-point semi-discrete system from rest (undamped, no foundation).

    The DST-I diagonalises the 5-point Laplacian with Dirichlet edges; mode ``(m, n)`` has
    ``omega^2 = T (mu_x,m + mu_y,n) / rho_A`` (:func:`skin_sim_lab.solvers.membrane.discrete_eigen_per_area`).
    """
    from scipy.fft import dstn, idstn

    from ..solvers.membrane import discrete_eigen_per_area, grid_spec

    mu_x, mu_y = discrete_eigen_per_area(grid_spec(mem, n, n))
    w = np.sqrt(mem.tension_n_per_m * (mu_y[:, None] + mu_x[None, :]) / mem.areal_density_kg_per_m2)
    return idstn(dstn(u0, type=1) * np.cos(w * t_s), type=1)


def spatial_error(mem: Membrane, n: int) -> float:
    """Max |5-point semi-discrete - continuum| at ``T_END_S`` over the initial peak (no time stepping)."""
    u0 = initial_state(mem, n)
    return float(np.max(np.abs(semi_discrete_reference(mem, n, u0) - reference(mem, n, u0))) / np.max(np.abs(u0)))


def run_point(method: str, mem: Membrane, n: int, steps: int, u0=None, u_ref=None) -> Point:
    """One map point: ``dt = T_END_S / steps``; error at ``T_END_S``, energy over ``max(steps, MIN_STEPS)``."""
    u0 = initial_state(mem, n) if u0 is None else u0
    if u_ref is None:
        u_ref = reference(mem, n, u0) if method == "exact modal" else semi_discrete_reference(mem, n, u0)
    dt = T_END_S / steps
    s = make_solver(method, mem, n)
    s.set_state(u0)
    with np.errstate(over="ignore", invalid="ignore"), warnings.catch_warnings():
        warnings.simplefilter("ignore")
        s.advance(dt, steps)
        err = float(np.max(np.abs(s.u_m - u_ref)) / np.max(np.abs(u0)))
    err = err if math.isfinite(err) else math.inf
    s.set_state(u0)
    ratio = energy_growth(s, dt, max(steps, MIN_STEPS))
    dx = mem.size_x_m / (n + 1)
    return Point(method, n, dx, dt, mem.wave_speed_m_s * dt / dx, ratio, err)


def sweep(
    methods=METHODS, grids=GRIDS, step_counts=STEP_COUNTS, mem: Membrane | None = None, progress: bool = True
) -> list[Point]:
    """Run every method on every grid at every step count; one :class:`Point` each."""
    mem = mem or dermis_membrane()
    out = []
    total = len(grids) * len(methods) * len(step_counts)
    bar = tqdm(total=total, desc="numerics sweep (grid x method x dt)", disable=not progress)
    for n in grids:
        u0 = initial_state(mem, n)
        refs = {"exact modal": reference(mem, n, u0), "grid": semi_discrete_reference(mem, n, u0)}
        for method in methods:
            for steps in step_counts:
                out.append(run_point(method, mem, n, steps, u0, refs["exact modal" if method == "exact modal" else "grid"]))
                bar.update()
    bar.close()
    return out


def measured_dt_limit_s(method: str, mem: Membrane, n: int, rel_tol: float = 1e-3, n_steps: int = 2 * MIN_STEPS) -> float:
    """Bisect the largest ``dt`` whose energy stays within ``GROWTH`` x over ``n_steps`` steps."""
    u0 = initial_state(mem, n)
    theory = dt_limit_s(method, mem, n)
    lo, hi = 0.5 * theory, 2.0 * theory

    def stable(dt):
        s = make_solver(method, mem, n)
        s.set_state(u0)
        return energy_growth(s, dt, n_steps) <= GROWTH

    assert stable(lo) and not stable(hi), "bracket"
    while hi / lo - 1 > rel_tol:
        mid = math.sqrt(lo * hi)
        lo, hi = (mid, hi) if stable(mid) else (lo, mid)
    return lo


def main(argv=None) -> int:
    """Print the measured explicit limits against theory for each grid."""
    ap = argparse.ArgumentParser(prog="skin-sim stability-numerics", description=__doc__.splitlines()[0])
    ap.add_argument("--grids", type=int, nargs="*", default=list(GRIDS))
    args = ap.parse_args(argv)
    print(f"stability-numerics: bisecting the explicit dt limits on {len(args.grids)} grid(s) x 2 methods", flush=True)
    mem = dermis_membrane()
    c = mem.wave_speed_m_s
    print(f"dermis membrane c = {c:.3f} m/s, patch {mem.size_x_m * 1e3:.0f} mm, undamped; energy growth > {GROWTH:g}x")
    print("  method      |  n  | dx mm | measured dt us | 2/omega_max us | ratio | c dt/dx measured | 1/sqrt(2)")
    for method in ("leapfrog", "mass-spring"):
        for n in args.grids:
            dx = mem.size_x_m / (n + 1)
            meas, th = measured_dt_limit_s(method, mem, n), dt_limit_s(method, mem, n)
            tqdm.write(
                f"  {method:<11} | {n:3d} | {dx * 1e3:5.2f} | {meas * 1e6:14.2f} | {th * 1e6:14.2f} | {meas / th:5.3f} | "
                f"{c * meas / dx:16.4f} | {1 / math.sqrt(2):.4f}"
            )
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
