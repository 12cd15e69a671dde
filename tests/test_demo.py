"""The demo's summary helpers (pure: no processes)."""

from skin_sim_node.demo import force_at_deepest, model_at, offline_check

MS = 1_000_000


def test_force_at_deepest_takes_the_wrench_that_answers_the_deepest_pose():
    poses = [(k * MS, 0.0, 0.0, -2e-3 * min(k, 10 - k) / 5) for k in range(11)]  # down to 2 mm at k = 5, back up
    wrenches = [(k * MS + MS // 4, k * MS, 0.1 * min(k, 10 - k)) for k in range(11)]  # each 0.25 ms after its pose
    depth_m, force_n = force_at_deepest(poses, wrenches, window_ns=MS)
    assert abs(depth_m - 2e-3) < 1e-15 and force_n == max(w[2] for w in wrenches) == 0.1 * 5


def test_force_at_deepest_without_data_is_none():
    assert force_at_deepest([], [(0, 0, 1.0)]) is None
    assert force_at_deepest([(0, 0.0, 0.0, -1e-3)], [(10**9, 0, 1.0)]) is None  # no wrench near the deepest instant


def _records(bag):
    from skin_sim_node.bags.io import iter_raw, open_bag, topic_types

    keys = {"/tool/pose": "tool_pose", "/tool/twist": "tool_twist", "/tool/wrench": "tool_wrench"}
    with open_bag(bag) as r:
        return [(t, keys[topic], raw) for topic, _, t, raw in iter_raw(bag, r, [k for k in topic_types(r) if k in keys])]


def _args(tmp_path):
    import types

    return types.SimpleNamespace(out=tmp_path / "demo", source="mock", path="press_hold_release")


def test_offline_check_passes_forces_that_are_the_offline_answer_and_draws_the_deepest_instant(tmp_path):
    from test_verdicts import _with_recorded_wrenches

    bag, _ = _with_recorded_wrenches(tmp_path, keep_every=2)
    checks = offline_check(_records(bag), _args(tmp_path), {})
    assert [ok for ok, _ in checks] == [True, True], checks
    assert (tmp_path / "demo" / "deformation_deepest.png").stat().st_size > 10_000
    assert (tmp_path / "demo" / "bag" / "metadata.yaml").exists()


def test_offline_check_fails_a_published_force_that_is_not_the_offline_answer(tmp_path):
    from test_verdicts import _with_recorded_wrenches

    bag, _ = _with_recorded_wrenches(tmp_path, bump_n=4.5)
    checks = offline_check(_records(bag), _args(tmp_path), {})
    assert not checks[0][0] and "DISAGREE" in checks[0][1] and "4.5 N" in checks[0][1], checks


def test_the_picture_state_is_the_deepest_instant():
    """The model drawn is the state at the deepest pose's stamp: its surface under the tool is at the tool's depth
    (the old picture took a display grid received near that time and showed undeformed tissue)."""
    from pathlib import Path

    import numpy as np

    from skin_sim_node.bags.inputs import InputOptions, read_inputs
    from skin_sim_node.bags.offline import replay
    from skin_sim_node.scenes import DEFAULT_PARAMS

    inputs = read_inputs(Path(__file__).parent / "data" / "press_hold_release" / "input", InputOptions())
    res = replay(inputs, DEFAULT_PARAMS, None, 0.0)
    k = int(np.argmin(res.tool_xyz_m[:, 2]))
    model, (x, y, z), n_aff = model_at(inputs, DEFAULT_PARAMS, int(res.stamps_ns[k]))
    assert (x, y, z) == tuple(res.tool_xyz_m[k]) and n_aff >= 1
    surface = model.cross_section(np.array([x]), y)[0][0]
    assert abs(surface - z) < 0.1 * abs(z), (surface, z)
    assert model.build_grid().heights_m[0].min() < 0.5 * z


def test_layers_reached_come_from_the_depth_not_the_chain(default_cfg):
    """A 20 um touch reaches the epidermis only; the dermis from its rest top (75 um), the fat from 1.275 mm."""
    from skin_sim_node.demo import layers_reached

    assert layers_reached(0.0, default_cfg) == [] and layers_reached(-1e-3, default_cfg) == []
    assert layers_reached(20e-6, default_cfg) == ["epidermis"]
    assert layers_reached(0.5e-3, default_cfg) == ["epidermis", "dermis"]
    assert layers_reached(2.6e-3, default_cfg) == ["epidermis", "dermis", "fat"]


def test_rate_check_holds_within_its_tolerance_and_names_the_reason():
    from skin_sim_node.demo import RATE_TOLERANCE, rate_check, rate_reasons

    assert RATE_TOLERANCE == 0.05
    assert rate_check("node ticks", 960.0) == (True, "node ticks 960/s of 1000/s (tolerance 5 %)")
    assert rate_check("node ticks", 949.0)[0] is False and rate_check("device forces", 273.0)[0] is False
    assert rate_check("node ticks", float("nan"))[0] is False  # nothing measured is not held
    why = rate_reasons(4, overruns=12)
    assert why.startswith("CPU: load average ") and "4 processes of this scene" in why and "woke late 12 times" in why
    assert "priorities: SCHED_FIFO allowed here" in why or "SCHED_FIFO not allowed" in why
    assert rate_check("node ticks", 243.0, target_hz=250.0)[0]  # the node answers at the server rate it announces


def test_picture_interfaces_never_above_the_deformed_layer_above():
    """Issue 29 item 7: each interface is drawn clipped to the deformed layer above it and the stack's bottom."""
    import numpy as np

    from skin_sim_node.bags.plots import clipped_layer_tops

    surface = np.array([-2.6e-3, -1.0e-3, 0.0])
    dermis_top = np.array([-2.0e-3, -1.1e-3, -75e-6])  # above the surface under the punch: a negative epidermis
    fat_top = np.array([-1.9e-3, -1.3e-3, -6e-3])  # above the dermis top, and below the 5.275 mm bottom
    tops = clipped_layer_tops(np.array([surface, dermis_top, fat_top]), -5.275e-3)
    assert np.array_equal(tops[0], surface)
    assert np.array_equal(tops[1], [-2.6e-3, -1.1e-3, -75e-6])
    assert np.array_equal(tops[2], [-2.6e-3, -1.3e-3, -5.275e-3])
    assert np.all(np.diff(tops, axis=0) <= 0)


def test_drawn_cross_section_keeps_every_interface_below_the_surface(tmp_path):
    """The drawn lines of the demo's cross-section at the deepest instant of a recorded press: each interface at or
    below the line above it (the picture showed the dermis/fat boundary above the surface under the punch)."""
    from pathlib import Path

    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    import numpy as np

    from skin_sim_node.bags.inputs import InputOptions, read_inputs
    from skin_sim_node.bags.offline import replay
    from skin_sim_node.bags.plots import draw_cross_section
    from skin_sim_node.scenes import DEFAULT_PARAMS

    inputs = read_inputs(Path(__file__).parent / "data" / "press_hold_release" / "input", InputOptions())
    res = replay(inputs, DEFAULT_PARAMS, None, 0.0)
    k = int(np.argmin(res.tool_xyz_m[:, 2]))
    model, (x, y, z), _ = model_at(inputs, DEFAULT_PARAMS, int(res.stamps_ns[k]))
    fig, ax = plt.subplots()
    draw_cross_section(ax, model, x, y, z, "t")
    lines = [ln.get_ydata() for ln in ax.lines[: len(model.cfg.layers)]]
    plt.close(fig)
    assert len(lines) == 3 and all(np.all(lo <= hi) for hi, lo in zip(lines, lines[1:], strict=False))
