"""Baseline membrane solvers: kernels against NumPy, limits, energy, exactness, statics."""

import math

import numpy as np
import pytest

from skin_sim_lab.solvers import (
    ImplicitSolver,
    LeapfrogSolver,
    MassSpringSolver,
    Membrane,
    ModalSolver,
    grid_spec,
    leapfrog_dt_limit_s,
    mass_spring_dt_limit_s,
    membrane_from_layer,
    static_indentation,
)
from skin_sim_lab.solvers import kernels as sk
from skin_sim_lab.solvers import reference as ref
from skin_sim_node.model import preset
from tests.conftest import kernel

MEM = Membrane(0.06, 0.05, 1.2, 3.0, damping_n_s_per_m3=40.0, foundation_n_per_m3=500.0)
UNDAMPED = Membrane(0.06, 0.06, 1.0, 1.0)


def bump(mem, nx, ny, width=0.006):
    g = grid_spec(mem, nx, ny)
    X, Y = np.meshgrid(g.xs_m, g.ys_m)
    return 1e-3 * np.exp(-(X**2 + Y**2) / (2 * width**2))


def test_leapfrog_kernel_matches_numpy(compiled, rng):
    u, up, load = rng.standard_normal((3, 7, 9))
    args = (0.01, 1.2, 3.0, 40.0, 500.0, 0.006, 0.005)
    want_u, want_prev = u, up
    for _ in range(3):
        want_u, want_prev = ref.leapfrog_step(want_u, want_prev, load, *args)
    got_u, got_prev = u.copy(), up.copy()
    kernel(sk.leapfrog_membrane_steps, compiled)(got_u, got_prev, load, 3, *args, np.zeros_like(u))
    np.testing.assert_allclose(got_u, want_u, rtol=1e-12, atol=1e-12)
    np.testing.assert_allclose(got_prev, want_prev, rtol=1e-12, atol=1e-12)


def test_mass_spring_kernel_matches_numpy(compiled, rng):
    u, v, load = rng.standard_normal((3, 6, 5))
    args = (1e-3, 0.2, 30.0, 40.0, 5.0, 0.3, 0.07)
    want_u, want_v = u, v
    for _ in range(4):
        want_u, want_v = ref.mass_spring_step(want_u, want_v, load, *args)
    got_u, got_v = u.copy(), v.copy()
    kernel(sk.mass_spring_steps, compiled)(got_u, got_v, load, 4, *args, np.zeros_like(u))
    np.testing.assert_allclose(got_u, want_u, rtol=1e-12, atol=1e-12)
    np.testing.assert_allclose(got_v, want_v, rtol=1e-12, atol=1e-12)


def test_leapfrog_limit_is_the_cfl_condition():
    nx = 199
    dx = UNDAMPED.size_x_m / (nx + 1)
    cfl_dt = dx / (math.sqrt(2) * UNDAMPED.wave_speed_m_s)
    assert leapfrog_dt_limit_s(UNDAMPED, nx, nx) == pytest.approx(cfl_dt, rel=1e-4)
    # undamped mass-spring: omega_max dt = 2, the same operator as the leapfrog
    assert mass_spring_dt_limit_s(UNDAMPED, nx, nx) == pytest.approx(leapfrog_dt_limit_s(UNDAMPED, nx, nx), rel=1e-12)
    assert mass_spring_dt_limit_s(UNDAMPED, nx, nx, edge_damping_n_s_per_m=0.01) < cfl_dt


@pytest.mark.parametrize("solver_cls, limit", [(LeapfrogSolver, leapfrog_dt_limit_s), (MassSpringSolver, mass_spring_dt_limit_s)])
def test_explicit_solvers_blow_up_just_past_their_limit(solver_cls, limit, rng):
    nx = ny = 15
    u0 = bump(UNDAMPED, nx, ny) + 1e-9 * rng.standard_normal((ny, nx))
    growth = {}
    for factor in (0.98, 1.02):
        s = solver_cls(UNDAMPED, nx, ny)
        s.set_state(u0)
        e0 = s.energy_j()
        with np.errstate(all="ignore"):
            s.advance(factor * limit(UNDAMPED, nx, ny), 4000)
        growth[factor] = s.energy_j() / e0
    assert growth[0.98] < 2.0  # bounded (the symplectic scheme's energy oscillates, it does not grow)
    assert not (growth[1.02] < 1e6)  # grew by orders of magnitude, or overflowed


def test_leapfrog_and_crank_nicolson_conserve_energy_undamped():
    nx = ny = 19
    u0 = bump(UNDAMPED, nx, ny)
    dt = 0.5 * leapfrog_dt_limit_s(UNDAMPED, nx, ny)
    for s in (LeapfrogSolver(UNDAMPED, nx, ny), ImplicitSolver(UNDAMPED, nx, ny, "crank_nicolson")):
        s.set_state(u0)
        s.step(dt)
        e1 = s.energy_j()
        s.advance(dt, 500)
        assert s.energy_j() == pytest.approx(e1, rel=1e-9), s.name


def test_backward_euler_dissipates_and_implicit_is_stable_far_past_the_limit():
    nx = ny = 19
    u0 = bump(UNDAMPED, nx, ny)
    big_dt = 50 * leapfrog_dt_limit_s(UNDAMPED, nx, ny)
    for scheme in ("crank_nicolson", "backward_euler"):
        s = ImplicitSolver(UNDAMPED, nx, ny, scheme)
        s.set_state(u0)
        e0 = s.energy_j()
        energies = []
        for _ in range(200):
            s.step(big_dt)
            energies.append(s.energy_j())
        assert max(energies) <= e0 * (1 + 1e-9)
        if scheme == "backward_euler":
            assert energies[-1] < 0.5 * e0


def test_modal_solver_single_mode_matches_closed_form():
    nx, ny = 11, 9
    g = grid_spec(MEM, nx, ny)
    X, Y = np.meshgrid(g.xs_m, g.ys_m)
    shape = np.sin(2 * math.pi * (X + MEM.size_x_m / 2) / MEM.size_x_m) * np.sin(math.pi * (Y + MEM.size_y_m / 2) / MEM.size_y_m)
    s = ModalSolver(MEM, nx, ny)
    s.set_state(1e-3 * shape)
    t = 0.0123
    s.advance(t / 7, 7)
    kappa2 = math.pi**2 * ((2 / MEM.size_x_m) ** 2 + (1 / MEM.size_y_m) ** 2)
    w0 = math.sqrt((MEM.tension_n_per_m * kappa2 + MEM.foundation_n_per_m3) / MEM.areal_density_kg_per_m2)
    g_ = MEM.damping_rate_per_s
    wd = math.sqrt(w0**2 - g_**2)
    amp = 1e-3 * math.exp(-g_ * t) * (math.cos(wd * t) + g_ / wd * math.sin(wd * t))
    np.testing.assert_allclose(s.u_m, amp * shape, atol=1e-12)


def test_modal_solver_static_load_matches_the_discrete_static_solve_and_truncates():
    import scipy.sparse.linalg as spla

    from skin_sim_lab.solvers.membrane import stiffness_per_area

    nx = ny = 31
    g = grid_spec(MEM, nx, ny)
    load = 10.0 * np.exp(-(np.add.outer(g.ys_m**2, g.xs_m**2)) / (2 * 0.008**2))
    s = ModalSolver(MEM, nx, ny)
    s.set_state(np.zeros((ny, nx)))
    s.advance(10.0, 1, load_pa=load)  # long after the transient: the continuum static solution
    fd = spla.spsolve(stiffness_per_area(MEM, g).tocsc(), load.ravel()).reshape(ny, nx)
    assert np.abs(s.u_m - fd).max() < 0.01 * fd.max()  # 5-point truncation error only
    assert np.abs(s.v_m_s).max() < 1e-12
    t = ModalSolver(MEM, nx, ny, modes=(3, 3))
    t.set_state(bump(MEM, nx, ny))
    coeffs = t._qu
    assert t.modes == (3, 3) and np.count_nonzero(coeffs) <= 9


def test_explicit_and_implicit_converge_to_the_exact_modal_release():
    cfg = preset("default")
    mem = membrane_from_layer(cfg, 1)
    errs = []
    for nx in (15, 31):
        u0 = bump(mem, nx, nx)
        exact = ModalSolver(mem, nx, nx)
        exact.set_state(u0)
        dt = 0.25 * leapfrog_dt_limit_s(mem, nx, nx)
        n = int(round(2e-3 / dt))
        exact.advance(dt, n)
        row = []
        for s in (LeapfrogSolver(mem, nx, nx), ImplicitSolver(mem, nx, nx), MassSpringSolver(mem, nx, nx)):
            s.set_state(u0)
            s.advance(dt, n)
            row.append(np.abs(s.u_m - exact.u_m).max() / 1e-3)
        errs.append(row)
    errs = np.array(errs)
    assert (errs[1] < errs[0]).all(), errs  # refining space and time reduces every method's error


def test_static_indentation_is_linear_symmetric_and_positive():
    f1, u1 = static_indentation(MEM, 31, 31, 1e-3)
    f2, u2 = static_indentation(MEM, 31, 31, 2e-3)
    assert f1 > 0 and f2 == pytest.approx(2 * f1, rel=1e-12)
    np.testing.assert_allclose(u1, u1[::-1, ::-1], atol=1e-15)
    assert 0 <= u1.min() and u1.max() == pytest.approx(1e-3)


@pytest.mark.parametrize(
    "bad", [dict(tension_n_per_m=-1.0), dict(areal_density_kg_per_m2=0.0), dict(damping_n_s_per_m3=math.nan)]
)
def test_membrane_rejects_invalid_parameters(bad):
    kw = dict(size_x_m=0.06, size_y_m=0.06, areal_density_kg_per_m2=1.0, tension_n_per_m=1.0) | bad
    with pytest.raises(ValueError, match="Membrane"):
        Membrane(**kw)
