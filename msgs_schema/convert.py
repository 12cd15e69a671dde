"""Converters between the contract's messages and plain numbers/arrays.

Readers use attribute access only, so they work on rclpy messages and on the
dataclasses that ``rosbags`` deserialises alike. Writers fill a message object the
caller owns (preallocated in the node), so the haptic path allocates no messages.
"""

from __future__ import annotations

import numpy as np

from .topics import LAYER_LABELS

NS = 1_000_000_000

# RGBA per layer for the mesh: epidermis, dermis, fat; rest (no contact) is skin tone.
LAYER_RGBA = ((0.95, 0.79, 0.65, 1.0), (0.85, 0.47, 0.48, 1.0), (0.96, 0.88, 0.56, 1.0))
REST_RGBA = (0.93, 0.80, 0.70, 1.0)


def stamp_ns(header) -> int:
    return int(header.stamp.sec) * NS + int(header.stamp.nanosec)


def set_stamp(header, t_ns: int) -> None:
    header.stamp.sec, header.stamp.nanosec = divmod(int(t_ns), NS)


def read_pose(msg):
    """PoseStamped -> (stamp_ns, frame_id, (x, y, z))."""
    p = msg.pose.position
    return stamp_ns(msg.header), msg.header.frame_id, (p.x, p.y, p.z)


def read_twist(msg):
    """TwistStamped -> (stamp_ns, frame_id, (vx, vy, vz))."""
    v = msg.twist.linear
    return stamp_ns(msg.header), msg.header.frame_id, (v.x, v.y, v.z)


def read_wrench(msg):
    """WrenchStamped -> (stamp_ns, frame_id, (fx, fy, fz))."""
    f = msg.wrench.force
    return stamp_ns(msg.header), msg.header.frame_id, (f.x, f.y, f.z)


def fill_pose(msg, t_ns: int, frame: str, xyz, quat=(0.0, 0.0, 0.0, 1.0)):
    set_stamp(msg.header, t_ns)
    msg.header.frame_id = frame
    p = msg.pose.position
    p.x, p.y, p.z = (float(c) for c in xyz)
    o = msg.pose.orientation
    o.x, o.y, o.z, o.w = (float(c) for c in quat)
    return msg


def fill_twist(msg, t_ns: int, frame: str, linear, angular=(0.0, 0.0, 0.0)):
    set_stamp(msg.header, t_ns)
    msg.header.frame_id = frame
    lin, ang = msg.twist.linear, msg.twist.angular
    lin.x, lin.y, lin.z = (float(c) for c in linear)
    ang.x, ang.y, ang.z = (float(c) for c in angular)
    return msg


def fill_wrench(msg, t_ns: int, frame: str, force, torque=(0.0, 0.0, 0.0)):
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
    msg.name = list(LAYER_LABELS)
    msg.position = [float(c) for c in compression_m]
    msg.velocity = [float(c) for c in rate_m_s]
    msg.effort = [float(c) for c in stress_pa]
    return msg


def read_contact(msg):
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
    channels = int(msg.encoding[4:]) if msg.encoding.startswith("32FC") else 1
    if not msg.encoding.startswith("32FC"):
        raise ValueError(f"expected a 32FCn image, got encoding {msg.encoding!r}")
    arr = np.frombuffer(bytes(msg.data), dtype=">f4" if msg.is_bigendian else "<f4")
    shape = (msg.height, msg.width) if channels == 1 else (msg.height, msg.width, channels)
    return arr.reshape(shape).astype(np.float64)


def mesh_arrays(xs, ys, heights, layer_index, stride: int = 2):
    """Triangle-list vertices (T*3, 3) and per-vertex RGBA (T*3, 4) of a height map.

    ``layer_index`` (rows, cols) is the deepest affected layer under each cell (-1: rest).
    """
    xs, ys = xs[::stride], ys[::stride]
    h = heights[::stride, ::stride]
    li = layer_index[::stride, ::stride]
    X, Y = np.meshgrid(xs, ys)
    verts = np.stack([X, Y, h], axis=-1)
    palette = np.array([*LAYER_RGBA, REST_RGBA])
    cols = palette[np.where(li < 0, 3, li)]
    a, b = verts[:-1, :-1], verts[:-1, 1:]
    c, d = verts[1:, :-1], verts[1:, 1:]
    ca, cb, cc, cd = cols[:-1, :-1], cols[:-1, 1:], cols[1:, :-1], cols[1:, 1:]
    tri = np.stack([a, b, d, a, d, c], axis=2).reshape(-1, 3)
    tri_c = np.stack([ca, cb, cd, ca, cd, cc], axis=2).reshape(-1, 4)
    return tri, tri_c


def fill_mesh_marker(marker, point_cls, color_cls, t_ns, frame, verts, colours, ns="tissue", marker_id=0):
    """Fill a TRIANGLE_LIST Marker (type 11) from vertex and colour arrays."""
    set_stamp(marker.header, t_ns)
    marker.header.frame_id = frame
    marker.ns, marker.id = ns, marker_id
    marker.type, marker.action = 11, 0
    marker.pose.orientation.w = 1.0
    marker.scale.x = marker.scale.y = marker.scale.z = 1.0
    marker.points = [point_cls(x=float(x), y=float(y), z=float(z)) for x, y, z in verts]
    marker.colors = [color_cls(r=float(r), g=float(g), b=float(b), a=float(a)) for r, g, b, a in colours]
    return marker
