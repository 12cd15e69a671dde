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
