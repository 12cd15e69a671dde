"""The layered form (issue 11): kernels against references, tangent against finite differences, physics figures."""

import copy
import math

import numpy as np
import pytest
from conftest import kernel
from scipy.integrate import quad
from scipy.special import j0, j1

from skin_sim_lab.oracles import physics
from skin_sim_lab.oracles import reference as ref
from skin_sim_node.model import SkinModel, preset
from skin_sim_node.model import friction as fr
from skin_sim_node.model import layered as lk
from skin_sim_node.model import layered_contact as lkc
from skin_sim_node.model import layered_law as lkl
from skin_sim_node.model import layout as lo
from skin_sim_node.model.calibration import BONE_STIFFNESS, BONE_STRAIN, WALL_STRAIN


@pytest.fixture(scope="module")
def cfg():
    return preset("default")


def test_default_preset_is_layered_and_paper_preset_is_paper(cfg):
    assert cfg.form == "layered" and preset("paper").form == "paper"


def test_jinc_matches_scipy(compiled):
    fn = kernel(lkc.jinc, compiled)
    for x in np.concatenate([np.linspace(1e-9, 3.0, 301), np.linspace(3.0, 300.0, 2000)]):
        w, dw = fn(float(x))
        assert w == pytest.approx(2 * j1(x) / x, abs=1e-7)
        assert dw == pytest.approx(2 * (x * j0(x) - 2 * j1(x)) / x**2, abs=1e-6)


@pytest.mark.parametrize("n", [0.0, 0.5, 1.45, 3.0])
def test_compression_law_matches_reference_and_properties(compiled, n):
    law = kernel(lkl.compression_law, compiled)
    eps = np.linspace(-2.0, 1.5, 701)
    phi = np.array([law(float(e), n, WALL_STRAIN)[0] for e in eps])
    dphi = np.array([law(float(e), n, WALL_STRAIN)[1] for e in eps])
    np.testing.assert_allclose(phi, [ref.compression_law_ref(e, n, WALL_STRAIN) for e in eps], rtol=1e-12, atol=1e-14)
    assert law(0.0, n, WALL_STRAIN) == (0.0, 1.0)  # small-strain stiffness is k
    assert np.all(np.diff(phi) > 0) and np.all(np.diff(dphi) >= -1e-12)  # increasing and convex
    # step 1e-9: at a kink of phi'' on a grid point (the wall, the bone onset at 0.97 where phi'' jumps by K_bone) a
    # central difference's error is ~ step * jump / 4: 2.5e-6 of phi' at K_bone = 1e4; roundoff stays ~1e-7 of phi'
    fd = [(law(float(e) + 1e-9, n, WALL_STRAIN)[0] - law(float(e) - 1e-9, n, WALL_STRAIN)[0]) / 2e-9 for e in eps]
    np.testing.assert_allclose(dphi, fd, rtol=1e-5)
    # stiffens at least like Hencky's 1 / (1 - eps) up to the wall, then keeps the wall's tangent; continuous tangent there
    for e in (0.3, 0.9, WALL_STRAIN):
        assert law(e, n, WALL_STRAIN)[1] >= 0.9999 / (1.0 - min(e, WALL_STRAIN))
    lo, hi = law(WALL_STRAIN - 1e-9, n, WALL_STRAIN), law(WALL_STRAIN + 1e-9, n, WALL_STRAIN)
    assert hi[0] - lo[0] == pytest.approx(2e-9 * lo[1], rel=1e-3)
    # the bottom: from BONE_STRAIN the slope grows by K_bone per unit strain, C1, then stays linear past eps = 1
    base = law(BONE_STRAIN, n, WALL_STRAIN)[1]
    assert law(1.0, n, WALL_STRAIN)[1] - base == pytest.approx(BONE_STIFFNESS * (1.0 - BONE_STRAIN), rel=1e-6)
    assert law(1.4, n, WALL_STRAIN)[1] == pytest.approx(law(1.0, n, WALL_STRAIN)[1], rel=1e-12)


def _chain_case(rng):
    nl = 3
    h = rng.uniform(0.05e-3, 5e-3, nl)
    ea = rng.uniform(0.01, 50.0, nl)
    n = rng.uniform(0.0, 2.5, nl)
    b = rng.uniform(0.0, 1.0, nl) * (rng.random(nl) > 0.3)
    c_old = rng.uniform(-0.1, 0.6, nl) * h * (rng.random() > 0.4)
    d = rng.uniform(0.0, 1.2) * h.sum()
    dt = float(rng.choice([1e-5, 1e-3, 5e-2]))
    # viscoelastic arms' carried-in force: <= 0 after loading from rest (prony_prepare), some cases elastic
    off = -rng.uniform(0.0, 0.3, nl) * ea * (rng.random() > 0.4)
    return d, ea, n, b, dt, c_old, h, off


def test_chain_solve_matches_bracketing_reference(compiled, rng):
    solve = kernel(lkl.chain_solve, compiled)
    checked = 0
    for _ in range(60):
        d, ea, n, b, dt, c_old, h, off = _chain_case(rng)
        c = np.zeros(3)
        g = np.zeros(3)
        t = solve(d, 0.0, ea, n, b, dt, c_old, h, WALL_STRAIN, off, c, g)
        t_ref, c_ref = ref.chain_solve_ref(d, ea, n, b, dt, c_old, h, WALL_STRAIN, off)
        if t_ref < 0:
            assert t == -1.0
            continue
        checked += 1
        assert t == pytest.approx(t_ref, rel=1e-9, abs=1e-12)
        np.testing.assert_allclose(c, c_ref, rtol=1e-8, atol=1e-15)
        assert c.sum() == pytest.approx(d, rel=1e-12, abs=1e-18)
        # iso-stress: every layer carries the same force, each with its own rate (eq 4 with per-layer rates)
        for i in range(3):
            phi, _ = lkl.compression_law(c[i] / h[i], n[i], WALL_STRAIN)
            resid = ea[i] * phi + b[i] / max(dt, lkl.DT_FLOOR_S) * (c[i] - c_old[i]) + off[i]
            assert resid == pytest.approx(t, rel=1e-9, abs=1e-12)
    assert checked > 20


def test_chain_warm_start_gives_the_same_root(rng):
    for _ in range(20):
        d, ea, n, b, dt, c_old, h, off = _chain_case(rng)
        c1, c2, g = np.zeros(3), np.zeros(3), np.zeros(3)
        t1 = lkl.chain_solve(d, 0.0, ea, n, b, dt, c_old, h, WALL_STRAIN, off, c1, g)
        t2 = lkl.chain_solve(d, 1e3, ea, n, b, dt, c_old, h, WALL_STRAIN, off, c2, g)
        assert t1 == pytest.approx(t2, rel=1e-10, abs=1e-13)


def test_averaged_bounds_match_quadrature_and_derivatives(compiled, cfg):
    fn = kernel(lkc.averaged_bounds, compiled)
    m = SkinModel(cfg)
    lp = m._arrays.lp
    bounds, dbx, dby, dbd = np.zeros(4), np.zeros(3), np.zeros(3), np.zeros(3)
    for x0, y0, radius in [(0.0, 0.0, 2.5e-3), (1.7e-3, -0.4e-3, 2.5e-3), (2.5e-3, 0.0, 0.8e-3), (0.3e-3, 1.1e-3, 1.5e-3)]:
        fn(x0, y0, radius, 0.0, lp, 5.275e-3, bounds, dbx, dby, dbd)
        for j in range(2):
            expect = ref.averaged_interface_ref(
                lp[lo.LP_IF_MEAN, j], lp[lo.LP_IF_AMP, j], lp[lo.LP_IF_KX, j], lp[lo.LP_IF_KY, j], x0, y0, radius
            )
            assert bounds[j + 1] == pytest.approx(expect, abs=2e-10)
        h = 1e-7
        plus, minus = np.zeros(4), np.zeros(4)
        scratch = np.zeros(3)
        fn(x0 + h, y0, radius, 0.0, lp, 5.275e-3, plus, scratch, scratch.copy(), scratch.copy())
        fn(x0 - h, y0, radius, 0.0, lp, 5.275e-3, minus, scratch, scratch.copy(), scratch.copy())
        np.testing.assert_allclose(dbx[:2], (plus - minus)[1:3] / (2 * h), rtol=1e-4, atol=1e-9)
        fn(x0, y0 + h, radius, 0.0, lp, 5.275e-3, plus, scratch, scratch.copy(), scratch.copy())
        fn(x0, y0 - h, radius, 0.0, lp, 5.275e-3, minus, scratch, scratch.copy(), scratch.copy())
        np.testing.assert_allclose(dby[:2], (plus - minus)[1:3] / (2 * h), rtol=1e-4, atol=1e-9)
    # the dermis/fat interface under the 5 mm punch varies by a few percent of the fat, not by its full amplitude
    at = [(fn(x, 0.0, 2.5e-3, 0.0, lp, 5.275e-3, bounds, dbx, dby, dbd), bounds[2])[1] for x in np.linspace(0, 5e-3, 51)]
    assert (max(at) - min(at)) / cfg.layers[2].thickness_m < 0.05


def _path():
    out = []
    for i in range(400):
        t = i * 1e-3
        z = -3e-3 * math.sin(math.pi * t / 0.3) if t < 0.3 else 1e-3
        vz = -3e-3 * math.pi / 0.3 * math.cos(math.pi * t / 0.3) if t < 0.3 else 0.0
        out.append(((0.02 * t, 0.001, z), (0.02, 0.003, vz)))
    return out


@pytest.mark.parametrize("shape", ["flat", "sphere"])
def test_layered_step_kernel_compiled_matches_py_func(cfg, shape):
    """The whole layered step, compiled and as .py_func, over a press-drag-release path."""
    c = cfg.replace(**{"tool.shape": shape, "modes.m": 5, "modes.n": 5, "lod.adaptive_modes": False, "lod.idle": False})
    fast, slow = SkinModel(c), SkinModel(c)
    for pos, vel in _path():
        f1 = fast.step(pos, vel, 1e-3)
        slow.kernel_calls += 1
        slow.flags = lk.layered_step_kernel.py_func(*map(float, pos), *map(float, vel), 1e-3, False, *slow._arrays.args)
        assert f1 == pytest.approx(slow.force_n, rel=1e-12, abs=1e-15) and fast.flags == slow.flags
        np.testing.assert_allclose(fast._out, slow._out, rtol=1e-10, atol=1e-13)
        np.testing.assert_allclose(fast.q, slow.q, rtol=1e-10, atol=1e-16)


def _contact_model(cfg, x, y, depth, vel):
    m = SkinModel(cfg)
    physics.press(m, x, y, depth, 5e-3)
    for _ in range(5):
        m.step((x, y, -depth), vel, 1e-3)
    return m


@pytest.mark.parametrize("shape", ["flat", "sphere"])
@pytest.mark.parametrize("where", [(0.0, 0.0), (2.5e-3, 0.0), (0.7e-3, 1.9e-3)])
@pytest.mark.parametrize("vel", [(0.0, 0.0, 0.0), (0.02, -0.01, 0.0), (4e-4, 3e-4, -1e-3)])
def test_tangent_matches_finite_differences(cfg, shape, where, vel):
    """K = dF/dx and D = dF/dv of tangent() against central differences of the next step's force vector."""
    c = cfg.replace(**{"tool.shape": shape})
    x, y = where
    depth = 1.2e-3
    m = _contact_model(c, x, y, depth, vel)
    pos = np.array([x, y, -depth])
    base = copy.deepcopy(m)
    m.step(tuple(pos), vel, 1e-3)
    tan = m.tangent()
    np.testing.assert_allclose(tan.force_n, m.force_vector_n)
    assert tan.in_contact and tan.contact_radius_m > 0

    def force(p, v):
        mm = copy.deepcopy(base)
        mm.step(tuple(p), tuple(v), 1e-3)
        return mm.force_vector_n

    h = 1e-8
    k_fd = np.column_stack([(force(pos + h * e, vel) - force(pos - h * e, vel)) / (2 * h) for e in np.eye(3)])
    scale = np.abs(tan.stiffness_n_per_m).max()
    np.testing.assert_allclose(tan.stiffness_n_per_m, k_fd, atol=2e-5 * scale)
    hv = 1e-7
    d_fd = np.column_stack(
        [(force(pos, np.add(vel, hv * e)) - force(pos, np.subtract(vel, hv * e))) / (2 * hv) for e in np.eye(3)]
    )
    np.testing.assert_allclose(tan.damping_n_s_per_m, d_fd, atol=1e-5 * max(1.0, np.abs(d_fd).max()))
    assert tan.normal @ tan.stiffness_n_per_m @ tan.normal < 0  # pressing in raises the force


def test_monotone_slow_press_at_many_points(cfg):
    """A 0.5 mm/s press to 5 mm never drops below 99 % of its running maximum, at 24 points of the sheet."""
    worst, _ = physics.monotone_scan(cfg, n_points=24)
    assert worst < 0.01


def test_drag_at_1mm_varies_at_most_1_3x(cfg):
    for y in (0.0, cfg.interfaces[-1].wavelength_x_m / 4):
        ratio, fmin, fmax = physics.drag_ratio(cfg, y_m=y)
        assert fmin > 0 and ratio <= 1.3


@pytest.mark.parametrize("depth", physics.BAND_DEPTHS_M)
def test_force_inside_the_in_vivo_band(cfg, depth):
    lo, hi = physics.band_n(depth)
    for x, y in [(0.0, 0.0), (cfg.interfaces[-1].wavelength_x_m / 2, 0.0)]:
        assert lo <= physics.quasi_static_force(cfg, depth, x, y) <= hi


def test_wall_below_the_stack_rises_steeply_and_stays_finite(cfg):
    curve = physics.wall_curve(cfg)
    f = np.array([p[1] for p in curve])
    d = np.array([p[0] for p in curve])
    assert np.all(np.diff(f) > 0)  # no clamp: deeper is always harder
    slope_deep = np.diff(f)[-1] / np.diff(d)[-1]
    k_small = 1.0 / sum(1.0 / la.stiffness_n_per_m for la in cfg.layers)
    # the fitted law's slope saturates at its wall strain (issue 20), and the bone term past BONE_STRAIN is the
    # bottom: a steep wall, as before the refit
    assert slope_deep > 50 * k_small
    m = SkinModel(cfg)  # a single tick 1 m into the tissue: finite, bounded by the wall's tangent line
    f1 = m.step((0.0, 0.0, -1.0), (0.0, 0.0, 0.0), 1e-3)
    assert math.isfinite(f1) and 0 < f1 < 1e3 * slope_deep


def elastic(cfg):
    """``cfg`` without viscoelastic arms: the elastic series chain (the equilibrium law)."""
    return physics.equilibrium(cfg)


@pytest.mark.parametrize("dt", [1e-4, 1e-3, 2e-2, 0.2])
def test_chain_is_passive_for_any_dt(cfg, dt):
    """Over press-release cycles the tool does non-negative work beyond the stored strain energy (backward Euler).
    The elastic chain, whose stored energy is the springs' alone; the arms: test_viscoelastic.py."""
    m = SkinModel(elastic(cfg))
    ea = m._arrays.lp[lo.LP_EA]
    nexp = m._arrays.lp[lo.LP_N]

    def stored(comp, thick):
        total = 0.0
        for i in range(3):
            n_i = nexp[i]
            energy = quad(lambda e, n_i=n_i: lkl.compression_law(e, n_i, WALL_STRAIN)[0], 0, comp[i] / thick[i])[0]
            total += ea[i] * thick[i] * energy
        return total

    work = 0.0
    d_prev = 0.0
    steps = max(20, int(0.6 / dt))
    for i in range(1, steps + 1):
        d = 2e-3 * (1 - math.cos(2 * math.pi * 3 * i / steps)) / 2 + 0.2e-3
        f = m.step((0.0, 0.0, -d), (0.0, 0.0, 0.0), dt)
        work += f * (d - d_prev)
        d_prev = d
    assert m.in_contact
    assert work - stored(m.compression_m, m._arrays.aux[lo.AUX_THICK, :3]) >= -1e-12


def test_series_dampers_are_softer_than_the_common_velocity(cfg):
    """A 100 mm/s press to 1 mm: dampers truly in series add less than the paper's common velocity (eq 6) does
    (the Kelvin-Voigt dampers alone: the viscoelastic arms' rate effect is test_viscoelastic.py's)."""
    inc = {}
    for form in ("layered", "paper"):
        c = elastic(cfg).replace(form=form)
        inc[form] = physics.press(SkinModel(c), 0.0, 0.0, 1e-3, 0.1) - physics.quasi_static_force(c, 1e-3)
    assert 0 < inc["layered"] < inc["paper"]


def test_friction_sticks_then_slides_against_the_motion(cfg):
    """Presliding (issue 30): a sideways move within the slip distance stretches the skin (``-k_t dx``); beyond it the
    friction is ``mu F_n`` against the motion, whatever velocity the step is told."""
    mu, k_t = cfg.friction_coefficient, cfg.tangential_stiffness_n_per_m
    for dx, vx in [(1e-5, 0.0), (1e-5, -5.0), (5e-3, 0.05)]:
        m = _contact_model(cfg, 0.0, 0.0, 1e-3, (0.0, 0.0, 0.0))
        m.step((dx, 0.0, -1e-3), (vx, 0.0, 0.0), 1e-3)
        fv = m.force_vector_n
        assert fv[0] < 0 and abs(fv[1]) < 1e-15
        if dx * k_t < mu * m.force_n:  # stick: elastic
            assert fv[0] == pytest.approx(-k_t * dx, rel=1e-9)
        else:  # slip: the slip level
            assert abs(fv[0]) == pytest.approx(mu * m.force_n, rel=1e-9)


def test_force_follows_the_tilted_deformed_surface(cfg):
    """Touching the flank of a fresh dent: the force leans along the surface normal, towards the dent's centre."""
    m = SkinModel(cfg)
    physics.press(m, 0.0, 0.0, 3e-3, 0.05)
    m.step((0.0, 0.0, 0.01), (0, 0, 0), 1e-3)  # lift off; the dent relaxes
    x = 0.005  # 2.5 mm outside the punch's rim, on the dent's flank (it decays over the foundation length)
    s = m.surface_displacement_at(x, 0.0)
    assert s > 1e-4
    m.step((x, 0.0, -(s + 2e-5)), (0, 0, 0), 1e-3)
    assert m.in_contact
    n = m.contact_normal
    fv = m.force_vector_n
    assert n[0] < -1e-3 and abs(np.linalg.norm(n) - 1) < 1e-12
    np.testing.assert_allclose(fv, m.force_n * n, rtol=1e-12)


def test_sphere_contact_radius_grows_with_depth(cfg):
    c = cfg.replace(**{"tool.shape": "sphere"})
    r = c.tool_radius_m
    radii, forces = [], []
    for d in (0.1e-3, 0.4e-3, 1.0e-3, 2.0e-3):
        m = SkinModel(c)
        forces.append(physics.press(m, 0.0, 0.0, d, 1e-3, hold_s=0.5))
        radii.append(m.contact_radius_m)
        assert m.contact_radius_m == pytest.approx(math.sqrt(r * d), rel=1e-12)
    assert np.all(np.diff(radii) > 0) and np.all(np.diff(forces) > 0)
    flat = physics.quasi_static_force(cfg, 1e-3)
    assert forces[2] < flat  # a sphere loads a smaller area than the punch of the same radius


def test_every_layer_deforms_in_the_grid(cfg):
    m = SkinModel(cfg)
    physics.press(m, 0.0, 0.0, 2e-3, 5e-3)
    g = m.build_grid()
    per_layer = g.displacement_m.reshape(3, -1).max(axis=1)
    assert np.all(per_layer > 0)
    np.testing.assert_allclose(per_layer, m.compression_m, rtol=0.05)  # each layer's membrane shows its compression
    assert per_layer[2] > 0.5e-3  # the fat takes most of a 2 mm press


def test_paper_preset_still_reproduces_eq9():
    assert physics.eq9_error(preset("paper")) < 1e-9


def test_presliding_tangent_kernel_matches_numpy_reference(compiled, rng):
    """K of the presliding friction (stick and slip), compiled and as py_func, against the NumPy expression."""
    fn = kernel(fr.presliding_tangent, compiled)
    for _ in range(40):
        normal = rng.normal(size=3)
        normal /= np.linalg.norm(normal)
        grad = rng.normal(size=3) * 100.0
        stretch = rng.normal(size=3) * 1e-3
        stretch -= (stretch @ normal) * normal
        k_t, mu, force = rng.uniform(10, 1000), rng.uniform(0, 1), rng.uniform(0, 3)
        k = np.empty((3, 3))
        fn(normal, stretch, k_t, mu, force, grad, k)
        np.testing.assert_allclose(k, ref.presliding_tangent_ref(normal, stretch, k_t, mu, force, grad), rtol=1e-12, atol=1e-9)
