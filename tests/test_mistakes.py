"""A new user's common mistakes each get one line that says what is wrong and how to write it.

Each command runs as a user runs it (``python -m skin_sim_node.cli``, the ``skin-sim`` entry point), so the
one-line answer is what a terminal shows.
"""

from __future__ import annotations

import os
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
