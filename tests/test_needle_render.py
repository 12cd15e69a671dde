"""The needle law at the device (issue 22, "At the device"): skin_sim_node/device/render.py's NeedleRender inside the
renderer's safety chain, and the offline insertion of skin_sim_lab/perf/needle_device.py (no scheduler, no clock)."""

from __future__ import annotations

import math

import numpy as np
import pytest

from msgs_schema.contact_model import LocalModel, NeedleLaw
from skin_sim_lab.perf import needle_device as nd
from skin_sim_node.cli import COMMANDS
from skin_sim_node.device.render import ContactRenderer, NeedleRender

U = (0.0, 0.0, -1.0)


def law(**kw) -> NeedleLaw:
    base = dict(
        axial_force_n=0.5,
        axial_gradient_n_per_m=400.0,
        rupture_distance_m=0.2e-3,
        post_rupture_force_n=0.1,
        post_rupture_gradient_n_per_m=0.0,
        friction_capacity_n=0.0,
        friction_capacity_gradient_n_per_m=0.0,
        friction_state=0.0,
        dahl_length_m=1e-3,
    )
    return NeedleLaw(U, **{**base, **kw})


def model(seq: int, nl: NeedleLaw, x0=(0.0, 0.0, -1e-3)) -> LocalModel:
    u = np.asarray(nl.axis)
    f0 = -u * nl.resistance_n
    return LocalModel(
        seq, 0, "tissue", np.asarray(x0), np.zeros(3), f0, -nl.axial_gradient_n_per_m * np.outer(u, u), np.zeros((3, 3)),
        np.array([0.0, 0.0, 1.0]), needle=nl,
    )  # fmt: skip


def plain_renderer(**kw) -> ContactRenderer:
    """No crossfade from zero to wait through: the first model is rendered from the first tick (cf 1 ms)."""
    return ContactRenderer(**{"crossfade_max_s": 1e-3, "max_force_n": 100.0, **kw})


def axial(f) -> float:
    """The axial resistance of a force on the tool, ``R = -u . F`` (N, > 0 resists insertion)."""
    return -float(np.asarray(U) @ f)


def at(z_below_x0: float, x0=(0.0, 0.0, -1e-3)) -> np.ndarray:
    return np.asarray(x0) + np.array([0.0, 0.0, -z_below_x0])


def test_f0_at_x0_and_the_law_along_the_axis():
    nl = law()
    r = NeedleRender(nl, max_k=math.inf, radius_m=2e-3)
    m = model(1, nl)
    K = m.stiffness_n_per_m
    assert r.force(m, K, m.damping_n_s_per_m, m.x0_m, None) == pytest.approx(m.f0_n)
    f = r.force(m, K, m.damping_n_s_per_m, at(0.1e-3), None)
    assert axial(f) == pytest.approx(nl.axial_force_n + nl.axial_gradient_n_per_m * 0.1e-3)  # R_e before the rupture
    # sideways off the track: K's axial part is not rendered twice (the law gives the axial force)
    f_side = r.force(m, K, m.damping_n_s_per_m, at(0.1e-3) + np.array([0.1e-3, 0.0, 0.0]), None)
    assert f_side == pytest.approx(f)


def test_the_rupture_latches_and_nothing_toggles_at_the_threshold():
    """Dithering across the rupture distance: one drop, then the post-rupture line whichever side the tool is; a new
    model starts unlatched."""
    nl = law()
    r = plain_renderer(max_stiffness_n_per_m=math.inf)
    r.set_model(model(1, nl), 0.0)
    d = nl.rupture_distance_m
    zs = [0.0, 0.5 * d, 0.999 * d, 1.001 * d, 0.999 * d, 1.001 * d, 0.9 * d]
    out = [axial(r.render(1e-3 * (k + 1), at(z))) for k, z in enumerate(zs)]
    peak = nl.axial_force_n + nl.axial_gradient_n_per_m * 0.999 * d
    assert out[2] == pytest.approx(peak)
    assert all(o <= nl.post_rupture_force_n + 1e-12 for o in out[3:])  # latched: never back up to the peak
    drops = sum(1 for a, b in zip(out, out[1:]) if a - b > 0.5 * (peak - nl.post_rupture_force_n))
    assert drops == 1
    assert r.needle is not None and r.needle.latched
    r.set_model(model(2, nl), 1e-2)
    assert r.needle is not None and not r.needle.latched


def test_dahl_starts_from_the_models_state_and_is_dissipative_over_a_cycle():
    """z starts at friction_state at x0 and follows the device's own axial moves (|z| <= 1); the friction over a
    closed back-and-forth absorbs energy (hysteresis), and on retraction it pulls the tool in: not erased."""
    nl = law(axial_force_n=0.0, axial_gradient_n_per_m=0.0, rupture_distance_m=0.0, friction_capacity_n=0.4, friction_state=0.3)
    r = NeedleRender(nl, max_k=math.inf, radius_m=2e-3)
    assert r.resistance(0.0) == pytest.approx(0.4 * 0.3)
    s = np.concatenate([np.linspace(0, 1e-3, 101), np.linspace(1e-3, -1e-3, 201)[1:], np.linspace(-1e-3, 0, 101)[1:]])
    R = np.array([r.resistance(float(v)) for v in s])
    assert abs(r.z) <= 1.0
    assert R[100] > 0 and R[-101] < 0  # resists insertion going in, resists withdrawal coming out
    work_absorbed = float(np.sum(0.5 * (R[1:] + R[:-1]) * np.diff(s)))
    assert work_absorbed > 0.0
    # inside the renderer, with the passivity controller on: retraction friction still pulls along -normal
    rr = plain_renderer(passivity_mass_kg=0.045, max_stiffness_n_per_m=math.inf)
    rr.set_model(model(1, law(axial_force_n=0.0, axial_gradient_n_per_m=0.0, rupture_distance_m=0.0,
                              friction_capacity_n=0.4, friction_state=1.0, dahl_length_m=1e-4)), 0.0)  # fmt: skip
    fz = [rr.render(1e-3 * (k + 1), at(-1e-5 * k))[2] for k in range(40)]  # withdrawing 10 um a tick, within the TTL
    assert fz[-1] < -0.3  # the shaft friction holds the needle in


def test_the_k_cap_bounds_the_axial_slopes_and_the_dahl_stick_stiffness():
    nl = law(axial_gradient_n_per_m=5000.0, post_rupture_gradient_n_per_m=-8000.0, friction_capacity_n=2.0, dahl_length_m=1e-4)
    r = NeedleRender(nl, max_k=1000.0, radius_m=2e-3)
    assert abs(r.grad) <= 1000.0 and abs(r.post_grad) <= 1000.0
    assert 2.0 * 2.0 / r.dahl_length_m <= 1000.0 + 1e-9  # reversal slope 2 F_c / x_0 within the cap
    # the threshold stays where the law puts it
    assert r.resistance(0.99 * nl.rupture_distance_m) > r.resistance(1.01 * nl.rupture_distance_m)


def test_the_magnitude_limit_is_last_and_a_stale_needle_model_fades():
    nl = law(axial_force_n=3.0, axial_gradient_n_per_m=0.0)
    r = plain_renderer(max_force_n=2.0)
    r.set_model(model(1, nl), 0.0)
    f = r.render(1e-3, at(0.0))
    assert float(np.linalg.norm(f)) == pytest.approx(2.0)
    assert r.counts_clamped >= 1
    out = [float(np.linalg.norm(r.render(1e-3 * k, at(0.0)))) for k in range(2, 130)]
    assert out[-1] == 0.0 and max(abs(a - b) for a, b in zip(out, out[1:])) <= 2.0 * 1e-3 / r.fade_s + 1e-9  # a ramp


@pytest.fixture(scope="module")
def runs():
    return {g: nd.insertion(g) for g in nd.GAUGES}


def test_offline_the_drop_lands_on_the_truths_tick_and_hold_last_is_later(runs):
    for r in runs.values():
        drops = [e for e in r["events"] if e["drop_n"] >= 0.1 * r["peak_n"]]
        assert drops  # the skin's puncture is a drop
        for e in r["events"]:
            assert e["latch"] is not None and abs(e["latch"] - e["tick"]) <= 1
        for e in drops:
            assert e["render"] is not None and abs(e["render"] - e["tick"]) <= 1
            assert e["hold"] is not None and e["hold"] > e["render"]  # hold-last waits for the next model


def test_offline_the_cycle_is_passive_and_no_command_overshoots_while_inserting(runs):
    for r in runs.values():
        assert r["absorbed_j"] > 0.0  # the observer's energy: the environment absorbed (generated < 0)
        assert r["render_over_in"] == 0
        assert r["render_p99_pct"] < r["hold_p99_pct"]
        assert r["rendered_peak_n"] <= nd.OVER_RATIO * r["peak_n"] + nd.OVER_N


def test_offline_force_scale_scales_the_vector_before_the_clamp():
    """18 G at sawSensablePhantom's 2 N: the clamp's tissue value is 2 N / scale, so a scale under 2 / peak clamps
    nothing and the drop keeps its shape in proportion."""
    full = nd.insertion(18, max_force_n=nd.SAW_MAX_FORCE_N, force_scale=1.0, renderer_kw={"max_stiffness_n_per_m": math.inf})
    assert full["clamped_ticks"] > 0 and full["rendered_peak_n"] == pytest.approx(nd.SAW_MAX_FORCE_N)
    k = 0.6
    scaled = nd.insertion(18, max_force_n=nd.SAW_MAX_FORCE_N, force_scale=k, renderer_kw={"max_stiffness_n_per_m": math.inf})
    assert scaled["clamped_ticks"] == 0 and k * scaled["rendered_peak_n"] < nd.SAW_MAX_FORCE_N


def test_the_cli_registers_needle_device():
    assert COMMANDS["needle-device"][0] == "skin_sim_lab.perf.needle_device"
