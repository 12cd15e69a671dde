"""Rosbag record/replay: storage round trips, offline determinism, golden regression, foreign and bad bags, live replay."""

from __future__ import annotations

import json
import math
import shutil
from pathlib import Path

import numpy as np
import pytest
import yaml

from msgs_schema import convert as cv
from msgs_schema.topics import TOPICS
from skin_sim_node.bags import compare, live, published, replay
from skin_sim_node.bags.golden import GRID_RATE_HZ, SCENE_PARAMS, SCENES, write_trajectory_bag
from skin_sim_node.bags.inputs import InputOptions, read_inputs
from skin_sim_node.bags.io import (
    BagNotFoundError,
    BagWriter,
    NoPoseTopicError,
    TruncatedBagError,
    UnknownMessageTypeError,
    deserialize,
    iter_raw,
    new_message,
    open_bag,
    qos_profiles,
)
from skin_sim_node.bags.offline import bag_topic, replay_to_bag
from skin_sim_node.bags.offline import replay as replay_offline
from skin_sim_node.device.mapping import DeviceMapping
from skin_sim_node.scenes import DEFAULT_PARAMS

DATA = Path(__file__).parent / "data"
PRESS = DATA / "press_hold_release" / "input"
T0 = 1_700_000_000 * 1_000_000_000


def raw_messages(bag, topic):
    with open_bag(bag) as r:
        return [(t, raw) for _, _, t, raw in iter_raw(bag, r, [topic])]


# --- storage -----------------------------------------------------------------------------
@pytest.mark.parametrize("storage", ["mcap", "sqlite3"])
def test_round_trip_both_storages(tmp_path, storage):
    bag = tmp_path / "rt"
    pose, wrench, image = (new_message(TOPICS[k].type) for k in ("tool_pose", "tool_wrench", "layer_heights"))
    grid = np.arange(4 * 5 * 3, dtype=np.float32).reshape(4, 5, 3) * 1e-4
    written = []
    with BagWriter(bag, storage) as w:
        for k in range(20):
            t = T0 + k * 1_000_000
            msg = cv.fill_pose(pose, t, "tissue", (k * 1e-3, 0.0, -1e-4 * k))
            written.append(w.write("/tool/pose", TOPICS["tool_pose"].type, t, msg, qos_profiles("tool_pose")))
            w.write("/tool/wrench", TOPICS["tool_wrench"].type, t, cv.fill_wrench(wrench, t, "tissue", (0.0, 0.0, 0.1 * k)))
        img = cv.fill_image(image, T0, "tissue", grid)
        img.data = np.frombuffer(img.data, dtype=np.uint8)
        w.write("/tissue/layer_heights", TOPICS["layer_heights"].type, T0, img)
    back = raw_messages(bag, "/tool/pose")
    assert [raw for _, raw in back] == written
    assert [t for t, _ in back] == [T0 + k * 1_000_000 for k in range(20)]
    p = [cv.read_pose(deserialize(raw, TOPICS["tool_pose"].type)) for _, raw in back]
    assert p[7] == (T0 + 7_000_000, "tissue", (7e-3, 0.0, -7e-4))
    forces = [cv.read_wrench(deserialize(raw, TOPICS["tool_wrench"].type))[2][2] for _, raw in raw_messages(bag, "/tool/wrench")]
    assert forces == pytest.approx([0.1 * k for k in range(20)], abs=0)
    ((_, raw),) = raw_messages(bag, "/tissue/layer_heights")
    assert np.array_equal(cv.read_image(deserialize(raw, TOPICS["layer_heights"].type)), grid.astype(np.float64))
    # metadata.yaml with every field `ros2 bag info` (rosbag2_storage's YAML decoder) reads
    meta = yaml.safe_load((bag / "metadata.yaml").read_text())["rosbag2_bagfile_information"]
    assert meta["version"] == 9 and meta["storage_identifier"] == storage
    assert meta["message_count"] == 41 and meta["duration"]["nanoseconds"] == 19_000_000
    assert meta["starting_time"]["nanoseconds_since_epoch"] == T0
    for f in meta["relative_file_paths"]:
        assert (bag / f).exists()
    assert meta["files"][0]["message_count"] == 41 and isinstance(meta["custom_data"], dict)
    assert isinstance(meta["ros_distro"], str) and meta["compression_mode"] == "" and meta["compression_format"] == ""
    topics = {t["topic_metadata"]["name"]: t for t in meta["topics_with_message_count"]}
    assert topics["/tool/pose"]["message_count"] == 20
    tm = topics["/tool/pose"]["topic_metadata"]
    assert tm["type"] == "geometry_msgs/msg/PoseStamped" and tm["serialization_format"] == "cdr"
    assert tm["type_description_hash"].startswith("RIHS01_")
    assert tm["offered_qos_profiles"][0]["reliability"] == "best_effort" and tm["offered_qos_profiles"][0]["depth"] == 1


def test_bag_qos_matches_contract_profiles():
    pytest.importorskip("rclpy")
    from msgs_schema.qos import qos_for

    for key in ("tool_pose", "tool_wrench", "layer_heights", "diagnostics"):
        (q,) = qos_profiles(key)
        ref = qos_for(key)
        assert (q.reliability.name, q.depth, q.durability.name) == (ref.reliability.name, ref.depth, ref.durability.name)


# --- offline replay ----------------------------------------------------------------------
def test_offline_replay_is_deterministic(tmp_path):
    inputs = read_inputs(PRESS, InputOptions())
    replay_to_bag(inputs, tmp_path / "a", grid_rate_hz=GRID_RATE_HZ)
    replay_to_bag(read_inputs(PRESS, InputOptions()), tmp_path / "b", grid_rate_hz=GRID_RATE_HZ)
    a, b = raw_messages(tmp_path / "a", "/tool/wrench"), raw_messages(tmp_path / "b", "/tool/wrench")
    assert len(a) == inputs.n_poses == 2301
    assert a == b  # identical bag timestamps and identical serialized force payloads
    assert raw_messages(tmp_path / "a", "/tissue/layer_heights") == raw_messages(tmp_path / "b", "/tissue/layer_heights")


@pytest.mark.parametrize("scene", SCENES)
def test_golden_regression(tmp_path, scene):
    out = tmp_path / "out"
    inputs = read_inputs(DATA / scene / "input", InputOptions())
    res = replay_to_bag(inputs, out, SCENE_PARAMS.get(scene, DEFAULT_PARAMS), grid_rate_hz=GRID_RATE_HZ)
    d = compare.diff_outputs(compare.read_outputs(DATA / scene / "expected"), compare.read_outputs(out))
    assert compare.verdict(d, compare.EXACT) == []
    assert d.matched == res.stamps_ns.size > 2000 and d.grids_matched >= 4
    assert res.layers_reached == ["epidermis", "dermis", "fat"]


def test_replay_cli_writes_bag_report_summary(tmp_path, capsys):
    out = tmp_path / "r"
    assert replay.main([str(PRESS), "--out", str(out), "--grid-rate-hz", "2"]) == 0
    s = json.loads((out / "summary.json").read_text())
    assert (out / "report.png").stat().st_size > 10_000 and (out / "outputs" / "metadata.yaml").exists()
    assert s["answered"] == s["poses"] == 2301 and s["peak_force_n"] > 0.1 and s["rejected"] == {}
    printed = capsys.readouterr().out
    assert "layers reached: epidermis, dermis, fat" in printed and f"report: {out / 'report.png'}" in printed
    assert compare.main([str(DATA / "press_hold_release" / "expected"), str(out / "outputs"), "--exact"]) == 0


def test_compare_defaults_are_the_live_replay_contract():
    """``replay --live`` PASS and ``compare``'s defaults are one contract: a live run that answered 97 % of the
    poses within 0.5 % of peak, with extra fallback-clock wrenches, passes both; ``--exact`` is for offline pairs."""
    a = {s: 1.0 + 1e-3 * s for s in range(1000)}
    b = {s: f * 1.005 for s, f in a.items() if s % 33}  # 97 % of A, 0.5 % of peak off
    b.update({10_000 + k: 0.0 for k in range(80)})  # wrenches that answer no pose of A
    d = compare.diff_outputs((a, {}), (b, {}))
    assert compare.verdict(d) == [] and d.matched_fraction == pytest.approx(0.969)
    fails = compare.verdict(d, compare.EXACT)
    assert len(fails) == 3 and "of B's wrench stamps are not in A" in fails[2]
    ap = replay.build_parser().parse_args(["x", "--live"])
    assert (live.force_tol_frac(ap, hands=False), ap.min_answered) == (compare.LIVE.force_rel, compare.LIVE.min_matched)
    # with hands the default is the recorded two-hand check's 5 %; a value given, the single-tool default included, wins
    assert live.force_tol_frac(ap, hands=True) == published.PUBLISHED_HANDS.force_rel
    given = replay.build_parser().parse_args(["x", "--live", "--force-tol-frac", str(compare.LIVE.force_rel)])
    assert live.force_tol_frac(given, hands=True) == compare.LIVE.force_rel
    b2 = {s: f for s, f in b.items() if s % 10}  # 87 % answered: both fail
    assert compare.verdict(compare.diff_outputs((a, {}), (b2, {})))[0].startswith("matched 0.8")


def test_compare_exits_nonzero_on_difference_and_two_on_bad_bag(tmp_path, capsys):
    a, b = DATA / "press_hold_release" / "expected", DATA / "edge_press" / "expected"
    assert compare.main([str(a), str(b)]) == 1
    assert "DIFFERENT: max |dF|" in capsys.readouterr().out
    assert compare.main([str(a), str(tmp_path / "nope")]) == 2
    assert f"skin-sim compare: error: {tmp_path / 'nope'}: no such bag" in capsys.readouterr().err


# --- foreign bags ------------------------------------------------------------------------
def short_forces(bag, opts):
    """Offline replay without an output bag (nothing is written next to the input)."""
    return replay_offline(read_inputs(bag, opts), grid_rate_hz=0)


def test_crtk_device_bag_gives_the_tissue_frame_forces(tmp_path):
    m = DeviceMapping(offset_m=(0.001, -0.002, 0.05), scale=1.0, axes="x-zy")  # a real Touch's base frame
    dev = write_trajectory_bag(
        tmp_path / "dev",
        "press_all_layers",
        compress=False,
        frame="base",
        mapping=m,
        pose_topic="/device/measured_cp",
        twist_topic="/device/measured_cv",
    )
    ref = short_forces(DATA / "press_all_layers" / "input", InputOptions())
    got = short_forces(dev, InputOptions(convention="crtk", mapping=m))
    assert np.array_equal(got.stamps_ns, ref.stamps_ns)
    assert np.allclose(got.force_n, ref.force_n, rtol=1e-9, atol=1e-12)
    # without the convention the device topic is not found, and says so
    with pytest.raises(NoPoseTopicError, match="no pose topic '/tool/pose'; topics present: /device/measured_cp"):
        read_inputs(dev, InputOptions())


def test_omni_device_bag_without_twist_replays(tmp_path):
    m = DeviceMapping()
    dev = write_trajectory_bag(
        tmp_path / "omni",
        "press_hold_release",
        compress=False,
        frame="base",
        mapping=m,
        pose_topic="/device/phantom/pose",
        twist_topic="/device/unused_twist",
    )
    inputs = read_inputs(dev, InputOptions(convention="omni"))
    assert inputs.twist_topic is None and inputs.n_poses == 2301
    ref = short_forces(PRESS, InputOptions())
    got = short_forces(dev, InputOptions(convention="omni"))
    assert got.peak_force_n == pytest.approx(ref.peak_force_n, rel=0.05)  # differentiated poses instead of twists


def test_topic_and_frame_remap(tmp_path):
    bag = write_trajectory_bag(
        tmp_path / "foreign",
        "press_hold_release",
        compress=False,
        frame="skin_patch",
        pose_topic="/haptics/tip_pose",
        twist_topic="/haptics/tip_twist",
    )
    ref = short_forces(PRESS, InputOptions())
    got = short_forces(bag, InputOptions(pose_topic="haptics/tip_pose", twist_topic="/haptics/tip_twist", frame="skin_patch"))
    assert np.array_equal(got.force_n, ref.force_n)
    wrong_frame = short_forces(bag, InputOptions(pose_topic="/haptics/tip_pose", twist_topic=""))
    assert wrong_frame.stamps_ns.size == 0 and wrong_frame.counts["unknown_frame"] == 2301


# --- bad bags: each with its exact error ---------------------------------------------------
def test_bag_without_pose_topic(tmp_path, capsys):
    bag = tmp_path / "nopose"
    with BagWriter(bag, "mcap") as w:
        w.write(
            "/tool/wrench",
            TOPICS["tool_wrench"].type,
            T0,
            cv.fill_wrench(new_message(TOPICS["tool_wrench"].type), T0, "tissue", (0, 0, 1)),
        )
    msg = (
        f"{bag}: no pose topic '/tool/pose'; topics present: /tool/wrench [geometry_msgs/msg/WrenchStamped] "
        "(choose one with --pose-topic, or --convention crtk|omni for a device driver's bag)"
    )
    with pytest.raises(NoPoseTopicError) as e:
        read_inputs(bag, InputOptions())
    assert str(e.value) == msg
    assert replay.main([str(bag), "--out", str(tmp_path / "o")]) == 2
    assert capsys.readouterr().err.strip() == f"skin-sim replay: error: {msg}"


@pytest.mark.parametrize("storage", ["mcap", "sqlite3"])
def test_truncated_bag(tmp_path, storage):
    bag = write_trajectory_bag(tmp_path / "cut", "press_hold_release", storage=storage, compress=False)
    (f,) = [p for p in bag.iterdir() if p.suffix in (".mcap", ".db3")]
    data = f.read_bytes()
    f.write_bytes(data[: len(data) // 2])
    with pytest.raises(TruncatedBagError, match=f"^bag file {f} is truncated or corrupt \\("):
        read_inputs(bag, InputOptions())


def _zero_mid_file(bag: Path, frac: float, n: int = 4096) -> Path:
    (f,) = [p for p in bag.iterdir() if p.suffix == ".mcap"]
    data = bytearray(f.read_bytes())
    i = int(len(data) * frac)
    data[i : i + n] = bytes(n)
    f.write_bytes(bytes(data))
    return f


@pytest.mark.parametrize("frac", [0.3, 0.5, 0.7])
def test_corrupt_mcap_is_one_line_error_in_replay_and_compare(tmp_path, capsys, frac):
    """4 kB zeroed mid-file: a record that does not decode (SerdeError), a bad length, or a scan that ends
    early without an error (0.3: 789 of 2301 poses) - each a one-line "truncated or corrupt" error, exit 2."""
    bag = write_trajectory_bag(tmp_path / "in", "press_hold_release", compress=False)
    replay_to_bag(read_inputs(bag, InputOptions()), tmp_path / "out", grid_rate_hz=0)
    f = _zero_mid_file(bag, frac)
    assert replay.main([str(bag), "--out", str(tmp_path / "o"), "--no-report"]) == 2
    err = capsys.readouterr().err
    assert err.startswith(f"skin-sim replay: error: bag file {f} is truncated or corrupt (") and err.count("\n") == 1, err
    assert "Traceback" not in err
    f_out = _zero_mid_file(tmp_path / "out", frac)
    assert compare.main([str(tmp_path / "out"), str(tmp_path / "out"), "--no-grids"]) == 2
    err = capsys.readouterr().err
    assert err.startswith(f"skin-sim compare: error: bag file {f_out} is truncated or corrupt (") and err.count("\n") == 1, err


def test_pose_topic_without_messages_is_an_error(tmp_path, capsys):
    bag = tmp_path / "empty_pose"
    with BagWriter(bag, "mcap") as w:
        w.add_topic("/tool/pose", TOPICS["tool_pose"].type)
        w.add_topic("/tool/twist", TOPICS["tool_twist"].type)
    assert replay.main([str(bag), "--out", str(tmp_path / "o")]) == 2
    err = capsys.readouterr().err
    assert err.startswith(f"skin-sim replay: error: {bag}: pose topic '/tool/pose' holds no messages") and err.count("\n") == 1
    assert not (tmp_path / "o" / "report.png").exists()


def test_foreign_frame_says_which_frames_and_how_to_map(tmp_path, capsys):
    bag = write_trajectory_bag(tmp_path / "foreign", "press_hold_release", compress=False, frame="skin_patch")
    assert replay.main([str(bag), "--out", str(tmp_path / "o"), "--grid-rate-hz", "0"]) == 2
    err = capsys.readouterr().err
    assert f"{bag}: none of 2301 poses was answered (unknown_frame" in err
    assert "/tool/pose holds poses in frame 'skin_patch' (2301 poses)" in err and "--frame skin_patch" in err
    assert replay.main([str(bag), "--out", str(tmp_path / "o"), "--grid-rate-hz", "0", "--frame", "skin_patch"]) == 0
    assert "answered 2301" in capsys.readouterr().out


def test_unknown_message_type_on_pose_topic(tmp_path):
    bag = tmp_path / "unknown"
    with BagWriter(bag, "mcap") as w:  # a type no typestore knows, declared with its own definition
        w._writer.add_connection(
            "/tool/pose", "acme_msgs/msg/StylusState", msgdef="float64 x\nfloat64 y\nfloat64 z", rihs01="RIHS01_" + "0" * 64
        )
    with pytest.raises(UnknownMessageTypeError) as e:
        read_inputs(bag, InputOptions())
    assert str(e.value) == (
        f"{bag}: unknown message type 'acme_msgs/msg/StylusState' on pose topic '/tool/pose' "
        "(expected geometry_msgs/msg/PoseStamped)"
    )
    bag2 = tmp_path / "point"
    with BagWriter(bag2, "sqlite3") as w:  # a known type, but not a pose
        w.add_topic("/tool/pose", "geometry_msgs/msg/PointStamped")
    with pytest.raises(UnknownMessageTypeError, match="unknown message type 'geometry_msgs/msg/PointStamped' on pose topic"):
        read_inputs(bag2, InputOptions())


def test_missing_bag(tmp_path):
    with pytest.raises(BagNotFoundError, match="no such bag"):
        read_inputs(tmp_path / "absent", InputOptions())
    (tmp_path / "empty").mkdir()
    with pytest.raises(BagNotFoundError, match=r"not a rosbag2 folder \(no metadata.yaml\)"):
        read_inputs(tmp_path / "empty", InputOptions())


# --- live against offline (real processes) ----------------------------------------------
@pytest.mark.ros
def test_live_replay_agrees_with_offline(tmp_path, ros_domain):
    pytest.importorskip("rclpy")
    bag = tmp_path / "in"
    shutil.copytree(PRESS, bag)
    code = replay.main([str(bag), "--out", str(tmp_path / "o"), "--no-report", "--grid-rate-hz", "0", "--live"])
    s = json.loads((tmp_path / "o" / "live_summary.json").read_text())
    assert s["max_df_n"] <= 0.01 * s["peak_force_n"], s
    # The bar is 95 % answered (the CLI's default, so `code` may be 1). With the node's
    # keep-last-10 input reader this measured 97.4-98.0 % over runs on this 2-core VM (92-97 % with
    # keep-last 1); a loaded CI machine can stall a process for several ms, so the test keeps a
    # margin below the CLI's bar and asserts 90 %.
    assert s["fraction_answered"] >= 0.90, s
    assert code in (0, 1) and s["pass"] == (code == 0)
    assert len(raw_messages(tmp_path / "o" / "live", bag_topic("tool_wrench"))) >= s["live_answered"]


@pytest.mark.parametrize("scene_name", ["press_hold_release", "press_all_layers"])
def test_report_surface_map_and_cross_section_agree_at_peak(scene_name):
    """The report's two pictures come from one model at peak force: its grid (the surface map), its pointwise
    cross-section and the tool depth must agree there (the model used to get q and centres but not the mode
    levels and active layer set: a flat map beside a dent half the tool's depth)."""
    res = short_forces(DATA / scene_name / "input", InputOptions())
    x, y, z = res.tool_xyz_m[res.peak_index]
    m = res.model_at_peak()
    g = m.build_grid()
    ix, iy = np.argmin(np.abs(g.xs_m - x)), np.argmin(np.abs(g.ys_m - y))
    surface_map = g.heights_m[0][iy, ix]
    section = m.cross_section([x], y)[0, 0]
    depth = res.depth_m[res.peak_index]
    assert depth > 0 and z == pytest.approx(-depth)
    assert section == pytest.approx(z, rel=0.02)  # the tool sits on the surface it dents
    at_cell = m.cross_section([g.xs_m[ix]], g.ys_m[iy])[0, 0]  # the grid cell nearest the tool, at its centre
    assert surface_map == pytest.approx(at_cell, rel=0.02)
    assert surface_map == pytest.approx(section, rel=0.05)  # up to half a 1 mm cell from the tool's centre
    assert g.heights_m[0].min() == pytest.approx(surface_map, rel=0.02)  # the deepest point of the map is there


def test_replay_takes_the_preset_the_bag_was_recorded_with(tmp_path, capsys):
    """A needle bag (skin-sim record writes skin_sim.params) replays with the needle's preset, not the flat punch's."""
    import shutil

    import yaml

    bag = tmp_path / "needle_input"
    shutil.copytree(DATA / "needle_oblique_30" / "input", bag)
    meta = yaml.safe_load((bag / "metadata.yaml").read_text())
    meta["rosbag2_bagfile_information"].setdefault("custom_data", {})["skin_sim.params"] = "needle.yaml"
    (bag / "metadata.yaml").write_text(yaml.safe_dump(meta))
    assert replay.main([str(bag), "--out", str(tmp_path / "r"), "--grid-rate-hz", "0", "--no-report"]) == 0
    printed = capsys.readouterr().out
    assert "needle.yaml (recorded with the bag)" in printed
    peak = float(printed.split("peak force ", 1)[1].split(" N", 1)[0])
    # the 21 G needle's skin peak, not a flat punch's: the skin ruptures when the tent's normal reaction N reaches
    # 1.80 N (issue 31's review); at 30 deg the tip's friction on the tent adds at most mu N = 0.9 N along the surface
    assert 1.80 - 0.01 <= peak <= 1.80 * math.hypot(1.0, 0.5) + 0.01


def _params_at(tmp_path, **node):
    """A copy of the default parameter file with node parameters changed."""
    doc = yaml.safe_load(Path(DEFAULT_PARAMS).read_text())
    doc["/**/skin_sim_node"]["ros__parameters"].update(node)
    path = tmp_path / "params.yaml"
    path.write_text(yaml.safe_dump(doc))
    return path


def test_offline_replay_answers_what_a_throttled_node_answers(tmp_path):
    """Issue 28 item 4: a node with rate_hz 250 (fixed) answers every fourth pose of a 1 kHz bag on the stamps; the
    offline replay applies the same throttle, and its forces are the session's stepped exactly as the node steps it
    (every pose taken, only the due ones ticked), bit for bit."""
    from skin_sim_node.bags.inputs import POSE
    from skin_sim_node.bags.offline import load_params
    from skin_sim_node.rate import AnswerThrottle
    from skin_sim_node.session import HapticSession
    from skin_sim_node.tools import make_tool

    params = _params_at(tmp_path, rate_hz=250.0, rate_policy="fixed")
    inputs = read_inputs(PRESS, InputOptions())
    res = replay_offline(inputs, params, grid_rate_hz=0)
    full = replay_offline(inputs, DEFAULT_PARAMS, grid_rate_hz=0)
    assert 0.24 <= len(res.stamps_ns) / len(full.stamps_ns) <= 0.26
    sp, cfg = load_params(params)
    s, th, prev, want = HapticSession(make_tool(cfg), sp), AnswerThrottle(250.0), None, []
    for stamp, rank, fr, xyz, quat in inputs.events:  # the node: on_pose for every pose, a tick for the due ones
        if rank != POSE:
            s.on_twist(stamp, fr, xyz)
        elif s.on_pose(stamp, fr, xyz, quat=quat) is None and th.due(stamp):
            want.append((stamp, s.tick(stamp, 0 if prev is None else stamp - prev).force_n))
            prev = stamp
    assert [w[0] for w in want] == list(res.stamps_ns)
    assert np.array_equal(np.array([w[1] for w in want]), res.force_vec_n)


@pytest.mark.ros
def test_live_replay_of_a_throttled_node_agrees_with_offline(tmp_path, ros_domain):
    """A real node at rate_hz 250 (fixed) fed the 1 kHz bag live: it answers the poses the offline replay answers
    (the throttle on the stamps, issue 28 item 4), with the same forces."""
    pytest.importorskip("rclpy")
    bag = tmp_path / "in"
    shutil.copytree(PRESS, bag)
    params = _params_at(tmp_path, rate_hz=250.0, rate_policy="fixed")
    code = replay.main(
        [str(bag), "--out", str(tmp_path / "o"), "--no-report", "--grid-rate-hz", "0", "--live", "--params", str(params)]
    )
    s = json.loads((tmp_path / "o" / "live_summary.json").read_text())
    assert s["max_df_n"] <= 0.01 * s["peak_force_n"], s
    assert s["fraction_answered"] >= 0.90, s  # of the offline answers: the same quarter of the poses
    assert code in (0, 1) and s["pass"] == (code == 0)
