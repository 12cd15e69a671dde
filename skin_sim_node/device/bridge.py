"""Device bridge: a Geomagic Touch (Phantom Omni) ROS 2 driver <-> skin_sim_node.

Device side, under the ``device_ns`` parameter (relative, default ``device``):

- ``convention:=crtk`` (jhu-saw sawSensablePhantom): reads ``measured_cp`` (PoseStamped) and
  ``measured_cv`` (TwistStamped), writes ``servo_cf`` (WrenchStamped).
- ``convention:=omni`` (omni_common family, e.g. AleBarte Geomagic_Touch_ROS2_Drivers): reads
  ``phantom/pose`` (PoseStamped), writes ``phantom/force_feedback`` (WrenchStamped). No twist:
  the node differentiates the poses. Remap the names to match a given driver.

Node side: publishes ``tool/pose`` and ``tool/twist`` in the tissue frame, subscribes
``tool/wrench``. Every message is republished inside the callback that receives it (no
timer in the data path). A watchdog timer sends one zero force when the device pose or
the node's wrench is older than ``watchdog_s``; wrenches are not forwarded while the
device pose is stale.

The pure part (:class:`DeviceMapping`) imports no ROS code; :class:`BridgeNode` is
built on first access.
"""

from __future__ import annotations

import argparse
import math
from dataclasses import dataclass

Vec3 = tuple[float, float, float]

TOUCH_PEAK_FORCE_N = 3.3
"""Peak force of a Geomagic Touch (3D Systems spec sheet: max exertable force 3.3 N at nominal position)."""

DEFAULT_OFFSET_M: Vec3 = (0.0, 0.0, 0.05)
"""Tissue-frame position of the device origin (m). Matches :mod:`skin_sim_node.device.sim_device`,
whose origin sits 50 mm above the rest surface: about a Touch's usable workspace half-height
(workspace 160 x 120 x 70 mm), so the stylus reaches the tissue from mid-workspace."""


def axes_matrix(axes: str) -> tuple[Vec3, Vec3, Vec3]:
    """Signed permutation matrix ``R`` (rows = tissue x, y, z) from a string like ``"x-zy"``.

    Each of the three tokens, an optional ``-`` and a device axis letter, says which device
    axis (with sign) the tissue axis is: ``"x-zy"`` means tissue x = device x, tissue y =
    -device z, tissue z = device y (a Touch's frame has y up and z towards the user).

    Raises
    ------
    ValueError
        If the string is not three signed, distinct axes.
    """
    tokens, sign = [], 1.0
    for ch in axes.replace(" ", "").lower():
        if ch in "+-":
            sign = -1.0 if ch == "-" else 1.0
            continue
        if ch not in "xyz":
            raise ValueError(f"axes {axes!r}: unexpected character {ch!r}")
        tokens.append((sign, "xyz".index(ch)))
        sign = 1.0
    if len(tokens) != 3 or sorted(j for _, j in tokens) != [0, 1, 2]:
        raise ValueError(f"axes {axes!r}: need each of x, y, z exactly once, e.g. 'xyz' or 'x-zy'")
    rows = []
    for s, j in tokens:
        row = [0.0, 0.0, 0.0]
        row[j] = s
        rows.append(tuple(row))
    return tuple(rows)


def _mat_vec(R, v) -> Vec3:
    return tuple(R[i][0] * v[0] + R[i][1] * v[1] + R[i][2] * v[2] for i in range(3))


def _mat_t_vec(R, v) -> Vec3:
    return tuple(R[0][j] * v[0] + R[1][j] * v[1] + R[2][j] * v[2] for j in range(3))


def _det(R) -> float:
    return (
        R[0][0] * (R[1][1] * R[2][2] - R[1][2] * R[2][1])
        - R[0][1] * (R[1][0] * R[2][2] - R[1][2] * R[2][0])
        + R[0][2] * (R[1][0] * R[2][1] - R[1][1] * R[2][0])
    )


def _quat_from_rot(R) -> tuple[float, float, float, float]:
    """(x, y, z, w) of a proper rotation matrix (Shepperd's method)."""
    tr = R[0][0] + R[1][1] + R[2][2]
    if tr > 0:
        s = 2.0 * math.sqrt(tr + 1.0)
        return ((R[2][1] - R[1][2]) / s, (R[0][2] - R[2][0]) / s, (R[1][0] - R[0][1]) / s, 0.25 * s)
    i = max(range(3), key=lambda k: R[k][k])
    j, k = (i + 1) % 3, (i + 2) % 3
    s = 2.0 * math.sqrt(max(1.0 + R[i][i] - R[j][j] - R[k][k], 0.0))
    q = [0.0, 0.0, 0.0, 0.0]
    q[i] = 0.25 * s
    q[j] = (R[j][i] + R[i][j]) / s
    q[k] = (R[k][i] + R[i][k]) / s
    q[3] = (R[k][j] - R[j][k]) / s
    return tuple(q)


def _quat_mul(a, b):
    ax, ay, az, aw = a
    bx, by, bz, bw = b
    return (
        aw * bx + ax * bw + ay * bz - az * by,
        aw * by - ax * bz + ay * bw + az * bx,
        aw * bz + ax * by - ay * bx + az * bw,
        aw * bw - ax * bx - ay * by - az * bz,
    )


def _finite(v) -> bool:
    return all(math.isfinite(c) for c in v)


@dataclass(frozen=True)
class DeviceMapping:
    """Device frame <-> tissue frame: ``p_tissue = scale * R p_device + offset_m``.

    Parameters
    ----------
    offset_m : tuple of float
        Tissue-frame position of the device origin (m). Default: :data:`DEFAULT_OFFSET_M`.
    scale : float
        Motion scale (tissue metres per device metre), > 0.
    axes : str
        Axis convention, see :func:`axes_matrix`.
    force_scale : float
        ``F_device = force_scale * R^T F_tissue`` before the clamp, >= 0.
    max_force_n : float
        Clamp of the device force magnitude (direction kept). Default: a Touch's peak force.
    """

    offset_m: Vec3 = DEFAULT_OFFSET_M
    scale: float = 1.0
    axes: str = "xyz"
    force_scale: float = 1.0
    max_force_n: float = TOUCH_PEAK_FORCE_N

    def __post_init__(self):
        object.__setattr__(self, "offset_m", tuple(float(c) for c in self.offset_m))
        if len(self.offset_m) != 3 or not _finite(self.offset_m):
            raise ValueError(f"offset_m must be 3 finite numbers, got {self.offset_m}")
        if not (math.isfinite(self.scale) and self.scale > 0):
            raise ValueError(f"scale must be finite and > 0, got {self.scale}")
        if not (math.isfinite(self.force_scale) and self.force_scale >= 0):
            raise ValueError(f"force_scale must be finite and >= 0, got {self.force_scale}")
        if not (math.isfinite(self.max_force_n) and self.max_force_n >= 0):
            raise ValueError(f"max_force_n must be finite and >= 0, got {self.max_force_n}")
        R = axes_matrix(self.axes)
        object.__setattr__(self, "R", R)
        object.__setattr__(self, "_q", _quat_from_rot(R) if _det(R) > 0 else None)

    @property
    def proper(self) -> bool:
        """True if ``R`` is a rotation (det +1); an improper convention cannot map orientations."""
        return self._q is not None

    def to_tissue(self, p_device) -> Vec3:
        """Device position (m) -> tissue position (m)."""
        r = _mat_vec(self.R, p_device)
        return tuple(self.scale * r[i] + self.offset_m[i] for i in range(3))

    def to_device(self, p_tissue) -> Vec3:
        """Tissue position (m) -> device position (m); inverse of :meth:`to_tissue`."""
        d = tuple((p_tissue[i] - self.offset_m[i]) / self.scale for i in range(3))
        return _mat_t_vec(self.R, d)

    def velocity_to_tissue(self, v_device) -> Vec3:
        r = _mat_vec(self.R, v_device)
        return tuple(self.scale * c for c in r)

    def velocity_to_device(self, v_tissue) -> Vec3:
        return tuple(c / self.scale for c in _mat_t_vec(self.R, v_tissue))

    def orientation_to_tissue(self, q_device) -> tuple[float, float, float, float]:
        """Device orientation quaternion (x, y, z, w) -> tissue; identity for an improper ``R``."""
        if self._q is None or not _finite(q_device):
            return (0.0, 0.0, 0.0, 1.0)
        return _quat_mul(self._q, q_device)

    def force_to_device(self, f_tissue) -> Vec3:
        """Tissue force (N) -> device force command (N): ``force_scale * R^T f``, magnitude clamped.

        A non-finite input gives zero force.
        """
        if not _finite(f_tissue):
            return (0.0, 0.0, 0.0)
        f = tuple(self.force_scale * c for c in _mat_t_vec(self.R, f_tissue))
        return clamp_magnitude(f, self.max_force_n)


def clamp_magnitude(f, max_n: float) -> Vec3:
    """``f`` scaled down to magnitude ``max_n`` if longer (direction kept); non-finite -> zero."""
    if not _finite(f):
        return (0.0, 0.0, 0.0)
    mag = math.sqrt(f[0] * f[0] + f[1] * f[1] + f[2] * f[2])
    if mag > max_n:
        k = max_n / mag
        return (f[0] * k, f[1] * k, f[2] * k)
    return (float(f[0]), float(f[1]), float(f[2]))


# --- ROS node ---------------------------------------------------------------------------
def publish_while_ok(node, pub, msg) -> bool:
    """Publish ``msg``; if rclpy was shut down meanwhile (SIGTERM mid-callback), drop it quietly.

    Returns True if published. Errors while the context is still valid propagate.
    """
    try:
        pub.publish(msg)
        return True
    except Exception:
        if node.context.ok():
            raise
        return False


HOUSEKEEPING_PERIOD_S = 0.05
"""Period of a timer in the loop-thread nodes (mock tool, simulated device). It wakes the executor so
that ``run_nodes``' Python-level SIGTERM handler runs within 50 ms even when no message arrives (the
main thread otherwise sleeps in the wait set and never runs it), and it ends the process from the
executor thread when the script is done."""

EXECUTOR = "events"  # run_nodes drives it with spin_once(timeout): far less CPU per callback
"""rclpy executor for :func:`run_nodes`. Not ``events``: with the rclpy 7.1.6 wheels its ``spin()``
ignores context shutdown (SIGINT/SIGTERM never return) and, in a local test, fired no timers."""

DEFAULTS = {
    "convention": "crtk",
    "device_ns": "device",
    "offset_m": list(DEFAULT_OFFSET_M),
    "scale": 1.0,
    "axes": "xyz",  # the simulated device's axes; a real Touch in its base frame: "x-zy"
    "force_scale": 1.0,
    "max_force_n": TOUCH_PEAK_FORCE_N,
    "watchdog_s": 0.05,  # as the node's watchdog: 50 ticks at 1 kHz, past DDS jitter, under hand reaction time
    "watchdog_rate_hz": 200.0,  # checks every 5 ms: a stale input is caught within 0.1 * watchdog_s
    "device_frame": "",  # frame_id of force commands; empty: the device pose's frame_id
    "restamp": False,  # stamp tool/pose with the bridge's clock instead of the driver's
}
CONVENTIONS = {
    # convention: (pose key, twist key or None, force key)
    "crtk": ("crtk_measured_cp", "crtk_measured_cv", "crtk_servo_cf"),
    "omni": ("omni_pose", None, "omni_force"),
}


def _build_node_class():
    import time

    from geometry_msgs.msg import PoseStamped, TwistStamped, WrenchStamped
    from rcl_interfaces.msg import FloatingPointRange, ParameterDescriptor
    from rclpy.node import Node

    from msgs_schema.convert import fill_pose, fill_twist, fill_wrench, read_pose, read_twist, read_wrench, stamp_ns
    from msgs_schema.qos import PROFILES, publisher, subscription
    from msgs_schema.topics import FRAMES, TOPICS

    from ..ros_util import ros_now_ns

    def frange(lo, hi):
        return [FloatingPointRange(from_value=float(lo), to_value=float(hi))]

    class BridgeNode(Node):
        """Republishes device poses as tool poses and node wrenches as device force commands.

        Parameters
        ----------
        overrides : dict, optional
            Parameter defaults (e.g. from argparse); ``--ros-args -p`` still wins.
        """

        def __init__(self, overrides: dict | None = None, **kwargs):
            super().__init__("skin_sim_bridge", **kwargs)
            d = {**DEFAULTS, **(overrides or {})}

            def desc(**kw):  # all read once at start: read-only, so a live change cannot silently do nothing
                return ParameterDescriptor(read_only=True, **kw)

            self.declare_parameter("convention", d["convention"], desc(description="crtk | omni"))
            self.declare_parameter("device_ns", d["device_ns"], desc(description="namespace of the device topics (relative)"))
            self.declare_parameter(
                "offset_m", [float(c) for c in d["offset_m"]], desc(description="tissue position of the device origin (m)")
            )
            self.declare_parameter(
                "scale", float(d["scale"]), desc(description="tissue m per device m", floating_point_range=frange(1e-3, 1e3))
            )
            self.declare_parameter("axes", d["axes"], desc(description="tissue x,y,z as signed device axes, e.g. xyz, x-zy"))
            self.declare_parameter(
                "force_scale",
                float(d["force_scale"]),
                desc(description="F_device = force_scale R^T F_tissue", floating_point_range=frange(0, 100)),
            )
            self.declare_parameter(
                "max_force_n",
                float(d["max_force_n"]),
                desc(description="device force clamp (N); Touch peak 3.3 N", floating_point_range=frange(0, 100)),
            )
            self.declare_parameter(
                "watchdog_s",
                float(d["watchdog_s"]),
                desc(description="input age that zeroes the force (s)", floating_point_range=frange(1e-3, 10)),
            )
            self.declare_parameter(
                "watchdog_rate_hz",
                float(d["watchdog_rate_hz"]),
                desc(description="watchdog check rate (Hz)", floating_point_range=frange(1, 10000)),
            )
            self.declare_parameter(
                "device_frame", d["device_frame"], desc(description="frame_id of force commands; empty: the device pose's")
            )
            self.declare_parameter("restamp", bool(d["restamp"]), desc(description="stamp tool poses with the bridge clock"))
            gp = self.get_parameter
            conv = gp("convention").value
            if conv not in CONVENTIONS:
                raise ValueError(f"convention {conv!r}: choose one of {', '.join(CONVENTIONS)}")
            self.mapping = DeviceMapping(
                tuple(gp("offset_m").value), gp("scale").value, gp("axes").value, gp("force_scale").value, gp("max_force_n").value
            )
            if not self.mapping.proper:
                self.get_logger().warn(f"axes {self.mapping.axes!r} is a reflection: tool orientation is published as identity")
            self.watchdog_ns = int(gp("watchdog_s").value * 1e9)
            self.restamp = gp("restamp").value
            self.device_frame = gp("device_frame").value
            self.tissue_frame = FRAMES["tissue"]
            ns = gp("device_ns").value.strip("/")
            pose_key, twist_key, force_key = CONVENTIONS[conv]

            def dev(key):
                return f"{ns}/{TOPICS[key].name}" if ns else TOPICS[key].name

            self._pose_out, self._twist_out, self._force_out = PoseStamped(), TwistStamped(), WrenchStamped()
            self._pose_pub = publisher(self, "tool_pose")
            self._twist_pub = publisher(self, "tool_twist") if twist_key else None
            self._force_pub = self.create_publisher(WrenchStamped, dev(force_key), PROFILES["driver"])
            subscription(self, pose_key, self._on_device_pose, name=dev(pose_key))
            if twist_key:
                subscription(self, twist_key, self._on_device_twist, name=dev(twist_key))
            subscription(self, "tool_wrench", self._on_wrench)
            self.last_pose_rx_ns: int | None = None
            self.last_wrench_rx_ns: int | None = None
            self.stale = False  # the first watchdog check sends one zero force
            self.counts = {"poses": 0, "twists": 0, "wrenches": 0, "forwarded": 0, "zeros": 0, "non_finite_pose": 0}
            self.create_timer(1.0 / gp("watchdog_rate_hz").value, self._watchdog)
            self.get_logger().info(
                f"bridge {conv}: {dev(pose_key)} -> {TOPICS['tool_pose'].name}; {TOPICS['tool_wrench'].name} -> "
                f"{dev(force_key)}; offset {self.mapping.offset_m} m, scale {self.mapping.scale}, axes {self.mapping.axes}, "
                f"clamp {self.mapping.max_force_n} N"
            )

        def _stamp(self, msg) -> int:
            s = stamp_ns(msg.header)
            return ros_now_ns(self) if self.restamp or s == 0 else s

        def _on_device_pose(self, msg) -> None:
            _, frame, p = read_pose(msg)
            if not _finite(p):
                self.counts["non_finite_pose"] += 1
                return
            self.last_pose_rx_ns = time.monotonic_ns()
            if not self.device_frame and frame:
                self.device_frame = frame
            o = msg.pose.orientation
            q = self.mapping.orientation_to_tissue((o.x, o.y, o.z, o.w))
            out = fill_pose(self._pose_out, self._stamp(msg), self.tissue_frame, self.mapping.to_tissue(p), q)
            publish_while_ok(self, self._pose_pub, out)
            self.counts["poses"] += 1

        def _on_device_twist(self, msg) -> None:
            _, _, v = read_twist(msg)
            if not _finite(v):
                return
            out = fill_twist(self._twist_out, self._stamp(msg), self.tissue_frame, self.mapping.velocity_to_tissue(v))
            publish_while_ok(self, self._twist_pub, out)
            self.counts["twists"] += 1

        def _on_wrench(self, msg) -> None:
            now = time.monotonic_ns()
            self.last_wrench_rx_ns = now
            self.counts["wrenches"] += 1
            if self.last_pose_rx_ns is None or now - self.last_pose_rx_ns > self.watchdog_ns:
                return  # device pose stale: the watchdog has commanded zero
            t_ns, _, f = read_wrench(msg)
            self._publish_force(t_ns or ros_now_ns(self), self.mapping.force_to_device(f))
            self.counts["forwarded"] += 1

        def _publish_force(self, t_ns: int, f) -> None:
            publish_while_ok(self, self._force_pub, fill_wrench(self._force_out, t_ns, self.device_frame or "device_base", f))

        def _watchdog(self) -> None:
            now = time.monotonic_ns()
            pose_stale = self.last_pose_rx_ns is None or now - self.last_pose_rx_ns > self.watchdog_ns
            wrench_stale = self.last_wrench_rx_ns is None or now - self.last_wrench_rx_ns > self.watchdog_ns
            stale = pose_stale or wrench_stale
            if stale and not self.stale:
                self._publish_force(ros_now_ns(self), (0.0, 0.0, 0.0))
                self.counts["zeros"] += 1
                if self.counts["poses"] or self.counts["wrenches"]:
                    what = "device pose" if pose_stale else "node wrench"
                    self.get_logger().warn(f"no {what} for {self.watchdog_ns * 1e-6:.0f} ms: device force set to zero")
            self.stale = stale

        def stop(self) -> None:
            c = self.counts
            self.get_logger().info(
                f"bridge stopping: {c['poses']} device poses, {c['twists']} twists, {c['wrenches']} wrenches "
                f"({c['forwarded']} forwarded), {c['zeros']} watchdog zero commands, {c['non_finite_pose']} non-finite poses"
            )

    return BridgeNode


def __getattr__(name: str):
    if name == "BridgeNode":
        cls = _build_node_class()
        globals()["BridgeNode"] = cls
        return cls
    raise AttributeError(f"module {__name__!r} has no attribute {name!r}")


def _vec3(text: str) -> list[float]:
    v = [float(c) for c in text.replace(",", " ").split()]
    if len(v) != 3:
        raise argparse.ArgumentTypeError(f"expected 3 numbers, got {text!r}")
    return v


def main(argv=None) -> int:
    """``bridge [--convention crtk|omni] [--device-ns NS] [--offset-m 'x y z'] [--axes xyz] ... [--ros-args ...]``."""
    ap = argparse.ArgumentParser(prog="bridge", description=__doc__.splitlines()[0])
    ap.add_argument("--convention", choices=sorted(CONVENTIONS))
    ap.add_argument("--device-ns", help="namespace of the device topics (default 'device'; '' for none)")
    ap.add_argument("--offset-m", type=_vec3, help="tissue position of the device origin, 'x y z' (m)")
    ap.add_argument("--scale", type=float, help="tissue m per device m")
    ap.add_argument("--axes", help="tissue x, y, z as signed device axes, e.g. xyz or x-zy")
    ap.add_argument("--force-scale", type=float)
    ap.add_argument("--max-force-n", type=float)
    ap.add_argument("--watchdog-s", type=float)
    opts, rest = ap.parse_known_args(argv)
    overrides = {k: v for k, v in vars(opts).items() if v is not None}
    if "axes" in overrides:
        axes_matrix(overrides["axes"])  # fail early with a clear message
    from ..ros_util import run_nodes

    cls = _build_node_class()
    return run_nodes([lambda: cls(overrides)], args=rest, executor=EXECUTOR)


if __name__ == "__main__":
    raise SystemExit(main())
