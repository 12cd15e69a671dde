"""Pure (no ROS) tests of the mock tool trajectories, the device mapping and the simulated device."""

import math

import numpy as np
import pytest

from skin_sim_node.device.mapping import DeviceMapping, axes_matrix, clamp_magnitude
from skin_sim_node.device.stylus import DeviceParams, SimulatedDevice
from skin_sim_node.device.trajectories import LIFT_Z_M, TRAJECTORIES, ScriptClock
from skin_sim_node.model import SkinModel, classify, interface_depths_m

NAMES = ["press_hold_release", "press_all_layers", "drag", "edge_press", "fast_stab", "lift_during_relax", "light_touch"]
NAMES += ["anchor_hold"]
NAMES += [
    "needle_straight",
    "needle_oblique_15",
    "needle_oblique_30",
    "needle_oblique_60",
    "needle_reinsert",
    "needle_slow",
    "needle_fast",
]


def samples(traj, dt=1e-3):
    ts = np.arange(0.0, traj.duration_s + dt / 2, dt)
    pv = [traj.sample(t) for t in ts]
    return ts, np.array([p for p, _ in pv]), np.array([v for _, v in pv])


# --- trajectories -------------------------------------------------------------------------
def test_trajectory_names_exact():
    assert sorted(TRAJECTORIES) == sorted(NAMES)


def test_pure_import_does_not_load_rclpy():
    import subprocess
    import sys

    code = (
        "import sys; from skin_sim_node.device.trajectories import TRAJECTORIES; "
        "from skin_sim_node.device.stylus import SimulatedDevice; from skin_sim_node.device.render import ContactRenderer; "
        "from skin_sim_node.device.mapping import DeviceMapping; print('rclpy' in sys.modules)"
    )
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True).stdout.strip()
    assert out == "False"


@pytest.mark.parametrize("name", NAMES)
def test_trajectory_starts_and_ends_lifted_at_rest(name):
    traj = TRAJECTORIES[name]
    for t in (-1.0, 0.0, traj.duration_s, traj.duration_s + 1.0):
        p, v = traj.sample(t)
        assert p[2] == pytest.approx(LIFT_Z_M, abs=1e-15)
        assert v == pytest.approx((0.0, 0.0, 0.0), abs=1e-15)


@pytest.mark.parametrize("name", NAMES)
def test_trajectory_velocity_is_exact_derivative(name):
    traj = TRAJECTORIES[name]
    h = 1e-7
    ts = np.linspace(h, traj.duration_s - h, 4001)
    vmax = 0.0
    for t in ts:
        (p1, _), (p0, _) = traj.sample(t + h), traj.sample(t - h)
        fd = (np.array(p1) - np.array(p0)) / (2 * h)
        v = np.array(traj.sample(t)[1])
        vmax = max(vmax, float(np.abs(v).max()))
        # central difference error: h^2/6 |p'''| inside a ramp, h/4 |jump of p''| across a joint (< 1e-5 m/s here)
        np.testing.assert_allclose(v, fd, rtol=0, atol=1e-5)
    assert vmax > 1e-3  # it moves


@pytest.mark.parametrize("name", NAMES)
def test_trajectory_is_continuous(name):
    _, p, v = samples(TRAJECTORIES[name], dt=1e-4)
    # a step of 0.1 ms moves at most v_max * dt: no jumps at the segment joins
    vmax = np.abs(v).max()
    assert np.abs(np.diff(p, axis=0)).max() <= vmax * 1e-4 * 1.0001


def test_press_hold_release_shape():
    traj = TRAJECTORIES["press_hold_release"]
    assert traj.duration_s == pytest.approx(2.3)
    assert traj.sample(0.5)[0] == pytest.approx((0.0, 0.0, -2.5e-3))
    assert traj.sample(1.0)[0] == pytest.approx((0.0, 0.0, -2.5e-3))  # holding
    assert traj.sample(1.5)[0] == pytest.approx((0.0, 0.0, -2.5e-3))  # end of the 1 s hold
    assert traj.sample(1.8)[0] == pytest.approx((0.0, 0.0, LIFT_Z_M))  # released in 0.3 s


def test_press_all_layers_reaches_fat(default_cfg):
    _, p, _ = samples(TRAJECTORIES["press_all_layers"])
    i = np.argmin(p[:, 2])
    assert p[i, 2] == pytest.approx(-4.0e-3)
    assert classify(default_cfg, p[i, 0], p[i, 1], -p[i, 2]).n_affected == 3
    deepest_fat_top = max(interface_depths_m(default_cfg, np.array([p[i, 0]]), np.array([p[i, 1]]))[:, 0])
    assert -p[i, 2] > deepest_fat_top + 2e-3


def test_drag_crosses_interface_peaks_and_valleys(default_cfg):
    traj = TRAJECTORIES["drag"]
    _, p, _ = samples(traj)
    pressed = p[np.isclose(p[:, 2], -1.5e-3, atol=1e-9)]
    assert pressed[:, 0].min() == pytest.approx(-0.02) and pressed[:, 0].max() == pytest.approx(0.02)
    fat_top = interface_depths_m(default_cfg, pressed[:, 0], pressed[:, 1])[1]
    iface = default_cfg.interfaces[1]
    peak, valley = iface.mean_depth_m - iface.amplitude_m, iface.mean_depth_m + iface.amplitude_m
    assert fat_top.min() == pytest.approx(peak, abs=1e-6)
    assert fat_top.max() == pytest.approx(valley, abs=1e-6)
    # at 1.5 mm the tip is below the dermis/fat peaks (0.775 mm) but above the valleys (1.775 mm)
    n = np.array([classify(default_cfg, x, y, -z).n_affected for x, y, z in pressed])
    assert set(n.tolist()) == {2, 3}
    crossings = np.count_nonzero(np.diff(n) != 0)
    assert crossings >= 2 * 40e-3 / iface.wavelength_x_m - 2  # enters and leaves the fat at every peak


def test_edge_press_near_edge(default_cfg):
    _, p, _ = samples(TRAJECTORIES["edge_press"])
    i = np.argmin(p[:, 2])
    assert p[i, 2] == pytest.approx(-2.0e-3)
    assert default_cfg.sheet_size_m[0] / 2 - p[i, 0] == pytest.approx(0.010)


def test_fast_stab_timing():
    traj = TRAJECTORIES["fast_stab"]
    ts, p, _ = samples(traj, dt=1e-5)
    below = ts[p[:, 2] < -1e-9]
    assert below[-1] - below[0] == pytest.approx(0.040, abs=2e-5)  # 20 ms in, 20 ms out
    assert p[:, 2].min() == pytest.approx(-3.0e-3)
    assert ts[np.argmin(p[:, 2])] - below[0] == pytest.approx(0.020, abs=2e-5)


def test_lift_during_relax_comes_back_within_30_ms():
    traj = TRAJECTORIES["lift_during_relax"]
    ts, p, _ = samples(traj, dt=1e-5)
    # the cosine ramps are flat to 1e-9 m within ~5 us of their ends
    i_release = np.nonzero(p[:, 2] < -3.0e-3 + 1e-9)[0][-1]
    i_up = i_release + np.nonzero(p[i_release:, 2] > 0.0)[0][0]
    i_back = i_up + np.nonzero(p[i_up:, 2] < -1.0e-3 + 1e-9)[0][0]
    release_start, back_down = ts[i_release], ts[i_back]
    assert back_down - release_start == pytest.approx(0.030, abs=3e-5)
    between = p[(ts > release_start) & (ts < back_down), 2]
    assert between.max() > 0.0  # the tool left the rest surface in between


def test_script_clock_delay_repeat_tail():
    traj = TRAJECTORIES["fast_stab"]
    clk = ScriptClock(traj, start_delay_s=1.0, repeat=2, tail_s=0.2)
    d = traj.duration_s
    assert clk.trajectory_time(0.5) == 0.0
    assert clk.trajectory_time(1.0 + 0.25) == pytest.approx(0.25)
    assert clk.trajectory_time(1.0 + d + 0.25) == pytest.approx(0.25)
    assert clk.trajectory_time(1.0 + 2 * d + 0.1) >= d
    assert not clk.done(1.0 + 2 * d + 0.19) and clk.done(1.0 + 2 * d + 0.2)
    assert not ScriptClock(traj, 0.0, 0, 0.0).done(1e6)


# --- device mapping -----------------------------------------------------------------------
CONVENTIONS = ["xyz", "x-zy", "-y-xz", "zxy", "-x-y-z", "y-z-x"]


@pytest.mark.parametrize("axes", CONVENTIONS)
def test_mapping_round_trip(axes, rng):
    m = DeviceMapping(offset_m=(0.01, -0.02, 0.05), scale=1.7, axes=axes)
    R = np.array(m.R)
    np.testing.assert_allclose(R @ R.T, np.eye(3))
    for _ in range(20):
        pd = rng.uniform(-0.1, 0.1, 3)
        pt = np.array(m.to_tissue(pd))
        np.testing.assert_allclose(pt, 1.7 * R @ pd + np.array([0.01, -0.02, 0.05]), atol=1e-15)
        np.testing.assert_allclose(m.to_device(pt), pd, atol=1e-15)
        vd = rng.uniform(-1, 1, 3)
        np.testing.assert_allclose(m.velocity_to_tissue(vd), 1.7 * R @ vd, atol=1e-15)
        np.testing.assert_allclose(m.velocity_to_device(m.velocity_to_tissue(vd)), vd, atol=1e-15)


def test_axes_semantics():
    R = np.array(axes_matrix("x-zy"))  # tissue x = dev x, tissue y = -dev z, tissue z = dev y
    np.testing.assert_array_equal(R @ np.array([1.0, 2.0, 3.0]), [1.0, -3.0, 2.0])
    assert DeviceMapping().to_tissue((0.0, 0.0, 0.0)) == pytest.approx((0.0, 0.0, 0.05))
    for bad in ("xxy", "xy", "xyzw", "xyq", ""):
        with pytest.raises(ValueError):
            axes_matrix(bad)


@pytest.mark.parametrize("axes", CONVENTIONS)
def test_force_mapping_is_r_transpose(axes, rng):
    m = DeviceMapping(axes=axes, force_scale=0.8, max_force_n=100.0)
    R = np.array(m.R)
    for _ in range(20):
        f = rng.uniform(-3, 3, 3)
        np.testing.assert_allclose(m.force_to_device(f), 0.8 * R.T @ f, atol=1e-15)


@pytest.mark.parametrize("axes", [a for a in CONVENTIONS if np.linalg.det(np.array(axes_matrix(a))) > 0])
def test_orientation_mapping_matches_r(axes, rng):
    m = DeviceMapping(axes=axes)
    assert m.proper
    q = m.orientation_to_tissue((0.0, 0.0, 0.0, 1.0))
    x, y, z, w = q
    Rq = np.array(
        [
            [1 - 2 * (y * y + z * z), 2 * (x * y - z * w), 2 * (x * z + y * w)],
            [2 * (x * y + z * w), 1 - 2 * (x * x + z * z), 2 * (y * z - x * w)],
            [2 * (x * z - y * w), 2 * (y * z + x * w), 1 - 2 * (x * x + y * y)],
        ]
    )
    np.testing.assert_allclose(Rq, np.array(m.R), atol=1e-12)


def test_force_clamp_keeps_direction_and_bounds_magnitude(rng):
    m = DeviceMapping(axes="x-zy")  # default clamp: 3.3 N
    R = np.array(m.R)
    for _ in range(50):
        f = rng.normal(size=3) * rng.uniform(0.1, 50)
        out = np.array(m.force_to_device(f))
        want = R.T @ f
        assert np.linalg.norm(out) <= 3.3 + 1e-12
        if np.linalg.norm(want) > 3.3:
            assert np.linalg.norm(out) == pytest.approx(3.3)
            np.testing.assert_allclose(out / np.linalg.norm(out), want / np.linalg.norm(want), atol=1e-12)
        else:
            np.testing.assert_allclose(out, want, atol=1e-15)


@pytest.mark.parametrize("bad", [(math.nan, 0.0, 1.0), (0.0, math.inf, 0.0), (-math.inf, math.nan, 2.0)])
def test_non_finite_force_gives_zero(bad):
    assert DeviceMapping().force_to_device(bad) == (0.0, 0.0, 0.0)
    assert clamp_magnitude(bad, 3.3) == (0.0, 0.0, 0.0)


def test_mapping_rejects_bad_values():
    for kw in ({"scale": 0.0}, {"scale": math.nan}, {"force_scale": -1.0}, {"max_force_n": math.inf}, {"offset_m": (0, 0)}):
        with pytest.raises(ValueError):
            DeviceMapping(**kw)


# --- simulated device ---------------------------------------------------------------------
def run_free(dev, dt=1e-3):
    n = int(round(dev.hand_path.duration_s / dt))
    err = np.empty(n)
    for k in range(n):
        dev.step((0.0, 0.0, 0.0), dt)
        err[k] = np.linalg.norm(np.array(dev.pos) - np.array(dev.hand()[0]))
    return err


@pytest.mark.parametrize("name", ["press_hold_release", "drag", "press_all_layers"])
def test_device_tracks_hand_without_force(name):
    dev = SimulatedDevice(name)
    assert dev.pos == pytest.approx(DeviceMapping().to_device(TRAJECTORIES[name].start_m))  # device frame
    err = run_free(dev)
    # lag ~ (B_h + b) / K_h * v_max (10 ms x < 30 mm/s) plus the inertial part: below 0.5 mm
    assert err.max() < 0.5e-3
    for _ in range(1000):  # after the path: settles onto the lifted end pose
        dev.step((0.0, 0.0, 0.0), 1e-3)
    np.testing.assert_allclose(dev.pos_tissue, TRAJECTORIES[name].end_m, atol=1e-6)


def test_device_force_delay_hold_and_saturation():
    dev = SimulatedDevice("press_hold_release", params=DeviceParams(hand_stiffness_n_per_m=0.0, hand_damping_n_s_per_m=0.0))
    dev.step((10.0, 0.0, 0.0), 1e-3)
    assert dev.applied_force_n == (0.0, 0.0, 0.0)  # one tick late
    v0 = dev.vel
    dev.step((math.nan, 0.0, 0.0), 1e-3)
    assert dev.applied_force_n == pytest.approx((3.3, 0.0, 0.0))  # saturated, direction kept
    assert (dev.vel[0] - v0[0]) == pytest.approx(3.3 / 0.045 * 1e-3, rel=1e-2)  # damping 0.05 N*s/m is negligible
    dev.step((0.0, 0.0, 0.0), 1e-3)
    assert dev.applied_force_n == (0.0, 0.0, 0.0)  # the NaN command was held as zero


def test_integrator_stability_bound():
    p = DeviceParams()
    assert p.max_stable_dt_s() > 10e-3  # hand spring alone: omega dt = 0.08 at 1 kHz
    assert p.max_stable_dt_s(9.7e3) > 1e-3  # stiffest default layer (epidermis flat-punch k) at 1 kHz


def test_closed_loop_press_hold_release_settles(default_cfg):
    """SimulatedDevice + SkinModel, force fed back one tick late, following press_hold_release."""
    dev = SimulatedDevice("press_hold_release")
    model = SkinModel(default_cfg)
    dt = 1e-3
    n = int(round(dev.hand_path.duration_s / dt))
    force = np.empty(n)
    z = np.empty(n)
    hand_z = np.empty(n)
    for k in range(n):
        p, v = dev.pos_tissue, dev.vel_tissue
        f = model.step(p, v, dt)
        force[k], z[k], hand_z[k] = f, p[2], dev.mapping.to_tissue(dev.hand()[0])[2]
        dev.step(dev.mapping.force_to_device((0.0, 0.0, f)), dt)
    hold = slice(int(1.0 / dt), int(1.5 / dt))  # last 0.5 s of the hold (0.5 s .. 1.5 s)
    fh = force[hold]
    assert fh.mean() > 0.01
    # settled: no oscillation; the force only creeps down as the tissue relaxes (viscoelastic arms, tau2 = 0.28 s)
    assert np.all(np.diff(fh) <= 1e-9)
    assert fh[0] - fh[-1] < 0.05 * fh.mean()
    k_h = dev.params.hand_stiffness_n_per_m
    # static balance: the hand spring, stretched by the stylus stopping short of the hand, carries the tissue force
    spring = k_h * (z[hold] - hand_z[hold])
    np.testing.assert_allclose(spring, fh, rtol=0.01)
    assert z[hold].mean() > hand_z[hold].mean()  # the stylus stops above (short of) the hand
    assert -z[hold].mean() > 0.5e-3  # and still well inside the tissue (below the ~0.1 mm epidermis, in the dermis)
    assert force[-200:].max() == 0.0  # lifted off at the end
    assert np.all(np.isfinite(force)) and force.max() < 3.3


def test_device_substeps_and_stabiliser_options():
    """substep_s = 0 is the one-step-per-tick integrator; substeps converge; bad options are rejected."""
    a = SimulatedDevice("press_hold_release")
    b = SimulatedDevice("press_hold_release", params=DeviceParams(substep_s=1e-3))  # one substep per 1 ms tick
    fine = SimulatedDevice("press_hold_release", params=DeviceParams(substep_s=1e-5))
    finer = SimulatedDevice("press_hold_release", params=DeviceParams(substep_s=2.5e-6))
    for _ in range(800):
        for d in (a, b, fine, finer):
            d.step((0.0, 0.0, 0.5), 1e-3)
    assert a.pos == b.pos
    np.testing.assert_allclose(fine.pos, finer.pos, atol=1e-7)
    assert SimulatedDevice("drag", params=DeviceParams(stabiliser="passivity")).passivity is not None
    for kw in ({"substep_s": -1.0}, {"substep_s": math.nan}, {"stabiliser": "magic"}):
        with pytest.raises(ValueError):
            DeviceParams(**kw)


def test_closed_loop_through_the_renderer_at_250_hz_settles(default_cfg):
    """The product's force path, pure: server (SkinModel + tangent) at 250 Hz, bridge renderer at 1 kHz with the Touch's
    caps and the passivity controller, SimulatedDevice applying the command one tick late."""
    from msgs_schema.contact_model import LocalModel
    from skin_sim_node.device.render import ContactRenderer

    dev = SimulatedDevice("press_hold_release")
    model = SkinModel(default_cfg)
    r = ContactRenderer(passivity_mass_kg=dev.params.mass_kg)
    dt, every = 1e-3, 4
    n = int(round(dev.hand_path.duration_s / dt))
    force, z = np.zeros(n), np.zeros(n)
    for k in range(n):
        p, v = dev.pos_tissue, dev.vel_tissue
        if k % every == 0:
            model.step(p, v, every * dt if k else 0.0)
            t = model.tangent()
            r.set_model(LocalModel(k, 0, "tissue", p, v, t.force_n, t.stiffness_n_per_m, t.damping_n_s_per_m, t.normal), k * dt)
        f = r.render(k * dt, p, v)
        force[k], z[k] = f[2], p[2]
        dev.step(dev.mapping.force_to_device(tuple(f)), dt)
    hold = slice(int(1.0 / dt), int(1.5 / dt))
    fh = force[hold]
    assert fh.mean() > 0.01 and fh.std() < 0.02 * fh.mean()
    # no steps at the device beyond the passivity controller's damping ending at separation (12 % of the peak here)
    assert np.all(np.abs(np.diff(force)) < 0.15 * max(force.max(), 1e-9))
    assert np.all(force >= 0.0)  # one-sided, the controller's damping included
    assert np.all(np.isfinite(force)) and force.max() <= 3.3
    assert force[-100:].max() < 1e-3  # lifted off at the end
