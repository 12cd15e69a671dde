"""The view's wire format (server -> page) and the pure helpers shared by the live and bag sources.

One binary WebSocket message per display frame::

    b"SKV1" | uint32 LE header length | UTF-8 JSON header | zero padding to 4 bytes | float32 LE grid

The header carries the tool tip, force, contact and time; ``grid`` in the header says that a
``(ny, nx, 3)`` float32 block of layer heights (m: surface, epidermis/dermis, dermis/fat, the
``tissue/layer_heights`` channels) follows. Frames whose grid did not change carry none.
Text messages are JSON objects with a ``type`` (``diag``, ``timeline``, ``info``).
"""

from __future__ import annotations

import json
import struct

import numpy as np

MAGIC = b"SKV1"

# Diagnostics keys the page shows (node diagnostics, skin_sim_node/server/node.py).
DIAG_KEYS = (
    "achieved_rate_hz", "target_rate_hz", "loop_mode", "missed_slots_window", "late_ticks_window",
    "clock_overruns_total", "period_us_p99", "kernel_us_p99", "input_age_ms", "input_stale", "n_affected_layers",
)  # fmt: skip


def encode_frame(header: dict, grid: np.ndarray | None = None) -> bytes:
    """Binary frame: header JSON plus, if given, the ``(ny, nx, 3)`` layer-heights grid as float32."""
    h = dict(header)
    if grid is not None:
        g = np.ascontiguousarray(grid, dtype="<f4")
        if g.ndim != 3 or g.shape[2] != 3:
            raise ValueError(f"layer heights must be (ny, nx, 3), got {g.shape}")
        h["grid"] = {"ny": int(g.shape[0]), "nx": int(g.shape[1])}
    text = json.dumps(h, separators=(",", ":")).encode()
    pad = (-(8 + len(text))) % 4
    out = MAGIC + struct.pack("<I", len(text) + pad) + text + b" " * pad
    return out + g.tobytes() if grid is not None else out


def decode_frame(data: bytes) -> tuple[dict, np.ndarray | None]:
    """Inverse of :func:`encode_frame` (used by tests and the benchmark's own client)."""
    if data[:4] != MAGIC:
        raise ValueError("not a skin-sim view frame")
    (n,) = struct.unpack("<I", data[4:8])
    header = json.loads(data[8 : 8 + n])
    grid = None
    if "grid" in header:
        ny, nx = header["grid"]["ny"], header["grid"]["nx"]
        grid = np.frombuffer(data, dtype="<f4", count=ny * nx * 3, offset=8 + n).reshape(ny, nx, 3)
    return header, grid


def diag_message(status_level: int, status_message: str, values: dict[str, str]) -> dict:
    """The page's diagnostics record: the shown keys, every ``regime_*`` and ``count_*`` counter."""
    shown = {k: values[k] for k in DIAG_KEYS if k in values}
    regime = {k[len("regime_") :]: v for k, v in values.items() if k.startswith("regime_")}
    counts = {k[len("count_") :]: v for k, v in values.items() if k.startswith("count_")}
    return {
        "type": "diag",
        "level": int(status_level),
        "message": status_message,
        "values": shown,
        "regime": regime,
        "counts": counts,
    }


def default_thickness_m() -> list[float]:
    """Layer thicknesses (m) of the parameter schema's defaults: epidermis, dermis, fat (the bottom of the cut)."""
    from msgs_schema.parameters import SPEC_BY_NAME
    from msgs_schema.tissue import LAYER_NAMES

    return [SPEC_BY_NAME[f"tissue.layers.{n}.thickness_m"].default for n in LAYER_NAMES]


def tool_depth_m(z_m: float) -> float:
    """Tool depth below the rest surface (z = 0, z up; topics.FRAMES), 0 above it."""
    return max(0.0, -float(z_m))


def decimate(t: np.ndarray, *series: np.ndarray, max_points: int = 4000):
    """Every k-th sample so that at most ``max_points`` remain (a plot needs no more than its pixels)."""
    k = max(1, int(np.ceil(len(t) / max_points)))
    return (t[::k], *(s[::k] for s in series))


def hands_info(hands) -> dict:
    """The page's ``info`` entry for the hands (issue 32): ``{"hands": [{"ns", "shape", "radius_m"}, ...]}`` with two
    hands, else nothing, so that a single-hand page is unchanged. Shared by the live and the bag source.

    Parameters
    ----------
    hands : sequence of (str, str, float)
        Each hand's namespace, its tool's shape and radius (m), the first hand first.

    Returns
    -------
    dict
    """
    if len(hands) < 2:
        return {}
    return {"hands": [{"ns": ns, "shape": shape, "radius_m": radius_m} for ns, shape, radius_m in hands]}


def add_hands(header: dict, hands) -> dict:
    """Put each hand's part of a frame header into ``header`` (issue 32): the first hand's fields at the top level (the
    single-hand page's fields: tool, force, needle, ...), and with two hands a ``hands`` list of every hand's (``ns`` and
    the same fields, the first hand's included). Shared by the live and the bag source.

    Parameters
    ----------
    header : dict
        The frame header so far (time, sequence); updated in place.
    hands : sequence of (str, dict)
        Each hand's namespace and its fields, the first hand first.

    Returns
    -------
    dict
        ``header``.
    """
    header.update(hands[0][1])
    if len(hands) > 1:
        header["hands"] = [{"ns": ns, **fields} for ns, fields in hands]
    return header


def friction_anchor(msg) -> list[float] | None:
    """The presliding friction's anchor (m, tissue frame) of a ``skin_sim_msgs/msg/ContactModel`` (rclpy or rosbags),
    or None: no message, no presliding law in it (out of contact, the paper form, the needle), or an older message
    without the field (issue 30)."""
    if msg is None or getattr(msg, "tangential_stiffness_n_per_m", 0.0) <= 0.0 or msg.friction_coefficient <= 0.0:
        return None
    return [float(c) for c in msg.friction_anchor_m]


# --- the needle (issue 22: tool.shape 'needle', tissue/needle) -----------------------------------
NEEDLE_FIELDS_3 = ("tip_m", "axis", "entry_m", "force_n")
NEEDLE_FIELDS_1 = ("insertion_m", "dimple_m", "dimple_force_n", "cutting_force_n", "friction_force_n")


def needle_gauge(outer_diameter_m: float, rel_tol: float = 0.01) -> int | None:
    """The gauge whose nominal outer diameter (the model's ISO 9626 table, ``model.needle.GAUGE_OUTER_DIAMETER_M``)
    is within ``rel_tol`` of ``outer_diameter_m``, else None (the page then shows the diameter alone)."""
    from ..model.needle import GAUGE_OUTER_DIAMETER_M  # the model's table (imported on use: it loads the kernels)

    for g, d in GAUGE_OUTER_DIAMETER_M.items():
        if abs(outer_diameter_m - d) <= rel_tol * d:
            return g
    return None


def pose_axis(q) -> list[float]:
    """The needle axis toward the tip from a pose orientation ``q = (x, y, z, w)``: R(q) applied to (0, 0, -1)
    (``tool/pose`` in msgs_schema/topics.py). Normalised first, so a slightly off-unit quaternion still gives a unit axis."""
    x, y, z, w = (float(c) for c in q)
    n = (x * x + y * y + z * z + w * w) ** 0.5 or 1.0
    x, y, z, w = x / n, y / n, z / n, w / n
    return [-2.0 * (x * z + w * y), -2.0 * (y * z - w * x), -(1.0 - 2.0 * (x * x + y * y))]


def read_needle(msg) -> dict:
    """A ``skin_sim_msgs/msg/NeedleState`` (rclpy or rosbags) as the page's ``needle`` record (SI units, tissue frame)."""
    out: dict = {"inserted": bool(msg.inserted), "ruptured_layers": int(msg.ruptured_layers)}
    for f in NEEDLE_FIELDS_3:
        out[f] = [float(v) for v in getattr(msg, f)]
    for f in NEEDLE_FIELDS_1:
        out[f] = float(getattr(msg, f))
    out["crossing_m"] = [float(v) for v in msg.crossing_m]
    return out


class TrackMemory:
    """The deepest insertion along the current track: the page draws the track from the entry to it.

    A track is the same entry and axis while ``inserted``; it ends when the needle is withdrawn (``inserted``
    false) or the node reports another entry (a new track after withdrawal). ``update`` adds ``deepest_m``
    to the record (0 without a track)."""

    SAME_M = 1e-6  # an entry that moved less than this is the same track (the node latches it: it does not move)

    def __init__(self):
        self.entry: list[float] | None = None
        self.deepest_m = 0.0

    def update(self, needle: dict) -> dict:
        if not needle["inserted"]:
            self.entry, self.deepest_m = None, 0.0
        else:
            e = needle["entry_m"]
            if self.entry is None or max(abs(a - b) for a, b in zip(e, self.entry)) > self.SAME_M:
                self.entry, self.deepest_m = list(e), 0.0
            self.deepest_m = max(self.deepest_m, needle["insertion_m"])
        needle["deepest_m"] = self.deepest_m
        return needle
