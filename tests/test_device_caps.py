"""Pure, deterministic tests of the bridge's force safety (issue 19, device side): the damping and stiffness caps,
the friction cone, the vector clamp, the device-clock fade and the namespace option's helpers. No ROS, no wall
clock: the test steps the device (its pose stamps) itself. Also the device path's transport choice under LOCALHOST
(an environment and a profile file, read, not run)."""

import math

import numpy as np
import pytest

from msgs_schema.contact_model import LocalModel
from skin_sim_node.device.mapping import (
    TOUCH_MAX_DAMPING_N_S_PER_M,
    TOUCH_MAX_STIFFNESS_N_PER_M,
    TOUCH_PEAK_FORCE_N,
    DeviceMapping,
    normalize_namespace,
    without_namespace_remap,
)
from skin_sim_node.device.render import (
    FADE_S,
    FRICTION_CONE_FLOOR,
    MAX_TICK_S,
    PASSIVITY_DELAY_TICKS,
    SERVO_PERIOD_S,
    ContactRenderer,
    cap_spectral_norm,
    clamp_vec,
)
from skin_sim_node.ros_util import UDP_LOOPBACK_PROFILE, localhost_udp_env

Z = np.array([0.0, 0.0, 1.0])
TANGENT = np.eye(3) - np.outer(Z, Z)
DT = 1e-3


def friction_model(seq=1, f0=(0.0, 0.0, 0.35), d_t=-3514.0, k_n=-1000.0, v0=(0.0, 0.0, 0.0), ttl=10.0, radius=1.0):
    """The model of issue 19's pose-less tick: f0 straight down, friction's mu F / v_s at zero speed as tangential D."""
    K = k_n * np.outer(Z, Z)
    D = d_t * TANGENT
    return LocalModel(seq, 0, "tissue", (0, 0, -1e-3), v0, f0, K, D, Z, radius, ttl)


def tangential(f):
    return float(np.linalg.norm(f - (f @ Z) * Z))


def settle(r, m, t0=0.0):
    """Deliver ``m`` at device time ``t0`` and step past the crossfade (``CROSSFADE_MAX_S``)."""
    r.set_model(m, t0)
    for i in range(25):
        r.render(t0 + i * DT, m.x0_m, m.v0_m_s)
    return t0 + 25 * DT


# --- caps ------------------------------------------------------------------------------------
def test_default_caps_are_the_touch_limits():
    r = ContactRenderer()
    assert (r.max_force_n, r.max_k, r.max_d) == (TOUCH_PEAK_FORCE_N, TOUCH_MAX_STIFFNESS_N_PER_M, TOUCH_MAX_DAMPING_N_S_PER_M)
    assert TOUCH_MAX_DAMPING_N_S_PER_M == 5.0 and TOUCH_MAX_STIFFNESS_N_PER_M == 1020.0


@pytest.mark.parametrize("seed", range(6))
def test_capped_matrices_have_no_direction_above_the_limit(seed):
    rng = np.random.default_rng(seed)
    A = rng.normal(scale=1e4, size=(3, 3))
    B = cap_spectral_norm(A, 5.0)
    u = rng.normal(size=(500, 3))
    u /= np.linalg.norm(u, axis=1, keepdims=True)
    assert np.linalg.norm(u @ B.T, axis=1).max() <= 5.0 + 1e-9  # |B u| <= limit for every unit direction
    np.testing.assert_allclose(B / np.linalg.norm(B), A / np.linalg.norm(A))  # scaled as a whole, structure kept
    small = 1e-3 * np.eye(3)
    np.testing.assert_array_equal(cap_spectral_norm(small, 5.0), small)  # below the cap: untouched


def test_damping_is_capped_beside_stiffness():
    r = ContactRenderer(max_force_n=math.inf)
    K, D = r.bounded(friction_model(k_n=-5e4))
    assert np.linalg.norm(K, 2) == pytest.approx(TOUCH_MAX_STIFFNESS_N_PER_M)
    assert np.linalg.norm(D, 2) == pytest.approx(TOUCH_MAX_DAMPING_N_S_PER_M)


def test_issue_19_sideways_flip_is_not_amplified():
    """f0 0.35 N straight down, D_t = -3514 N s/m, a device velocity flipping sideways at 0.1 m/s: before, 3.3 N
    sideways commands that flip sign; now the tangential part is at most the damping cap times the speed and inside
    the friction cone, and the normal force is the model's."""
    m = friction_model()
    r = ContactRenderer()
    t = settle(r, m)
    for i in range(200):
        v = np.array([0.1 if i % 2 else -0.1, 0.0, 0.0])
        f = r.render(t + i * DT, m.x0_m, v)
        assert f @ Z == pytest.approx(0.35, abs=1e-12)
        assert tangential(f) <= min(TOUCH_MAX_DAMPING_N_S_PER_M * 0.1, FRICTION_CONE_FLOOR * 0.35) + 1e-12
        assert np.linalg.norm(f) <= 1.2 * 0.35 / math.cos(math.atan(FRICTION_CONE_FLOOR)) + 0.05


def test_whole_vector_f0_is_rendered_at_x0():
    """The contact model's whole f0, friction included, reaches the device at x0; a model sliding at a higher
    coefficient than the floor (moist skin, mu 0.8) keeps its own ratio."""
    for f0 in ((-0.175, 0.0, 0.35), (0.0, 0.28, 0.35), (0.1, -0.1, 1.2)):
        m = friction_model(f0=f0, d_t=-2.0)
        r = ContactRenderer(max_force_n=math.inf)
        t = settle(r, m)
        np.testing.assert_allclose(r.render(t, m.x0_m, m.v0_m_s), f0, atol=1e-12)


def test_friction_cone_bounds_what_k_implies():
    """A K with friction rows while f0 has none (issue 19: K carries friction, f0 does not): pressing deeper gives at
    most the cone's tangential force, never the K row's full extrapolation."""
    K = -1000.0 * np.outer(Z, Z) + np.array([[0.0, 0.0, 0.0], [0.0, 0.0, 0.0], [0.0, 0.0, 0.0]])
    K[0, 2] = 1000.0  # dF_x/dz: pushing down 1 mm asks for 1 N sideways (ratio ~1.4 at 0.35 + 1 N normal)
    m = LocalModel(1, 0, "tissue", (0, 0, -1e-3), (0, 0, 0), (0, 0, 0.35), K, np.zeros((3, 3)), Z, 1.0, 10.0)
    r = ContactRenderer(max_force_n=math.inf, max_stiffness_n_per_m=math.inf)
    t = settle(r, m)
    f = r.render(t, (0.0, 0.0, -2e-3))
    assert f[2] == pytest.approx(1.35)
    assert tangential(f) == pytest.approx(FRICTION_CONE_FLOOR * 1.35)


# --- the vector clamp ------------------------------------------------------------------------
def test_clamp_scales_the_vector_not_each_axis():
    f = np.array([3.0, -3.0, 3.0])
    c = clamp_vec(f, TOUCH_PEAK_FORCE_N)
    assert np.linalg.norm(c) == pytest.approx(TOUCH_PEAK_FORCE_N)
    np.testing.assert_allclose(c / np.linalg.norm(c), f / np.linalg.norm(f))  # direction kept


@pytest.mark.parametrize("seed", range(4))
def test_no_command_above_the_device_limit_in_any_direction(seed):
    """The whole chain, renderer (with the passivity controller) and the mapping to device axes with a force scale:
    the device command's magnitude never exceeds the limit, whatever the model."""
    rng = np.random.default_rng(seed)
    mapping = DeviceMapping(scale=1.0, axes="x-zy", force_scale=2.0, max_force_n=TOUCH_PEAK_FORCE_N)
    r = ContactRenderer(max_force_n=TOUCH_PEAK_FORCE_N / 2.0, passivity_mass_kg=0.045)
    for k in range(400):
        if k % 4 == 0:
            m = LocalModel(
                k + 1,
                0,
                "tissue",
                rng.normal(scale=1e-3, size=3),
                rng.normal(scale=0.1, size=3),
                rng.normal(scale=10.0, size=3),
                rng.normal(scale=1e5, size=(3, 3)),
                rng.normal(scale=1e4, size=(3, 3)),
                rng.normal(size=3),
                1.0,
                1.0,
            )
            r.set_model(m)
        f = r.render(k * DT, rng.normal(scale=2e-3, size=3), rng.normal(scale=0.2, size=3))
        cmd = np.array(mapping.force_to_device(tuple(f)))
        assert np.linalg.norm(cmd) <= TOUCH_PEAK_FORCE_N * (1 + 1e-12)


# --- the device clock ------------------------------------------------------------------------
def fade_run(stamps, ttl=0.02):
    r = ContactRenderer(max_force_n=math.inf)
    m = LocalModel(1, 0, "tissue", (0, 0, -1e-3), (0, 0, 0), (0, 0, 2.0), np.zeros((3, 3)), np.zeros((3, 3)), Z, 1.0, ttl)
    r.set_model(m, 0.0)
    return np.array([r.render(t, (0.0, 0.0, -1e-3))[2] for t in stamps]), r


def test_fade_runs_on_the_pose_stamps_a_burst_does_not_jump():
    """Poses queued and answered in a burst carry their own stamps: the fade is the same ramp as on time."""
    stamps = np.arange(0, 150) * DT
    f, _ = fade_run(stamps)
    steps = np.abs(np.diff(f[40:]))
    assert steps.max() <= 2.0 * DT / FADE_S + 1e-9
    assert f[-1] == 0.0


def test_a_late_device_tick_advances_the_fade_by_at_most_max_tick():
    stamps = list(np.arange(0, 40) * DT) + [0.039 + 0.008] + list(0.047 + np.arange(1, 100) * DT)  # an 8 ms gap at 47 ms
    f, r = fade_run(stamps)
    i = 40
    assert f[i - 1] > 0.0 and r.counts["fades_ttl"] == 1
    assert f[i - 1] - f[i] <= 2.0 * MAX_TICK_S / FADE_S + 1e-9  # 8 % of the force, not the 16 % of 8 ms
    assert np.abs(np.diff(f)).max() <= 2.0 * MAX_TICK_S / FADE_S + 1e-9


def test_stamps_going_back_do_not_turn_the_clock_back():
    stamps = list(np.arange(0, 30) * DT) + list(0.010 + np.arange(0, 100) * DT)  # a restarted driver's stamps
    f, r = fade_run(stamps)
    assert np.abs(np.diff(f[25:])).max() <= 2.0 * DT / FADE_S + 1e-9  # after the first model's crossfade in
    assert r.model_age_s() == pytest.approx(0.029 + 99 * DT)  # time went on from the new stamps
    assert f[-1] == 0.0 and r.counts["fades_ttl"] == 1


def test_ttl_counts_the_raw_stamps():
    """A device that paused for 100 ms resumes on a model 100 ms old: stale (TTL 50 ms), it fades."""
    r = ContactRenderer(max_force_n=math.inf)
    m = LocalModel(1, 0, "tissue", (0, 0, -1e-3), (0, 0, 0), (0, 0, 2.0), np.zeros((3, 3)), np.zeros((3, 3)), Z, 1.0, 0.05)
    r.set_model(m, 0.0)
    for i in range(30):
        r.render(i * DT, (0.0, 0.0, -1e-3))
    assert r.state == "model"
    f = r.render(0.029 + 0.1, (0.0, 0.0, -1e-3))
    assert r.state == "fade" and r.outside_reason == "ttl" and f[2] <= 2.0 + 1e-12
    assert f[2] >= 2.0 * (1 - MAX_TICK_S / FADE_S) - 1e-9  # and it starts a ramp, not a step


def test_a_model_without_a_time_is_booked_at_the_latest_device_tick():
    r = ContactRenderer(max_force_n=math.inf)
    m = friction_model(ttl=0.05, d_t=0.0)
    r.set_model(m)  # before any device tick: booked at the first one
    r.render(100.0, m.x0_m)
    assert r.model_age_s() == 0.0
    r.render(100.001, m.x0_m)
    assert r.model_age_s() == pytest.approx(0.001)
    r.set_model(friction_model(seq=2, ttl=0.05, d_t=0.0))
    assert r.model_age_s() == pytest.approx(0.0)


# --- the namespace option's helpers ----------------------------------------------------------
@pytest.mark.parametrize(
    ("given", "expected"), [("", ""), ("/", ""), ("skin1", "/skin1"), ("/skin1/", "/skin1"), (" a/b_2 ", "/a/b_2")]
)
def test_normalize_namespace(given, expected):
    assert normalize_namespace(given) == expected


@pytest.mark.parametrize("bad", ["1skin", "a//b", "a-b", "a b"])
def test_bad_namespace_is_a_one_line_error(bad):
    with pytest.raises(ValueError, match="is not a ROS name") as e:
        normalize_namespace(bad)
    assert "\n" not in str(e.value)


def test_namespace_remap_is_dropped_only_for_the_node_side():
    args = ["--ros-args", "-r", "__ns:=/x", "-p", "scale:=2.0", "--remap", "skin_sim_bridge:__ns:=/y", "-r", "a:=b"]
    assert without_namespace_remap(args) == ["--ros-args", "-p", "scale:=2.0", "-r", "a:=b"]
    assert without_namespace_remap([]) == []


# --- the device path's transports under LOCALHOST -----------------------------------------------
def test_localhost_device_path_goes_off_shared_memory():
    updates, why = localhost_udp_env({"ROS_AUTOMATIC_DISCOVERY_RANGE": "LOCALHOST"})
    assert updates == {
        "ROS_AUTOMATIC_DISCOVERY_RANGE": "SYSTEM_DEFAULT",
        "FASTRTPS_DEFAULT_PROFILES_FILE": str(UDP_LOOPBACK_PROFILE),
    }
    assert "no shared memory" in why


@pytest.mark.parametrize(
    ("env", "keep", "reason"),
    [
        ({"ROS_AUTOMATIC_DISCOVERY_RANGE": "SUBNET"}, False, "SUBNET"),
        ({}, False, "unset"),
        ({"ROS_AUTOMATIC_DISCOVERY_RANGE": "LOCALHOST"}, True, "asked for"),
        ({"ROS_AUTOMATIC_DISCOVERY_RANGE": "LOCALHOST", "FASTRTPS_DEFAULT_PROFILES_FILE": "/x.xml"}, False, "user's"),
        ({"ROS_AUTOMATIC_DISCOVERY_RANGE": "LOCALHOST", "ROS_STATIC_PEERS": "10.0.0.2"}, False, "STATIC_PEERS"),
        ({"ROS_AUTOMATIC_DISCOVERY_RANGE": "LOCALHOST", "RMW_IMPLEMENTATION": "rmw_cyclonedds_cpp"}, False, "cyclone"),
    ],
)
def test_the_users_transport_choices_are_kept(env, keep, reason):
    updates, why = localhost_udp_env(env, keep_shm=keep)
    assert updates == {} and reason in why and "\n" not in why


def test_the_profile_keeps_discovery_on_this_host_without_multicast():
    """SYSTEM_DEFAULT hands the transports to the profile: it must leave no route to multicast discovery."""
    import xml.etree.ElementTree as ET

    ns = {"p": "http://www.eprosima.com/XMLSchemas/fastRTPS_Profiles"}
    root = ET.parse(UDP_LOOPBACK_PROFILE).getroot()
    part = root.find("p:participant", ns)
    assert part.get("is_default_profile") == "true"
    rtps = part.find("p:rtps", ns)
    assert rtps.find("p:useBuiltinTransports", ns).text == "false"
    assert rtps.find("p:builtin/p:metatrafficMulticastLocatorList", ns) is None
    assert rtps.find("p:builtin/p:metatrafficUnicastLocatorList/p:locator/p:udpv4", ns) is not None  # no default multicast
    peers = [a.text for a in rtps.findall("p:builtin/p:initialPeersList/p:locator/p:udpv4/p:address", ns)]
    assert peers == ["127.0.0.1"]
    kinds = [t.find("p:type", ns).text for t in root.findall("p:transport_descriptors/p:transport_descriptor", ns)]
    assert kinds == ["UDPv4"]


def test_the_passivity_controller_ticks_on_the_servo_period_not_on_stamp_jitter():
    """bench-device, 2026-12-06: the emulated driver, a whole period late once, published its next pose 0.144 ms
    after (stamps are publish times) while the pose had moved a whole period's 13 um. The passivity controller took
    dx / 0.144 ms as the velocity and mass / 0.144 ms as its bound, and its damping commanded the device's 3.3 N for
    one tick against a true 0.91 N. Its tick is the servo period: the damping it may add stays what a 1 ms tick
    allows."""
    mass = 0.045
    speed = 13e-3  # m/s along -x: the drag's speed there

    def run(stamps):
        r = ContactRenderer(max_force_n=TOUCH_PEAK_FORCE_N, passivity_mass_kg=mass)
        # an environment that pushes the stylus along its motion (-x): it feeds energy, so the controller acts
        f0 = (-0.5, 0.0, 0.9)
        m = LocalModel(1, 0, "tissue", (0.0, 0.0, -1e-3), np.zeros(3), f0, np.zeros((3, 3)), np.zeros((3, 3)), Z, 1.0, 10.0)
        r.set_model(m, 0.0)
        damping = []  # what the controller added to the rendered force, each tick
        for k, t in enumerate(stamps):
            x = (-speed * k * 1e-3, 0.0, -1e-3)  # the pose of slot k: its position at the slot's deadline
            damping.append(np.linalg.norm(r.render(t, x) - r._last_out))
        return np.array(damping), r

    regular = np.arange(40) * 1e-3
    jittered = regular.copy()
    jittered[30] += 0.921e-3  # a late slot...
    jittered[31] = jittered[30] + 0.144e-3  # ...and the next one published right after it
    d_reg, r_reg = run(regular)
    d_jit, _ = run(jittered)
    assert r_reg.passivity.active_ticks > 0 and d_reg.max() > 0.0  # the controller is acting in this scene
    bound = mass / (PASSIVITY_DELAY_TICKS + 1) / SERVO_PERIOD_S * speed  # its damping at most m/T times the speed
    assert d_reg.max() <= bound * (1 + 1e-9)
    assert d_jit.max() <= bound * (1 + 1e-9), d_jit[28:34]
