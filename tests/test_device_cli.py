"""Device node command lines (issue 13 "device nodes", issue 15 item 9): one base, described options, true usage."""

import subprocess
import sys

import pytest

pytest.importorskip("rclpy")

from skin_sim_node.device.bridge import BridgeNode  # noqa: E402
from skin_sim_node.device.mock_tool import MockToolNode  # noqa: E402
from skin_sim_node.device.sim_device import SimDeviceNode  # noqa: E402

NODES = {"bridge": BridgeNode, "device": SimDeviceNode, "mock-tool": MockToolNode}


@pytest.mark.parametrize("command", sorted(NODES))
def test_help_names_the_command_and_describes_every_option(command):
    cls = NODES[command]
    ap = cls.parser()
    assert ap.prog == f"skin-sim {command}"
    for action in ap._actions:
        if action.option_strings and action.dest != "help":
            assert action.help and len(action.help) > 10, f"{command} {action.option_strings} has no description"
    out = subprocess.run([sys.executable, "-m", "skin_sim_node.cli", command, "--help"], capture_output=True, text=True)
    assert out.returncode == 0 and out.stdout.startswith(f"usage: skin-sim {command}")


def test_bridge_help_describes_the_issue_15_options():
    text = BridgeNode.parser().format_help()
    text = text[text.index("options:") :]
    for flag, words in (("--force-scale", "F_device"), ("--max-force-n", "clamp"), ("--watchdog-s", "zero force")):
        block = text[text.index(flag) :].split("\n  --")[0]
        assert words in block, block


def test_every_parameter_is_declared_read_only_from_one_table():
    for cls in NODES.values():
        names = [p.name for p in cls.PARAMS]
        assert len(names) == len(set(names))
        opts = vars(cls.parser().parse_args([]))
        assert all(v is None or v is False for k, v in opts.items() if k in names)  # no option given: ROS defaults rule


def test_bad_axes_is_a_one_line_error(capsys):
    assert BridgeNode.main(["--axes", "xxz"]) == 2
    assert "need each of x, y, z exactly once" in capsys.readouterr().out
