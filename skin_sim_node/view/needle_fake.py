"""A scripted needle for the view: publishes ``tool/pose``, ``tool/wrench``, ``tissue/layer_heights`` and
``tissue/needle`` as the node does with ``tool.shape`` 'needle', from a geometric script, not the model.

    python -m skin_sim_node.view.needle_fake --angle-deg 30 [--namespace /ns] [--loop]

It exists to test and show the view's needle drawing before (and independently of) the node's needle: the
track enters at the sheet's centre at ``--angle-deg`` from vertical, the interfaces are flat at the schema's default
rest depths, and each layer ruptures once its top's dimple along the axis passes an illustrative threshold
(:data:`FAKE_RUPTURE_DIMPLE_M`). The forces are illustrative too (``FAKE_*`` below): no number it publishes is a
result of the tissue model. The insertion: from 2 mm above the surface along the axis down to ``--depth-mm`` along
the axis, hold, back out, at ``--speed-mm-s``.
"""

from __future__ import annotations

import argparse
import math
import time
from dataclasses import dataclass, field

import numpy as np

from .frames import default_thickness_m

FAKE_RUPTURE_DIMPLE_M = (1.0e-3, 0.6e-3, 0.5e-3)
"""Dimple along the axis at which each layer's top ruptures (epidermis, dermis, fat). Illustrative values for the
view only (the model's skin ruptures at a ~5 mm dimple, docs/needle.md); small so a short insertion punctures all."""
FAKE_DIMPLE_N_PER_M = 800.0  # illustrative axial stiffness of the dimple (N/m)
FAKE_CUTTING_N = 0.15  # illustrative cutting force while the tip advances in a punctured layer (N)
FAKE_FRICTION_N_PER_M = 30.0  # illustrative shaft friction per inserted length in punctured layers (N/m)
DIMPLE_SIGMA_M = 1.5e-3  # width of the Gaussian dimple drawn into the grid (illustrative)


@dataclass
class NeedleScript:
    """The scripted insertion: straight in along a fixed axis and back out, entry at the sheet's centre."""

    angle_deg: float = 30.0
    azimuth_deg: float = 0.0  # direction of the tilt in the x-y plane, from +x
    depth_m: float = 3.5e-3  # deepest tip travel along the axis from the entry
    start_m: float = -2.0e-3  # tip travel at the start (above the surface)
    speed_m_s: float = 2.0e-3
    hold_s: float = 1.0
    thickness_m: list[float] = field(default_factory=default_thickness_m)

    @property
    def axis(self) -> np.ndarray:
        a, b = math.radians(self.angle_deg), math.radians(self.azimuth_deg)
        return np.array([math.sin(a) * math.cos(b), math.sin(a) * math.sin(b), -math.cos(a)])

    @property
    def quaternion(self) -> tuple[float, float, float, float]:
        """(x, y, z, w) with R(q) (0, 0, -1) = :attr:`axis` (a tilt by the angle about the horizontal axis
        perpendicular to the azimuth; frames.pose_axis inverts it)."""
        a, b = math.radians(self.angle_deg), math.radians(self.azimuth_deg)
        # rotation axis u = (-sin b, cos b, 0) by -a: R (0, 0, -1) = (sin a cos b, sin a sin b, -cos a)
        s = math.sin(-a / 2)
        return (-math.sin(b) * s, math.cos(b) * s, 0.0, math.cos(-a / 2))

    @property
    def crossing_m(self) -> list[float]:
        """Axis length from the entry to each layer's top and the stack's bottom (flat interfaces at rest)."""
        tops = np.concatenate([[0.0], np.cumsum(self.thickness_m)])
        return [float(d / math.cos(math.radians(self.angle_deg))) for d in tops]

    @property
    def period_s(self) -> float:
        return 2 * (self.depth_m - self.start_m) / self.speed_m_s + 2 * self.hold_s

    def travel(self, t_s: float) -> tuple[float, float]:
        """(tip travel along the axis, its rate) at ``t_s`` into a cycle: in, hold, out, hold above."""
        ramp = (self.depth_m - self.start_m) / self.speed_m_s
        t = t_s % self.period_s
        if t < ramp:
            return self.start_m + self.speed_m_s * t, self.speed_m_s
        if t < ramp + self.hold_s:
            return self.depth_m, 0.0
        if t < 2 * ramp + self.hold_s:
            return self.depth_m - self.speed_m_s * (t - ramp - self.hold_s), -self.speed_m_s
        return self.start_m, 0.0

    def state(self, t_s: float) -> dict:
        """The NeedleState fields (and the pose) at ``t_s`` from the start of the script."""
        s, v = self.travel(t_s)
        cr, axis = self.crossing_m, self.axis
        inserted = s > 0.0
        # layers ruptured on this track: the deepest reached so far decides (the track is latched until withdrawn)
        ramp = (self.depth_m - self.start_m) / self.speed_m_s
        deepest = (s if (t_s % self.period_s) < ramp else self.depth_m) if inserted else 0.0
        k = 0
        while k < 3 and deepest > cr[k] + FAKE_RUPTURE_DIMPLE_M[k]:
            k += 1
        dimple = max(0.0, min(s - cr[k], FAKE_RUPTURE_DIMPLE_M[k])) if k < 3 and inserted else 0.0
        in_ruptured = max(0.0, min(s, cr[k] if k < 3 else s)) if inserted else 0.0
        cutting = FAKE_CUTTING_N if v > 0 and k > 0 and 0.0 < s <= cr[min(k, 3)] else 0.0
        friction = math.copysign(FAKE_FRICTION_N_PER_M * in_ruptured, v) if v and k > 0 else 0.0
        dimple_f = FAKE_DIMPLE_N_PER_M * dimple
        axial = dimple_f + cutting + friction
        return {
            "inserted": inserted,
            "tip_m": (axis * s).tolist(),
            "axis": axis.tolist(),
            "entry_m": [0.0, 0.0, 0.0],
            "insertion_m": max(0.0, s),
            "dimple_m": dimple,
            "ruptured_layers": k,
            "crossing_m": cr,
            "dimple_force_n": dimple_f,
            "cutting_force_n": cutting,
            "friction_force_n": friction,
            "force_n": (-axial * axis).tolist(),
            "quaternion": self.quaternion,
            "next_layer": k,
        }

    def grid(self, st: dict, nx: int, ny: int, sheet_m: tuple[float, float]) -> np.ndarray:
        """Layer heights (ny, nx, 3): flat at rest, the next intact layer's top and those below dimpled under the tip."""
        tops = -np.concatenate([[0.0], np.cumsum(self.thickness_m)[:2]])
        xs = -sheet_m[0] / 2 + (np.arange(nx) + 0.5) * sheet_m[0] / nx
        ys = -sheet_m[1] / 2 + (np.arange(ny) + 0.5) * sheet_m[1] / ny
        g = np.empty((ny, nx, 3), np.float32)
        g[:] = tops
        if st["dimple_m"] > 0:
            tip = st["tip_m"]
            r2 = (xs[None, :] - tip[0]) ** 2 + (ys[:, None] - tip[1]) ** 2
            bowl = st["dimple_m"] * -st["axis"][2] * np.exp(-r2 / (2 * DIMPLE_SIGMA_M**2))
            for j in range(st["next_layer"], 3):
                g[..., j] -= bowl
        return g


def fill_needle(msg, st: dict, t_ns: int, frame: str = "tissue"):
    """A NeedleState message (rclpy or rosbags) from :meth:`NeedleScript.state`."""
    from msgs_schema import convert as cv

    cv.set_stamp(msg.header, t_ns)
    msg.header.frame_id = frame
    msg.inserted = bool(st["inserted"])
    for f in ("tip_m", "axis", "entry_m", "force_n"):
        setattr(msg, f, np.asarray(st[f], dtype=np.float64))
    for f in ("insertion_m", "dimple_m", "dimple_force_n", "cutting_force_n", "friction_force_n"):
        setattr(msg, f, float(st[f]))
    msg.ruptured_layers = int(st["ruptured_layers"])
    msg.crossing_m = np.asarray(st["crossing_m"], dtype=np.float64)
    return msg


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(prog="python -m skin_sim_node.view.needle_fake", description=__doc__.splitlines()[0])
    ap.add_argument("--namespace", default="")
    ap.add_argument("--angle-deg", type=float, default=30.0, help="insertion angle from vertical")
    ap.add_argument("--azimuth-deg", type=float, default=0.0, help="tilt direction in the x-y plane, from +x")
    ap.add_argument("--depth-mm", type=float, default=3.5, help="deepest tip travel along the axis")
    ap.add_argument("--speed-mm-s", type=float, default=2.0)
    ap.add_argument("--rate-hz", type=float, default=60.0, help="publish rate of every topic")
    ap.add_argument("--duration-s", type=float, help="stop after this long (default: until interrupted)")
    ap.add_argument("--stop-at-depth", action="store_true", help="stay at the deepest point once reached")
    args = ap.parse_args(argv)
    import rclpy

    from msgs_schema import convert as cv
    from msgs_schema.parameters import SPEC_BY_NAME
    from msgs_schema.qos import publisher
    from msgs_schema.topics import FRAMES, TOPICS

    script = NeedleScript(args.angle_deg, args.azimuth_deg, args.depth_mm * 1e-3, speed_m_s=args.speed_mm_s * 1e-3)
    sheet = (SPEC_BY_NAME["tissue.sheet.size_x_m"].default, SPEC_BY_NAME["tissue.sheet.size_y_m"].default)
    nx, ny = SPEC_BY_NAME["tissue.grid.nx"].default, SPEC_BY_NAME["tissue.grid.ny"].default
    rclpy.init()
    node = rclpy.create_node("skin_sim_needle_fake", namespace=args.namespace or "")
    pubs = {k: publisher(node, k) for k in ("tool_pose", "tool_wrench", "layer_heights", "needle")}
    msgs = {k: TOPICS[k].msg_class() for k in pubs}
    frame = FRAMES["tissue"]
    t0 = time.monotonic()
    ramp_s = (script.depth_m - script.start_m) / script.speed_m_s
    crossings = [round(c * 1e3, 3) for c in script.crossing_m]
    print(f"needle fake: {args.angle_deg:g} deg from vertical, crossings {crossings} mm", flush=True)
    try:
        while rclpy.ok():
            t = time.monotonic() - t0
            if args.duration_s is not None and t > args.duration_s:
                break
            st = script.state(min(t, ramp_s + 1e-9) if args.stop_at_depth else t)
            t_ns = time.time_ns()
            cv.fill_pose(msgs["tool_pose"], t_ns, frame, st["tip_m"], st["quaternion"])
            cv.fill_wrench(msgs["tool_wrench"], t_ns, frame, st["force_n"])
            cv.fill_image(msgs["layer_heights"], t_ns, frame, script.grid(st, nx, ny, sheet))
            fill_needle(msgs["needle"], st, t_ns, frame)
            for k, p in pubs.items():
                p.publish(msgs[k])
            time.sleep(1.0 / args.rate_hz)
    except KeyboardInterrupt:
        pass
    finally:
        node.destroy_node()
        rclpy.try_shutdown()
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
