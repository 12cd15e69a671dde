"""Pure tests of the servo-rate contact renderer (issue 12): crossfade, TTL fade, radius exit,
one-sidedness, clamps, bad models. No ROS."""

import math
import subprocess
import sys

import numpy as np
import pytest

from msgs_schema.contact_model import LocalModel
from skin_sim_node.device.render import FADE_S, ContactRenderer, HoldLastRenderer

Z = np.array([0.0, 0.0, 1.0])
DT = 1e-3


def model(seq, f0=(0.0, 0.0, 1.0), x0=(0.0, 0.0, -1e-3), k=500.0, K=None, ttl=0.05, radius=2e-3, normal=Z):
    K = -k * np.outer(Z, Z) if K is None else K
    return LocalModel(seq, 0, "tissue", x0, (0, 0, 0), f0, K, np.zeros((3, 3)), normal, radius, ttl)


def run(r, xs, models, t0=0.0):
    """Render at 1 kHz at positions ``xs``; ``models``: {tick: LocalModel} delivered before that tick."""
    out = []
    for i, x in enumerate(xs):
        t = t0 + i * DT
        if i in models:
            r.set_model(models[i], t)
        out.append(r.render(t, x))
    return np.array(out)


def uncapped(**kw):
    return ContactRenderer(max_force_n=math.inf, max_stiffness_n_per_m=math.inf, **kw)


def test_pure_import():
    code = "import sys; import skin_sim_node.device.render, msgs_schema.contact_model; print('rclpy' in sys.modules)"
    assert subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True).stdout.strip() == "False"


def test_linear_model_between_updates():
    r = uncapped()
    x0 = np.array([0.0, 0.0, -1e-3])
    r.set_model(model(1, x0=x0), 0.0)
    f = [r.render(0.030 + i * DT, x0 + [0, 0, -i * 1e-5]) for i in range(5)]  # after the first crossfade
    for i, fi in enumerate(f):
        assert fi == pytest.approx([0, 0, 1.0 + 500.0 * i * 1e-5], abs=1e-12)


def test_first_model_fades_in_and_later_models_switch_within_one_tick():
    r = uncapped()
    x = np.zeros((200, 3)) + [0, 0, -1e-3]
    models = {i: model(s, f0=(0, 0, f), ttl=1.0) for i, s, f in ((0, 1, 1.0), (100, 2, 2.0), (104, 3, 1.2))}
    f = run(r, x, models)[:, 2]
    steps = np.abs(np.diff(f))
    # first model fades in from zero over CROSSFADE_MAX (20 ms): <= 1 N / 20 per tick
    assert steps[:40].max() <= 1.0 / 20 + 1e-9
    assert f[99] == pytest.approx(1.0, abs=1e-12)
    # model to model: within CROSSFADE_MIN (one 1 ms tick), no lag behind the newest model
    assert f[100] == pytest.approx(2.0, abs=1e-12) and f[104] == pytest.approx(1.2, abs=1e-12)
    assert f[-1] == pytest.approx(1.2, abs=1e-12)


def test_ttl_fade_never_steps_and_ends_at_zero():
    r = uncapped()
    x = np.zeros((200, 3)) + [0, 0, -1e-3]
    f = run(r, x, {0: model(1, f0=(0, 0, 2.0), ttl=0.05)})[:, 2]
    assert f[50] == pytest.approx(2.0)  # still fresh at 50 ms: age <= ttl
    fading = f[50 : 52 + round(FADE_S / DT)]
    assert np.all(np.diff(fading) <= 1e-12)
    assert np.abs(np.diff(f[20:])).max() <= 2.0 * DT / FADE_S + 1e-9  # <= 2 N / 50 ticks per tick
    assert f[51 + round(FADE_S / DT)] == pytest.approx(0.0, abs=1e-12)
    assert f[50 + round(FADE_S / DT)] > 0.0
    assert np.all(f[110:] == 0.0)
    assert r.counts["fades_ttl"] == 1 and r.state == "fade"


def test_radius_exit_fades_and_return_blends_back():
    r = uncapped()
    xs = [np.array([0.0, 0.0, -1e-3])] * 30 + [np.array([3e-3, 0.0, -1e-3])] * 30 + [np.array([0.0, 0.0, -1e-3])] * 60
    f = run(r, xs, {0: model(1, f0=(0, 0, 1.5), radius=2e-3, ttl=10.0)})[:, 2]
    assert r.counts["fades_radius"] == 1
    assert f[29] == pytest.approx(1.5) and f[59] < 1.5 * (1 - 29 * DT / FADE_S) + 1e-9
    assert np.abs(np.diff(f)).max() <= 1.5 / 20 + 1e-9  # fade: 1.5 N / 50 ticks; the way back: over >= 1 ms from ~0.6 N
    assert f[-1] == pytest.approx(1.5)


def test_one_sided_along_the_normal_and_no_tangential_step_at_separation():
    K = -np.array([[0, 0, 0], [0, 0, 0], [0, 0, 1000.0]]) + np.array([[-200.0, 0, 0], [0, 0, 0], [0, 0, 0]])
    m = model(1, f0=(0.3, 0.0, 1.0), x0=(0, 0, -1e-3), K=K, ttl=10.0)
    r = uncapped()
    r.set_model(m, 0.0)
    zs = np.linspace(-1.5e-3, 0.5e-3, 401)  # from deeper than x0 to 0.5 mm above the separation point
    f = np.array([r.render(1.0 + i * DT, (0.0, 0.0, z)) for i, z in enumerate(zs)])
    assert np.all(f[:, 2] >= 0.0)
    assert np.all(f[zs >= 0.0] == 0.0)  # above where f0 + K dx reaches zero: nothing, not a pull
    # tangential part shrinks with the normal force: continuous through separation
    assert np.abs(np.diff(f[:, 0])).max() < 0.3 * (zs[1] - zs[0]) / 1e-3 * 1.01


@pytest.mark.parametrize("seed", range(5))
def test_random_models_respect_clamps_and_normal(seed):
    rng = np.random.default_rng(seed)
    r = ContactRenderer(max_force_n=3.3, max_stiffness_n_per_m=1020.0)
    K = rng.normal(scale=5e4, size=(3, 3))
    m = model(1, f0=rng.normal(scale=5, size=3), K=K, ttl=10.0, radius=1.0)
    r.set_model(m, 0.0)
    assert np.linalg.norm(r._model.K, 2) == pytest.approx(1020.0)
    for i in range(300):
        f = r.render(0.03 + i * DT, rng.normal(scale=3e-3, size=3))
        assert np.linalg.norm(f) <= 3.3 + 1e-12
        assert f @ Z >= -1e-12


def test_bad_models_and_inputs():
    r = uncapped()
    assert r.set_model(model(1, f0=(0, 0, math.nan)), 0.0) == "non-finite model"
    assert r.set_model(model(5), 0.0) is None
    assert "not after" in r.set_model(model(4), 0.01)  # late / duplicate
    assert r.set_model(model(0), 0.2) is None  # the old one expired: a restarted node (sequence from 0) is followed
    f = r.render(0.3, (math.nan, 0, 0))
    assert np.isfinite(f).all()
    assert r.counts == {"models": 2, "rejected_non_finite": 1, "rejected_out_of_order": 1, "fades_ttl": 0, "fades_radius": 0}


def test_passivity_controller_dissipates_an_active_model():
    """A model with negative damping (D > 0 along the motion) feeds energy; the controller bounds it."""
    D = 2.0 * np.eye(3)  # F = D v: pushes along the velocity, an active element
    m = LocalModel(1, 0, "tissue", (0, 0, 0), (0, 0, 0), (0, 0, 1.0), np.zeros((3, 3)), D, Z, 1.0, 10.0)
    energies = {}
    for mass in (None, 0.045):
        r = uncapped(passivity_mass_kg=mass)
        r.set_model(m, 0.0)
        work = 0.0
        prev_f, prev_x = np.zeros(3), np.zeros(3)
        for i in range(1, 400):
            t = 0.03 + i * DT
            x = np.array([0.01 * math.sin(2 * math.pi * 2 * t), 0.0, 0.0])
            v = np.array([0.01 * 2 * math.pi * 2 * math.cos(2 * math.pi * 2 * t), 0.0, 0.0])
            work += float(prev_f @ (x - prev_x))
            prev_f, prev_x = r.render(t, x, v), x
        energies[mass] = work  # energy put into the tool by the rendered force
    assert energies[None] > 1e-4
    assert energies[0.045] < 0.2 * energies[None]


def test_hold_last_baseline():
    h = HoldLastRenderer()
    h.set_model(model(1, f0=(0, 0, 1.0)), 0.0)
    assert h.render(0.01, (0, 0, -5e-3))[2] == 1.0
    assert h.render(0.06, (0, 0, -5e-3))[2] == 0.0


def test_passivity_damping_fades_with_the_model():
    """After a stale model's fade the device gets exactly zero, even while the stylus moves with an energy debt."""
    D = 2.0 * np.eye(3)  # an active model: the controller has work to do
    m = LocalModel(1, 0, "tissue", (0, 0, 0), (0, 0, 0), (0, 0, 1.0), np.zeros((3, 3)), D, Z, 1.0, 0.1)
    r = uncapped(passivity_mass_kg=0.045)
    r.set_model(m, 0.0)
    out, active = [], 0
    for i in range(1, 400):
        t = i * DT
        x = np.array([0.01 * math.sin(2 * math.pi * 3 * t), 0.0, 0.0])
        v = np.array([0.01 * 2 * math.pi * 3 * math.cos(2 * math.pi * 3 * t), 0.0, 0.0])
        out.append(np.linalg.norm(r.render(t, x, v)))
        active = max(active, r.passivity.active_ticks)
    out = np.array(out)
    assert active > 0
    assert np.all(out[round((0.1 + FADE_S) / DT) + 1 :] == 0.0)  # TTL 100 ms + fade 50 ms: nothing after


def test_a_stall_fades_out_and_back_in_over_the_longest_crossfade():
    """Issue 31: the node's stale zero model (its watchdog fired) and the first model after the stall are each blended
    over the longest crossfade, not one tick: the hand feels a fade out and a fade back in, never a step."""
    from msgs_schema.contact_model import STALE_RADIUS_M
    from skin_sim_node.device.render import CROSSFADE_MAX_S

    r = ContactRenderer()
    stale = LocalModel(3, 0, "tissue", (0.0, 0.0, -1e-3), (0, 0, 0), (0, 0, 0), np.zeros((3, 3)), np.zeros((3, 3)), Z,
                       STALE_RADIUS_M, 10.0)  # fmt: skip
    x = (0.0, 0.0, -1e-3)
    models = {0: model(1, ttl=10.0), 10: model(2, ttl=10.0), 100: stale, 300: model(4, ttl=10.0)}  # f0 1 N, held
    f = run(r, [x] * 400, models)[:, 2]
    assert f[99] == pytest.approx(1.0)
    steps = np.abs(np.diff(f[99:]))
    assert steps.max() <= 1.0 * DT / CROSSFADE_MAX_S + 1e-9  # out and back in, at most one blend's slope per tick
    assert f[100 + int(CROSSFADE_MAX_S / DT) + 1] == 0.0 and f[399] == pytest.approx(1.0)
