"""The tool seam is real (issue 28): a toy tool defined here alone runs through the session, the node and the bridge's law.

:class:`RigidPlane` is a rigid plate parallel to the sheet: a penalty wall ``F = k d`` along ``+z`` at the depth ``d``
below the rest surface, ``K = -k z z^T``, no damping, no friction. Nothing outside this file knows it: the node is
given it by the tool registry (``skin_sim_node.tools.TOOLS``, patched for the test), as a new module under ``tools/``
would be, and the device side renders it from the contact model message alone. No wall clock: the node's own clock
thread is stopped and every pose is fed to its subscription callback with stamps 1 ms apart.
"""

from __future__ import annotations

import time

import numpy as np
import pytest
from conftest import node_in_process

from msgs_schema.contact_model import fill_contact_model_from_tick, read_contact_model
from msgs_schema.parameters import SessionParams
from skin_sim_node import tools
from skin_sim_node.device.render import ContactRenderer
from skin_sim_node.model import FLAG_CONTACT, Indenter, TissueConfig, normal_tangent, preset
from skin_sim_node.session import HapticSession
from skin_sim_node.tools import Tool, ToolNeeds, ToolPose, ToolStep

K_PLANE_N_PER_M = 400.0
"""The toy wall's stiffness (N/m)."""
MS = 1_000_000


class RigidPlane(Tool):
    """A rigid plate pressing the whole sheet: ``F = k d`` along ``+z`` (module docstring). The tissue is stepped under a
    punch of ``tool.radius_m`` for its deformation only (the display's), as the needle steps it."""

    needs = ToolNeeds(orientation=False, rises_only=False, friction=False)
    steps = 0

    @classmethod
    def indenter(cls, cfg: TissueConfig) -> Indenter:
        return Indenter(cfg.tool_radius_m)

    def step(self, pose: ToolPose) -> ToolStep:
        RigidPlane.steps += 1
        t = self.tissue
        t.step(pose.position_m, pose.velocity_m_s, pose.dt_s, pose.restart)
        depth = max(-pose.position_m[2], 0.0)
        f = K_PLANE_N_PER_M * depth
        tangent = normal_tangent(f, K_PLANE_N_PER_M, 0.0, 1.0) if depth > 0.0 else None
        return ToolStep(
            force_n=np.array([0.0, 0.0, f]),
            tangent=tangent,
            flags=FLAG_CONTACT if depth > 0.0 else 0,
            idle=t.last_tick_idle,
            depth_m=depth,
            n_affected=0,
            compression_m=(0.0,) * len(self.cfg.layers),
            stress_pa=0.0,
        )


def _press(s_on_pose, s_tick, depths_m):
    """Feed one pose per depth (stamps 1 ms apart, straight down) and tick once per pose; the tick results."""
    out = []
    for k, d in enumerate(depths_m, start=1):
        assert s_on_pose(k * MS, (0.0, 0.0, -d)) is None
        out.append(s_tick(k * MS))
    return out


def _render_at(result, dx_m: float) -> np.ndarray:
    """The bridge's law: the tick's contact model message read back and rendered ``dx_m`` below its pose."""
    from skin_sim_msgs.msg import ContactModel

    m = read_contact_model(fill_contact_model_from_tick(ContactModel(), result, result.stamp_ns, "tissue"))
    r = ContactRenderer(max_force_n=np.inf, max_stiffness_n_per_m=np.inf)
    assert r.set_model(m, 0.0) is None
    x = np.array(result.x0_m) + [0.0, 0.0, -dx_m]
    return r.render(0.05, x)  # past the first model's crossfade, within its time-to-live


def test_a_toy_tool_runs_through_the_session_and_the_bridge_law():
    s = HapticSession(RigidPlane(preset("default")), SessionParams(max_stamp_age_s=0.0, max_force_rate_n_per_s=0.0))
    res = _press(
        lambda st, xyz: s.on_pose(st, "tissue", xyz),
        lambda st: s.tick(st, MS),
        np.linspace(0.0, 2e-3, 21),
    )
    r = res[-1]
    assert r.force_n == pytest.approx((0.0, 0.0, K_PLANE_N_PER_M * 2e-3), abs=1e-12)
    assert r.tangent.stiffness_n_per_m[2, 2] == pytest.approx(-K_PLANE_N_PER_M)
    assert r.tangent.friction_coefficient == 0.0 and r.tangent.needle is None  # friction off: declared
    assert s.readout() is None
    # the session's limits scale it like any tool's: a clamp at half the force halves f0 and K
    clamped = HapticSession(RigidPlane(preset("default")), SessionParams(max_stamp_age_s=0.0, max_force_n=0.4))
    rc = _press(lambda st, xyz: clamped.on_pose(st, "tissue", xyz), lambda st: clamped.tick(st, MS), [2e-3])[-1]
    assert rc.force_z_n == pytest.approx(0.4) and rc.tangent.stiffness_n_per_m[2, 2] == pytest.approx(-0.5 * K_PLANE_N_PER_M)
    # the device renders the plane's law from the contact model alone: 0.1 mm deeper, k * 0.1 mm more
    f = _render_at(r, 1e-4)
    assert f == pytest.approx([0.0, 0.0, K_PLANE_N_PER_M * 2.1e-3], abs=1e-9)


@pytest.mark.ros
@pytest.mark.usefixtures("ros_domain")
def test_a_toy_tool_runs_through_the_node(monkeypatch):
    """The node class in-process with rclpy: it builds, warms up and ticks the toy tool through its pose callback, and
    creates no read-out publisher for a tool that declares none."""
    pytest.importorskip("rclpy")
    from geometry_msgs.msg import PoseStamped
    from rclpy.serialization import serialize_message

    from msgs_schema import convert as cv

    monkeypatch.setitem(tools.TOOLS, "flat", RigidPlane)  # the registry entry a tools/ module would add
    # the stamp-age check off, the watchdog at its largest: no stall between two fed poses fires it
    with node_in_process(max_stamp_age_s=0.0, watchdog_s=10.0) as node:
        assert type(node.session.tool) is RigidPlane and node.hands[0].readouts == {}
        pose = PoseStamped()
        base = time.time_ns() - 1_000_000_000  # stamps in the past: the stamp-age check is off (max_stamp_age_s 0)

        def on_pose(stamp, xyz):
            node._on_pose(serialize_message(cv.fill_pose(pose, base + stamp, "tissue", xyz)))

        before = RigidPlane.steps
        res = _press(on_pose, lambda st: node._last, np.linspace(0.0, 2e-3, 21))
        assert RigidPlane.steps - before == 21  # one tool step per answered pose
        r = res[-1]
        assert r.answered and r.force_n == pytest.approx((0.0, 0.0, K_PLANE_N_PER_M * 2e-3), abs=1e-12)
        assert _render_at(r, 1e-4) == pytest.approx([0.0, 0.0, K_PLANE_N_PER_M * 2.1e-3], abs=1e-9)
