"""Device node command lines (issue 13 "device nodes", issue 15 item 9): one base, described options, true usage."""

import subprocess
import sys

import pytest

pytest.importorskip("rclpy")

from skin_sim_node.device.bridge import BridgeNode
from skin_sim_node.device.mock_tool import MockToolNode
from skin_sim_node.device.sim_device import SimDeviceNode

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


def test_contact_model_message_round_trip_and_stale_tick():
    from types import SimpleNamespace

    import numpy as np
    from skin_sim_msgs.msg import ContactModel

    from msgs_schema.contact_model import STALE_RADIUS_M, fill_contact_model_from_tick, read_contact_model
    from skin_sim_node.model.contact import ContactTangent

    K = np.arange(9.0).reshape(3, 3) - 4
    tg = ContactTangent(np.array([0.1, 0.0, 1.2]), K, -0.5 * np.eye(3), np.array([0.0, 0.0, 1.0]), 2.5e-3)
    tick = SimpleNamespace(
        seq=7, x0_m=(0.001, 0.0, -0.002), velocity_m_s=(0.0, 0.0, -0.01), force_n=(0.1, 0.0, 1.1), stale=False, tangent=tg
    )
    m = read_contact_model(fill_contact_model_from_tick(ContactModel(), tick, 1_700_000_000_123_456_789, "tissue"))
    assert (m.sequence, m.stamp_ns, m.frame_id) == (7, 1_700_000_000_123_456_789, "tissue")
    np.testing.assert_array_equal(m.stiffness_n_per_m, K)
    np.testing.assert_array_equal(m.f0_n, tick.force_n)  # the published force, not the raw tangent's
    assert m.finite and m.validity_radius_m < 1.0
    stale = read_contact_model(
        fill_contact_model_from_tick(ContactModel(), SimpleNamespace(**{**vars(tick), "stale": True}), 0, "tissue")
    )
    assert stale.validity_radius_m == STALE_RADIUS_M and not stale.stiffness_n_per_m.any() and not stale.f0_n.any()


def test_bad_node_ns_is_a_one_line_error(capsys):
    assert BridgeNode.main(["--node-ns", "1skin"]) == 2
    out = capsys.readouterr().out
    assert "is not a ROS name" in out and out.count("\n") == 1


def test_node_ns_moves_only_the_node_topics():
    """``--node-ns /skin1`` with a process-wide ``-r __ns:=/rig``: the device topics follow the process namespace, the
    node's topics the option (before, ``-r __ns:=`` moved both). Builds the node only: no DDS traffic, no timing."""
    import rclpy

    ros_args = ["--ros-args", "-r", "__ns:=/rig"]
    ctx = rclpy.Context()
    rclpy.init(args=ros_args, context=ctx)
    BridgeNode.ROS_ARGS = ros_args
    bridge = BridgeNode({"node_ns": "skin1", "rt_priority": 0}, context=ctx)
    try:
        device_topics = {name for name, _ in bridge.get_topic_names_and_types()} | {s.topic_name for s in bridge.subscriptions}
        assert "/rig/device/measured_cp" in device_topics
        assert bridge.server.node.get_namespace() == "/skin1"
        link = {s.topic_name for s in bridge.server.node.subscriptions} | {p.topic_name for p in bridge.server.node.publishers}
        assert {"/skin1/tool/contact_model", "/skin1/tool/pose"} <= link
    finally:
        bridge.stop()
        bridge.destroy_node()
        rclpy.try_shutdown(context=ctx)
        BridgeNode.ROS_ARGS = []


def test_a_journal_without_the_node_is_a_one_line_error(capsys):
    """``--journal`` is the composed node's (``--with-node``); alone it stops the command with one line."""
    assert BridgeNode.main(["--journal", "/tmp/x.npz"]) == 2
    out = capsys.readouterr().out
    assert "--journal needs --with-node" in out and out.count("\n") == 1
