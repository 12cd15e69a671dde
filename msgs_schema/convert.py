"""Converters between the contract's messages and plain numbers/arrays.

Readers use attribute access only, so they work on rclpy messages and on the
dataclasses that ``rosbags`` deserialises alike. Writers fill a message object the
caller owns (preallocated in the node), so the haptic path allocates no messages.
"""

from __future__ import annotations

import struct

import numpy as np

from .contact_model import fill_contact_model_from_tick  # noqa: F401 - the local contact model (issue 12)
from .tissue import LAYER_NAMES

NS = 1_000_000_000

# RGBA per layer for the mesh: epidermis, dermis, fat; rest (no contact) is skin tone.
LAYER_RGBA = ((0.95, 0.79, 0.65, 1.0), (0.85, 0.47, 0.48, 1.0), (0.96, 0.88, 0.56, 1.0))
REST_RGBA = (0.93, 0.80, 0.70, 1.0)


def stamp_ns(header) -> int:
    """A ``std_msgs/Header`` stamp in integer nanoseconds."""
    return int(header.stamp.sec) * NS + int(header.stamp.nanosec)


def set_stamp(header, t_ns: int) -> None:
    """Set ``header.stamp`` from integer nanoseconds."""
    header.stamp.sec, header.stamp.nanosec = divmod(int(t_ns), NS)


def read_pose(msg):
    """PoseStamped -> (stamp_ns, frame_id, (x, y, z))."""
    p = msg.pose.position
    return stamp_ns(msg.header), msg.header.frame_id, (p.x, p.y, p.z)


def read_twist(msg):
    """TwistStamped -> (stamp_ns, frame_id, (vx, vy, vz))."""
    v = msg.twist.linear
    return stamp_ns(msg.header), msg.header.frame_id, (v.x, v.y, v.z)


# --- raw CDR (the node's 1 kHz path) ------------------------------------------------------------------------
# rclpy turns each received message into Python objects (PoseStamped: 13.4 us here) and each published one back
# (WrenchStamped: ~4 us); at 1 kHz, with a twist beside every pose, that was a third of the node's time per pose
# beyond the bare echo's. The node takes pose and twist as serialized CDR and publishes the wrench serialized.
# Layout (OMG XCDR1, as rmw_fastrtps writes it): a 4-byte encapsulation header (0x00 0x01: little endian,
# 0x00 0x00: big endian), then, aligned relative to its end: std_msgs/Header (int32 sec, uint32 nanosec, uint32
# length incl. the NUL, the chars) and the first float64 vector (position, linear, force) on the next 8 bytes.


def _align8(n: int) -> int:
    return (n + 7) & ~7


def read_stamped_vec3_cdr(data: bytes):
    """Serialized PoseStamped or TwistStamped -> (stamp_ns, frame_id, first vector: position or linear).

    Raises ``ValueError`` with one line for a buffer that is not such a message.
    """
    if len(data) < 16 or data[0] != 0 or data[1] not in (0, 1):
        raise ValueError(f"not a CDR-encapsulated message ({len(data)} bytes)")
    e = "<" if data[1] == 1 else ">"
    sec, nsec, n = struct.unpack_from(e + "iII", data, 4)
    off = 4 + _align8(12 + n)
    if n == 0 or off + 24 > len(data):
        raise ValueError(f"truncated CDR message ({len(data)} bytes, frame_id of {n} bytes)")
    if data[15 + n] != 0:
        raise ValueError("malformed CDR message: frame_id is not NUL-terminated")
    frame = data[16 : 15 + n].decode("utf-8", "replace")
    return sec * NS + nsec, frame, struct.unpack_from(e + "3d", data, off)


def read_pose_cdr(data: bytes):
    """Serialized PoseStamped -> (stamp_ns, frame_id, position, orientation ``(x, y, z, w)``).

    Raises ``ValueError`` with one line for a buffer that is not such a message (as :func:`read_stamped_vec3_cdr`).
    """
    stamp, frame, xyz = read_stamped_vec3_cdr(data)
    e = "<" if data[1] == 1 else ">"
    off = 4 + _align8(12 + struct.unpack_from(e + "I", data, 12)[0]) + 24
    if off + 32 > len(data):
        raise ValueError(f"truncated CDR pose ({len(data)} bytes): no orientation")
    return stamp, frame, xyz, struct.unpack_from(e + "4d", data, off)


class WrenchCdr:
    """Serialized ``geometry_msgs/WrenchStamped`` for one frame, rewritten in place (no message objects)."""

    def __init__(self, frame: str):
        name = frame.encode() + b"\0"
        self._vec = 4 + _align8(12 + len(name))
        self._buf = bytearray(self._vec + 48)
        struct.pack_into("<4BI", self._buf, 0, 0, 1, 0, 0, 0)
        struct.pack_into(f"<I{len(name)}s", self._buf, 12, len(name), name)

    def fill(self, t_ns: int, force, torque=(0.0, 0.0, 0.0)) -> bytes:
        """The serialized message for stamp ``t_ns`` (ns) and ``force``/``torque`` (N, N m): the preallocated buffer, patched."""
        sec, nsec = divmod(int(t_ns), NS)
        struct.pack_into("<iI", self._buf, 4, sec, nsec)
        struct.pack_into("<6d", self._buf, self._vec, *force, *torque)
        return bytes(self._buf)

    def fill_from_tick(self, result, t_ns: int) -> bytes:
        """``tool/wrench`` from a haptic tick's result, as :func:`fill_wrench_from_tick` fills the message."""
        return self.fill(t_ns, result.force_n)


class PoseCdr:
    """Serialized ``geometry_msgs/PoseStamped`` for one frame, rewritten in place (the bridge's forwarded tool pose)."""

    def __init__(self, frame: str):
        name = frame.encode() + b"\0"
        self._vec = 4 + _align8(12 + len(name))
        self._buf = bytearray(self._vec + 56)
        struct.pack_into("<4BI", self._buf, 0, 0, 1, 0, 0, 0)
        struct.pack_into(f"<I{len(name)}s", self._buf, 12, len(name), name)

    def fill(self, t_ns: int, xyz, quat=(0.0, 0.0, 0.0, 1.0)) -> bytes:
        """The serialized pose for stamp ``t_ns`` (ns), position ``xyz`` (m) and orientation ``quat`` ``(x, y, z, w)``."""
        sec, nsec = divmod(int(t_ns), NS)
        struct.pack_into("<iI", self._buf, 4, sec, nsec)
        struct.pack_into("<7d", self._buf, self._vec, *xyz, *quat)
        return bytes(self._buf)


def read_wrench(msg):
    """WrenchStamped -> (stamp_ns, frame_id, (fx, fy, fz))."""
    f = msg.wrench.force
    return stamp_ns(msg.header), msg.header.frame_id, (f.x, f.y, f.z)


def fill_pose(msg, t_ns: int, frame: str, xyz, quat=(0.0, 0.0, 0.0, 1.0)):
    """Fill a ``PoseStamped`` the caller owns: stamp ``t_ns`` (ns), ``frame``, position ``xyz`` (m), ``quat`` (x, y, z, w)."""
    set_stamp(msg.header, t_ns)
    msg.header.frame_id = frame
    p = msg.pose.position
    p.x, p.y, p.z = (float(c) for c in xyz)
    o = msg.pose.orientation
    o.x, o.y, o.z, o.w = (float(c) for c in quat)
    return msg


def fill_twist(msg, t_ns: int, frame: str, linear, angular=(0.0, 0.0, 0.0)):
    """Fill a ``TwistStamped`` the caller owns: stamp ``t_ns`` (ns), ``frame``, ``linear`` (m/s), ``angular`` (rad/s)."""
    set_stamp(msg.header, t_ns)
    msg.header.frame_id = frame
    lin, ang = msg.twist.linear, msg.twist.angular
    lin.x, lin.y, lin.z = (float(c) for c in linear)
    ang.x, ang.y, ang.z = (float(c) for c in angular)
    return msg


def fill_wrench(msg, t_ns: int, frame: str, force, torque=(0.0, 0.0, 0.0)):
    """Fill a ``WrenchStamped`` the caller owns: stamp ``t_ns`` (ns), ``frame``, ``force`` (N), ``torque`` (N m)."""
    set_stamp(msg.header, t_ns)
    msg.header.frame_id = frame
    f, m = msg.wrench.force, msg.wrench.torque
    f.x, f.y, f.z = (float(c) for c in force)
    m.x, m.y, m.z = (float(c) for c in torque)
    return msg


def fill_contact(msg, t_ns: int, frame: str, compression_m, rate_m_s, stress_pa):
    """JointState: one entry per layer; position = compression, velocity = rate, effort = stress."""
    set_stamp(msg.header, t_ns)
    msg.header.frame_id = frame
    if len(msg.name) != len(LAYER_NAMES):
        msg.name = list(LAYER_NAMES)
    msg.position = [float(c) for c in compression_m]
    msg.velocity = [float(c) for c in rate_m_s]
    msg.effort = [float(c) for c in stress_pa]
    return msg


def fill_wrench_from_tick(msg, result, t_ns: int, frame: str):
    """``tool/wrench`` from a haptic tick's result (``skin_sim_node.session.TickResult``, read by attribute)."""
    return fill_wrench(msg, t_ns, frame, result.force_n)


def fill_contact_from_tick(msg, result, t_ns: int, frame: str):
    """``tissue/contact`` from a haptic tick's result: per layer compression, its rate and the Reuss stress."""
    return fill_contact(msg, t_ns, frame, result.compression_m, result.compression_rate_m_s, result.stress_pa)


def read_contact(msg):
    """``tissue/contact`` (``JointState``) -> (stamp ns, compression m, compression rate m/s, stress Pa), per layer."""
    return stamp_ns(msg.header), np.array(msg.position), np.array(msg.velocity), np.array(msg.effort)


def fill_image(msg, t_ns: int, frame: str, data: np.ndarray):
    """float32 image from (rows, cols) or (rows, cols, channels) metres."""
    arr = np.ascontiguousarray(data, dtype=np.float32)
    channels = 1 if arr.ndim == 2 else arr.shape[2]
    set_stamp(msg.header, t_ns)
    msg.header.frame_id = frame
    msg.height, msg.width = int(arr.shape[0]), int(arr.shape[1])
    msg.encoding = f"32FC{channels}"
    msg.is_bigendian = 0
    msg.step = int(arr.shape[1] * 4 * channels)
    msg.data = arr.tobytes()
    return msg


def read_image(msg) -> np.ndarray:
    """A ``32FC1``/``32FCn`` ``sensor_msgs/Image`` -> float64 array (rows, cols) or (rows, cols, n).

    Raises
    ------
    ValueError
        Any other encoding.
    """
    channels = int(msg.encoding[4:]) if msg.encoding.startswith("32FC") else 1
    if not msg.encoding.startswith("32FC"):
        raise ValueError(f"expected a 32FCn image, got encoding {msg.encoding!r}")
    arr = np.frombuffer(bytes(msg.data), dtype=">f4" if msg.is_bigendian else "<f4")
    shape = (msg.height, msg.width) if channels == 1 else (msg.height, msg.width, channels)
    return arr.reshape(shape).astype(np.float64)


def mesh_arrays(xs, ys, heights, layer_index, stride: int = 3, min_disp_m: float = 1e-6):
    """Triangle-list vertices (T*3, 3) and per-vertex RGBA (T*3, 4) of the deformed surface.

    Only the bounding box of cells deformed by more than ``min_disp_m`` is meshed at
    ``stride``; the rest of the sheet is four flat rectangles at z = 0 that tile it exactly.
    (rclpy builds one Python object per point: a full 120 x 120 mesh costs ~90 ms a frame.)
    ``layer_index`` (rows, cols) is the deepest affected layer under each cell (-1: rest).
    """
    deformed = np.abs(heights) > min_disp_m
    x0, x1 = xs[0], xs[-1]
    y0, y1 = ys[0], ys[-1]
    verts, cols = [], []
    if deformed.any():
        rows = np.flatnonzero(deformed.any(axis=1))
        cs = np.flatnonzero(deformed.any(axis=0))
        r0, r1 = max(rows[0] - 1, 0), min(rows[-1] + 1, len(ys) - 1)
        c0, c1 = max(cs[0] - 1, 0), min(cs[-1] + 1, len(xs) - 1)
        ri = np.unique(np.r_[np.arange(r0, r1, stride), r1])
        ci = np.unique(np.r_[np.arange(c0, c1, stride), c1])
        X, Y = np.meshgrid(xs[ci], ys[ri])
        v = np.stack([X, Y, heights[np.ix_(ri, ci)]], axis=-1)
        li = layer_index[np.ix_(ri, ci)]
        palette = np.array([*LAYER_RGBA, REST_RGBA])
        c = palette[np.where(li < 0, 3, li)]
        quads = [v[:-1, :-1], v[:-1, 1:], v[1:, :-1], v[1:, 1:]]
        cq = [c[:-1, :-1], c[:-1, 1:], c[1:, :-1], c[1:, 1:]]
        verts.append(np.stack([quads[0], quads[1], quads[3], quads[0], quads[3], quads[2]], axis=2).reshape(-1, 3))
        cols.append(np.stack([cq[0], cq[1], cq[3], cq[0], cq[3], cq[2]], axis=2).reshape(-1, 4))
        bx0, bx1, by0, by1 = xs[ci[0]], xs[ci[-1]], ys[ri[0]], ys[ri[-1]]
        rects = [(x0, x1, y0, by0), (x0, x1, by1, y1), (x0, bx0, by0, by1), (bx1, x1, by0, by1)]
    else:
        rects = [(x0, x1, y0, y1)]
    for ax0, ax1, ay0, ay1 in rects:
        if ax1 > ax0 and ay1 > ay0:
            a, b, c_, d = (ax0, ay0, 0.0), (ax1, ay0, 0.0), (ax0, ay1, 0.0), (ax1, ay1, 0.0)
            verts.append(np.array([a, b, d, a, d, c_]))
            cols.append(np.tile(REST_RGBA, (6, 1)))
    return np.concatenate(verts), np.concatenate(cols)


def fill_mesh_marker(marker, point_cls, color_cls, t_ns, frame, verts, colours, ns="tissue", marker_id=0):
    """Fill a TRIANGLE_LIST Marker (type 11) from vertex and colour arrays.

    Point and colour objects of the previous frame are reused (setting fields costs about a
    quarter of constructing a message object in rclpy).
    """
    set_stamp(marker.header, t_ns)
    marker.header.frame_id = frame
    marker.ns, marker.id = ns, marker_id
    marker.type, marker.action = 11, 0
    marker.pose.orientation.w = 1.0
    marker.scale.x = marker.scale.y = marker.scale.z = 1.0
    pts = list(marker.points)
    cols = list(marker.colors)
    n = len(verts)
    pts.extend(point_cls() for _ in range(n - len(pts)))
    cols.extend(color_cls() for _ in range(n - len(cols)))
    del pts[n:], cols[n:]
    for p, (x, y, z) in zip(pts, np.asarray(verts, dtype=float).tolist()):
        p.x, p.y, p.z = x, y, z
    for c, (r, g, b, a) in zip(cols, np.asarray(colours, dtype=float).tolist()):
        c.r, c.g, c.b, c.a = r, g, b, a
    marker.points = pts
    marker.colors = cols
    return marker


def fill_needle_state(msg, state: dict, t_ns: int, frame: str):
    """``tissue/needle`` (``skin_sim_msgs/NeedleState``) from the model's needle read-out (a dict of the message's
    field names, ``skin_sim_node.model.needle_skin.NeedleSkin.needle_state``); attribute access only."""
    msg.header.stamp.sec, msg.header.stamp.nanosec = divmod(int(t_ns), NS)
    msg.header.frame_id = frame
    msg.inserted = bool(state["inserted"])
    for name in ("tip_m", "axis", "entry_m", "force_n"):
        getattr(msg, name)[:] = [float(c) for c in state[name]]
    for name in ("insertion_m", "dimple_m", "dimple_force_n", "cutting_force_n", "friction_force_n"):
        setattr(msg, name, float(state[name]))
    msg.ruptured_layers = int(state["ruptured_layers"])
    msg.crossing_m = [float(c) for c in state["crossing_m"]]
    return msg
