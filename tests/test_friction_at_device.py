"""Friction reaches the hand (issue 19): a 10 mm/s drag at 1 mm through the session, the contact model message and
the bridge's renderer (the device stepped by the test, no DDS): the tangential force the device is commanded is
mu times the normal force within 5 % and opposes the motion."""

from __future__ import annotations

import numpy as np
import pytest

pytest.importorskip("skin_sim_msgs")

from skin_sim_msgs.msg import ContactModel

from msgs_schema.contact_model import fill_contact_model_from_tick, read_contact_model
from skin_sim_node.device.render import ContactRenderer
from skin_sim_node.session import HapticSession, SessionParams
from skin_sim_node.tools import make_tool

MS = 1_000_000
T0 = 1_700_000_000 * 1_000_000_000


@pytest.mark.parametrize("direction", [(1.0, 0.0), (0.0, -1.0), (0.6, 0.8)])
def test_drag_at_1mm_renders_mu_times_the_normal_force_against_the_motion(default_cfg, direction):
    mu = default_cfg.friction_coefficient
    s = HapticSession(make_tool(default_cfg), SessionParams(max_stamp_age_s=0.0))
    renderer = ContactRenderer()
    msg = ContactModel()
    u = np.array([*direction, 0.0])
    speed = 0.01  # 10 mm/s
    ratios = []
    for i in range(1500):  # press to 1 mm over 0.5 s, then drag for 1 s
        stamp = T0 + i * MS
        t = i * 1e-3
        z = -1e-3 * min(1.0, t / 0.5)
        xy = u[:2] * speed * max(0.0, t - 0.5)
        v = np.array([*(u[:2] * speed if t > 0.5 else (0.0, 0.0)), -2e-3 if t < 0.5 else 0.0])
        pos = (float(xy[0]), float(xy[1]), z)
        s.on_twist(stamp, "tissue", tuple(v))
        s.on_pose(stamp, "tissue", pos)
        r = s.tick(stamp, MS)
        m = read_contact_model(fill_contact_model_from_tick(msg, r, stamp, "tissue"))
        renderer.set_model(m, stamp * 1e-9)
        f = renderer.render(stamp * 1e-9 + 1e-4, pos, tuple(v))  # the device's next servo tick, at the same pose
        if t > 0.8:  # steady drag
            n = np.asarray(m.normal)
            fn = float(f @ n)
            ft = f - fn * n
            ratios.append((float(np.linalg.norm(ft)) / fn, float(ft @ u) / float(np.linalg.norm(ft))))
    ratio = np.array(ratios)
    assert np.all(np.abs(ratio[:, 0] / mu - 1.0) <= 0.05), (ratio[:, 0].min(), ratio[:, 0].max())
    assert np.all(ratio[:, 1] < -0.99)  # against the motion
