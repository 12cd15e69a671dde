"""A new user's common mistakes each get one line that says what is wrong and how to write it.

Each command runs as a user runs it (``python -m skin_sim_node.cli``, the ``skin-sim`` entry point), so the
one-line answer is what a terminal shows.
"""

from __future__ import annotations

import os
import shutil
import subprocess
import sys
import time
from pathlib import Path

import pytest

from skin_sim_node.startup import node_argument_error, start_line, suggest

REPO = Path(__file__).resolve().parents[1]


def run(*argv, timeout=120):
    return subprocess.run(
        [sys.executable, "-m", "skin_sim_node.cli", *argv],
        cwd=REPO,
        capture_output=True,
        text=True,
        timeout=timeout,
        env=dict(os.environ),
    )


def one_line_error(p) -> str:
    lines = p.stderr.strip().splitlines()
    assert p.returncode == 2 and len(lines) == 1, (p.returncode, p.stdout, p.stderr)
    return lines[0]


def test_params_file_without_ros_args_is_an_error_that_shows_the_right_spelling():
    line = one_line_error(run("node", "--params-file", "config/paper.yaml"))
    assert line.endswith("skin-sim node --ros-args --params-file config/paper.yaml"), line
    assert node_argument_error(["--ros-args", "--params-file", "config/paper.yaml"]) is None


def test_missing_params_file_is_one_line(tmp_path):
    assert one_line_error(run("node", "--ros-args", "--params-file", "nope.yaml")) == (
        "skin-sim node: error: --params-file nope.yaml: no such file"
    )
    line = one_line_error(run("replay", "tests/data/drag/input", "--params", "nope.yaml", "--out", str(tmp_path / "o")))
    assert line == "skin-sim replay: error: --params nope.yaml: no such file", line
    assert not (tmp_path / "o").exists()  # nothing half-written


def test_option_typo_gets_a_suggestion():
    line = one_line_error(run("bridge", "--stabilizer", "passivity"))
    assert "unrecognized arguments: --stabilizer passivity (did you mean '--stabiliser'?)" in line, line
    line = one_line_error(run("soak", "--duraton-s", "3"))
    assert "(did you mean '--duration-s'?)" in line, line


def test_command_and_chart_target_typos_get_a_suggestion():
    line = one_line_error(run("replya", "out/rec"))
    assert line.startswith("skin-sim: error: unknown command 'replya' (did you mean 'replay'?)"), line
    line = one_line_error(run("chart", "stabilty"))
    assert "unknown target 'stabilty' (did you mean 'stability'?)" in line, line
    assert suggest("zzzz", ["replay"]) == ""  # nothing close: no guess


def test_start_line_names_form_preset_and_tool():
    flat = {"tissue.form": "paper", "tissue.tool.shape": "flat", "tissue.tool.radius_m": 2.5e-3}
    assert start_line(flat, ["--ros-args", "--params-file", "config/paper.yaml"]) == (
        "starting: tissue form 'paper', preset config/paper.yaml, tool flat punch r = 2.50 mm"
    )
    assert "no preset file" in start_line(dict(flat, **{"tissue.tool.shape": "sphere"}), [])
    args = ["--ros-args", "--params-file", str(REPO / "config/paper.yaml")]  # keyed /**/skin_sim_node
    assert "NOT applied" not in start_line(flat, args, "/skin_sim_node")
    assert "NOT applied" not in start_line(flat, args, "/bed1/skin_sim_node")


def test_start_line_says_when_a_bare_key_misses_a_namespaced_node(tmp_path):
    bare = tmp_path / "bare.yaml"
    bare.write_text("skin_sim_node:\n  ros__parameters:\n    rate_hz: 500.0\n")
    flat = {"tissue.form": "layered", "tissue.tool.shape": "flat", "tissue.tool.radius_m": 2.5e-3}
    args = ["--ros-args", "--params-file", str(bare)]
    assert "NOT applied" not in start_line(flat, args, "/skin_sim_node")
    assert "NOT applied: it has no entry for /bed1/skin_sim_node" in start_line(flat, args, "/bed1/skin_sim_node")


@pytest.mark.ros
def test_node_first_line_names_the_tissue_form_preset_and_tool(tmp_path, ros_domain):
    """The first line says what runs, and the shipped preset (keyed ``/**/skin_sim_node``) applies in a namespace too:
    it was keyed ``skin_sim_node:``, which rcl matches to ``/skin_sim_node`` only, and namespaced nodes ran without it."""
    from skin_sim_node.scenes import Scene

    firsts = {}
    with Scene(tmp_path / "logs") as scene:
        for ns in ("/", "/mistakes"):
            node = scene.start(
                f"node{len(firsts)}", "node", "--ros-args", "--params-file", "config/paper.yaml", "-r", f"__ns:={ns}"
            )
            scene.wait_for_log(node, "live:", timeout_s=180)
            time.sleep(0.2)
            firsts[ns] = next(line for line in node.log().splitlines() if "skin_sim_node" in line)
    assert firsts["/"].endswith("starting: tissue form 'paper', preset config/paper.yaml, tool flat punch r = 2.50 mm")
    assert firsts["/mistakes"].endswith("starting: tissue form 'paper', preset config/paper.yaml, tool flat punch r = 2.50 mm")


def test_parameter_file_keys_match_as_rcl_reads_them():
    from skin_sim_node.startup import key_matches

    assert key_matches("/**/skin_sim_node", "/skin_sim_node") and key_matches("/**/skin_sim_node", "/s1/skin_sim_node")
    assert key_matches("skin_sim_node", "/skin_sim_node") and not key_matches("skin_sim_node", "/s1/skin_sim_node")
    assert key_matches("/*/skin_sim_node", "/s1/skin_sim_node") and not key_matches("/*/skin_sim_node", "/skin_sim_node")
    assert key_matches("/**", "/a/b/c") and not key_matches("/other", "/skin_sim_node")


# --- configuration that cannot be silently wrong (issue 29 item 1) ------------------------------------------------
MISSPELT = """/**/skin_sim_node:
  ros__parameters:
    max_forse_n: 3.0
    tissue:
      layers:
        dermis:
          stifness_n_per_m: 100.0
"""


def test_unknown_names_get_the_closest_valid_name():
    from msgs_schema.parameters import check_overrides, check_tissue
    from msgs_schema.spec import ConfigError, unknown_name

    assert unknown_name("rate_hzz", ["rate_hz", "display_rate_hz"]) == "unknown parameter 'rate_hzz' (did you mean 'rate_hz'?)"
    assert "docs/parameters.md" in unknown_name("zzzz", ["rate_hz"])  # nothing close: where the names are listed
    with pytest.raises(ConfigError) as e:
        check_overrides(
            {"max_forse_n": 3.0, "tissue.layers.dermis.stifness_n_per_m": 1.0, "use_sim_time": False}, ["use_sim_time"]
        )
    assert str(e.value) == (
        "unknown parameter 'max_forse_n' (did you mean 'max_force_n'?); unknown parameter "
        "'tissue.layers.dermis.stifness_n_per_m' (did you mean 'tissue.layers.dermis.stiffness_n_per_m'?)"
    )
    with pytest.raises(ConfigError, match=r"did you mean 'layers.fat.thickness_m'"):
        check_tissue({"layers.fat.thicknes_m": 1e-3})
    # an integer for a float is the float; the builtin name is accepted and left out
    assert check_overrides({"max_force_n": 3, "use_sim_time": True}, ["use_sim_time"]) == {"max_force_n": 3.0}


def test_offline_commands_refuse_unknown_names_in_a_parameter_file(tmp_path):
    bad = tmp_path / "bad.yaml"
    bad.write_text(MISSPELT)
    line = one_line_error(run("visco", "--params-file", str(bad)))
    assert line.startswith("skin-sim visco: error: unknown parameter 'max_forse_n' (did you mean 'max_force_n'?)"), line
    line = one_line_error(run("replay", "tests/data/drag/input", "--params", str(bad), "--out", str(tmp_path / "o")))
    assert "'tissue.layers.dermis.stifness_n_per_m' (did you mean 'tissue.layers.dermis.stiffness_n_per_m'?)" in line, line


@pytest.mark.ros
def test_node_refuses_unknown_names_and_bad_values_in_one_line(tmp_path, ros_domain):
    """A misspelt safety limit in a file, a misspelt -p, a bad value in a file and with -p: one line each, exit 2,
    and the node never reaches "live:" (it does not run on the defaults)."""
    bad = tmp_path / "bad.yaml"
    bad.write_text(MISSPELT)
    neg = tmp_path / "neg.yaml"
    neg.write_text(MISSPELT.replace("max_forse_n", "max_force_n").replace("stifness_n_per_m: 100.0", "stiffness_n_per_m: -822.7"))
    cases = {
        ("--params-file", str(bad)): "error: unknown parameter 'max_forse_n' (did you mean 'max_force_n'?); unknown "
        "parameter 'tissue.layers.dermis.stifness_n_per_m' (did you mean 'tissue.layers.dermis.stiffness_n_per_m'?); "
        "the node does not start",
        ("-p", "rate_hzz:=500.0"): "error: unknown parameter 'rate_hzz' (did you mean 'rate_hz'?); the node does not start",
        ("--params-file", str(neg)): "error: tissue.layers.dermis.stiffness_n_per_m = -822.7 N/m: must be > 0.0; "
        "the node does not start",
        ("-p", "tissue.layers.dermis.stiffness_n_per_m:=-822.7"): "error: tissue.layers.dermis.stiffness_n_per_m = -822.7 "
        "N/m: must be > 0.0; the node does not start",
        ("-p", "max_force_n:=abc"): "error: max_force_n: expected a number, got 'abc'; the node does not start",
    }
    for args, expected in cases.items():
        p = run("node", "--ros-args", *args)
        assert one_line_error(p) == expected, (args, p.stderr)
        assert "live:" not in p.stdout + p.stderr


@pytest.mark.ros
def test_device_commands_refuse_unknown_names_and_bad_values_in_one_line(ros_domain):
    p = run("bridge", "--ros-args", "-p", "max_forse_n:=2.0")
    assert one_line_error(p) == "error: unknown parameter 'max_forse_n' (did you mean 'max_force_n'?); the node does not start"
    p = run("bridge", "--max-force-n", "500")
    assert one_line_error(p) == "error: max_force_n = 500.0: must be <= 100.0; the node does not start"
    p = run("bridge", "--ros-args", "-p", "axes:=xqz")
    assert one_line_error(p) == "error: axes 'xqz': unexpected character 'q'; the node does not start"
    p = run("device", "--ros-args", "-p", "rate_hz:=5.0")
    assert one_line_error(p) == "error: rate_hz = 5.0: must be >= 10.0; the node does not start"
    p = run("mock-tool", "--ros-args", "-p", "trajectry:=drag")
    assert one_line_error(p) == "error: unknown parameter 'trajectry' (did you mean 'trajectory'?); the node does not start"


@pytest.mark.ros
def test_live_sets_are_refused_with_the_start_up_reason(tmp_path, ros_domain):
    """``set_parameters`` over the node's real parameter service: an unknown name and a bad value are refused with
    the reasons start-up gives; an integer for a float parameter and a good value are applied."""
    import rclpy
    from rcl_interfaces.srv import SetParameters
    from rclpy.executors import SingleThreadedExecutor
    from rclpy.parameter import Parameter

    from skin_sim_node.scenes import Scene

    with Scene(tmp_path / "logs") as scene:
        node = scene.start("node", "node")
        scene.wait_for_log(node, "live:", timeout_s=180)
        ctx = rclpy.Context()
        rclpy.init(context=ctx)
        try:
            client_node = rclpy.create_node("mistakes_param_client", context=ctx)
            executor = SingleThreadedExecutor(context=ctx)
            executor.add_node(client_node)
            cli = client_node.create_client(SetParameters, "/skin_sim_node/set_parameters")
            assert cli.wait_for_service(timeout_sec=60.0), node.log()

            def set_one(name, value):
                req = SetParameters.Request(parameters=[Parameter(name, value=value).to_parameter_msg()])
                fut = cli.call_async(req)
                executor.spin_until_future_complete(fut, timeout_sec=60.0)
                assert fut.done(), name
                return fut.result().results[0]

            r = set_one("max_forse_n", 3.0)
            assert not r.successful and r.reason == "unknown parameter 'max_forse_n' (did you mean 'max_force_n'?)", r
            r = set_one("tissue.layers.dermis.stiffness_n_per_m", -822.7)
            assert not r.successful and r.reason == "tissue.layers.dermis.stiffness_n_per_m = -822.7 N/m: must be > 0.0", r
            r = set_one("max_force_n", 5000.0)
            assert not r.successful and r.reason == "max_force_n = 5000.0 N: must be <= 1000.0", r
            assert set_one("max_force_n", 3).successful  # an integer for a float parameter
            executor.shutdown()
            client_node.destroy_node()
        finally:
            rclpy.shutdown(context=ctx)
        scene.wait_for_log(node, "parameters applied: max_force_n=3.0")


@pytest.mark.ros
def test_bridge_touch_preset_sets_the_touch_axes(tmp_path, ros_domain):
    """``skin-sim bridge --device touch`` (the README's real-device line) maps a Touch's base frame: axes x-zy, CRTK;
    an explicit --axes wins over the preset."""
    from skin_sim_node.scenes import Scene

    with Scene(tmp_path / "logs") as scene:
        touch = scene.start("touch", "bridge", "--device", "touch", "--device-ns", "arm")
        scene.wait_for_log(touch, "axes x-zy", timeout_s=120)
        assert "bridge crtk: /arm/measured_cp" in touch.log()
        own = scene.start("own", "bridge", "--device", "touch", "--axes", "xyz", "--device-ns", "arm2")
        scene.wait_for_log(own, "axes xyz", timeout_s=120)


# --- hints where there was silence (issue 29 item 5) ---------------------------------------------------------------
@pytest.mark.ros
def test_view_without_a_node_says_so(ros_domain):
    """This test's own DDS domain has no node: the live view says so (it printed only its URL) and keeps serving."""
    p = run("view", "--port", "0", "--duration-s", "1", timeout=120)
    assert p.returncode == 0, p.stderr
    assert "skin-sim view: no skin_sim_node answered in namespace / (no namespace) within 3 s" in p.stdout, p.stdout
    assert "skin-sim node, on this ROS_DOMAIN_ID" in p.stdout


def test_view_screenshot_exits_after_its_picture(tmp_path):
    """``--screenshot`` without ``--duration-s``: the command ends by itself once the picture is saved (it served on
    forever). A bag source, so no node or DDS is involved; without Chromium it ends too, exit 1 with the reason."""
    shot = tmp_path / "view.png"
    data = REPO / "tests" / "data" / "press_all_layers"
    p = run(
        "view", str(data / "input"), str(data / "expected"), "--port", "0", "--screenshot", str(shot), "--shot-after-s", "0.2"
    )
    if shutil.which("chromium") is None:
        assert p.returncode == 1 and "skin-sim view: no screenshot:" in p.stdout, (p.stdout, p.stderr)
        return
    assert p.returncode == 0, (p.stdout, p.stderr)
    assert f"skin-sim view: screenshot {shot}" in p.stdout and shot.stat().st_size > 10_000, p.stdout


def test_record_refuses_a_bad_parameter_file_before_anything_starts(tmp_path):
    bad = tmp_path / "bad.yaml"
    bad.write_text(MISSPELT)
    line = one_line_error(run("record", str(tmp_path / "rec"), "--params", str(bad)))
    assert line.startswith("skin-sim record: error: unknown parameter 'max_forse_n' (did you mean 'max_force_n'?)"), line
    assert not (tmp_path / "rec").exists() and not (tmp_path / "rec_logs").exists()  # nothing half-written


@pytest.mark.ros
def test_a_scene_node_that_refuses_its_parameters_is_one_configuration_error(tmp_path, ros_domain):
    """Commands that start a node through a Scene (record, benchmarks with --node-param, ...) end with the node's one
    line: ``wait_for_log`` raises a ConfigError (cli: one line, exit 2), still a RuntimeError for their callers."""
    from msgs_schema.spec import ConfigError
    from skin_sim_node.scenes import Scene, StartRefusedError

    with Scene(tmp_path / "logs") as scene:
        node = scene.node("-p", "rate_hzz:=500.0")
        with pytest.raises(StartRefusedError) as e:
            scene.wait_for_log(node, "live:", timeout_s=180)
    assert isinstance(e.value, ConfigError) and isinstance(e.value, RuntimeError)
    assert str(e.value) == "skin_sim_node: unknown parameter 'rate_hzz' (did you mean 'rate_hz'?); the node does not start"


def test_a_parameter_file_that_is_not_yaml_is_one_line(tmp_path):
    """A parameter file that does not parse (an unclosed list) stops the node, an offline command and the view with one
    line naming the file and the place, exit 2, before rcl or a bag is touched (rcl's own parse error was a C log line
    and a traceback)."""
    bad = tmp_path / "broken.yaml"
    bad.write_text("a: [1, 2\n  b: :\n")
    where = f"{bad}: not a YAML parameter file (line 2, column 4)"
    assert one_line_error(run("node", "--ros-args", "--params-file", str(bad))).startswith(
        f"skin-sim node: error: --params-file {where}"
    )
    line = one_line_error(run("replay", "tests/data/drag/input", "--params", str(bad), "--out", str(tmp_path / "o")))
    assert line.startswith(f"skin-sim replay: error: {where}"), line
    assert not (tmp_path / "o").exists()
