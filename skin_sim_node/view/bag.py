"""Bag source: plays recorded rosbag2 folders (``skin-sim record``, golden and replay outputs) with a timeline.

Reads with the project's bag readers (:mod:`skin_sim_node.bags.io`, ``rosbags``: MCAP and sqlite3,
no rclpy). Every contract topic found in any of the given bags is loaded into memory once, indexed
by bag time, so a seek is a binary search: the page can scrub frame by frame. Several bags are
merged on one timeline (e.g. a golden input bag with its expected-output bag).
"""

from __future__ import annotations

import json
import threading
import time
from pathlib import Path
from typing import Any

import numpy as np
from tqdm import tqdm

from msgs_schema import convert as cv
from msgs_schema.parameters import SPEC_BY_NAME
from msgs_schema.topics import TOPICS

from ..bags.io import BagError, deserialize, iter_raw, open_bag, register_project_type, topic_types
from . import frames as fr
from .frames import decimate, default_thickness_m, diag_message, encode_frame, tool_depth_m

KEYS = ("tool_pose", "tool_wrench", "contact", "layer_heights", "diagnostics", "needle")


def register_needle_type(msgdef: str | None) -> bool:
    """Teach the bag readers' type store ``skin_sim_msgs/msg/NeedleState`` from the bag's own ``msgdef`` or the source
    tree (:func:`skin_sim_node.bags.io.register_project_type`); False if neither is there."""
    return register_project_type(TOPICS["needle"].type, msgdef)


def find_topic(types: dict[str, str], key: str) -> str | None:
    """The bag topic of contract topic ``key``: same relative name in any namespace, same type.

    Of several, the shortest name, then the first in name order: in a two-hand bag (``/left/tool/pose``,
    ``/right/tool/pose``, ...) every key then comes from the same hand (the view plays one hand of such a bag)."""
    spec = TOPICS[key]
    hits = [t for t, m in types.items() if m == spec.type and (t.lstrip("/") == spec.name or t.endswith("/" + spec.name))]
    return min(hits, key=lambda t: (len(t), t)) if hits else None


class BagData:
    """All contract topics of the bags, as arrays on bag time (ns)."""

    def __init__(self, paths: list[Path]):
        self.paths = [Path(p) for p in paths]
        series: dict[str, list] = {k: [] for k in KEYS}
        for path in self.paths:
            with open_bag(path) as reader:
                types = topic_types(reader)
                topics = {find_topic(types, k): k for k in KEYS}
                topics.pop(None, None)
                needle_topic = next((t for t, k in topics.items() if k == "needle"), None)
                if needle_topic is not None:
                    conn = next(c for c in reader.connections if c.topic == needle_topic)
                    if not register_needle_type(getattr(conn, "msgdef", None) and getattr(conn.msgdef, "data", None)):
                        topics.pop(needle_topic)  # no definition to read it with: the bag plays without the needle
                if not topics:
                    raise BagError(f"{path}: none of the skin-sim topics ({', '.join(TOPICS[k].name for k in KEYS)})")
                total = sum(c.msgcount for c in reader.connections if c.topic in topics)
                for topic, msgtype, t_ns, raw in tqdm(
                    iter_raw(path, reader, list(topics)), total=total, desc=f"reading {path.name}", unit="msg", leave=False
                ):
                    key = topics[topic]
                    msg = deserialize(raw, msgtype)
                    if key == "tool_pose":
                        q = msg.pose.orientation
                        series[key].append((t_ns, *cv.read_pose(msg)[2], q.x, q.y, q.z, q.w))
                    elif key == "needle":
                        series[key].append((t_ns, fr.read_needle(msg)))
                    elif key == "tool_wrench":
                        series[key].append((t_ns, *cv.read_wrench(msg)[2]))
                    elif key == "contact":
                        _, comp, _, stress = cv.read_contact(msg)
                        series[key].append((t_ns, *comp[:3], *stress[:3]))
                    elif key == "layer_heights":
                        series[key].append((t_ns, cv.read_image(msg).astype(np.float32)))
                    else:
                        for st in msg.status:
                            values = {kv.key: kv.value for kv in st.values}
                            if "achieved_rate_hz" in values:
                                series[key].append((t_ns, diag_message(int(st.level), st.message, values)))
        if not any(series.values()):
            raise BagError(f"{', '.join(map(str, self.paths))}: the skin-sim topics are present but empty")
        starts = [s[0][0] for s in series.values() if s]
        ends = [s[-1][0] for s in series.values() if s]
        self.t0_ns, self.t1_ns = min(starts), max(ends)

        def table(key, width):
            rows = sorted(series[key], key=lambda r: r[0])
            a = np.array(rows, dtype=np.float64).reshape(-1, width)
            return ((a[:, 0] - self.t0_ns) * 1e-9) if len(a) else np.zeros(0), a[:, 1:]

        self.pose_t, pose = table("tool_pose", 8)
        self.pose, self.pose_q = pose[:, :3], pose[:, 3:]
        self.wrench_t, self.wrench = table("tool_wrench", 4)
        self.contact_t, self.contact = table("contact", 7)
        grids = sorted(series["layer_heights"], key=lambda r: r[0])
        self.grid_t = np.array([(t - self.t0_ns) * 1e-9 for t, _ in grids])
        self.grids = [g for _, g in grids]
        diags = sorted(series["diagnostics"], key=lambda r: r[0])
        self.diag_t = np.array([(t - self.t0_ns) * 1e-9 for t, _ in diags])
        self.diags = [d for _, d in diags]
        needles = sorted(series["needle"], key=lambda r: r[0])
        self.needle_t = np.array([(t - self.t0_ns) * 1e-9 for t, _ in needles])
        track = fr.TrackMemory()  # the deepest insertion of each track, in bag order: a seek shows the track so far
        self.needles = [track.update(n) for _, n in needles]

    @property
    def duration_s(self) -> float:
        return (self.t1_ns - self.t0_ns) * 1e-9

    @staticmethod
    def index_at(ts: np.ndarray, t_s: float) -> int:
        """Index of the newest sample at or before ``t_s`` (-1: none yet)."""
        return int(np.searchsorted(ts, t_s, side="right")) - 1

    def header_at(self, t_s: float) -> dict:
        h: dict[str, Any] = {"t_s": t_s, "duration_s": self.duration_s}
        i = self.index_at(self.pose_t, t_s)
        if i >= 0:
            h["tool"] = self.pose[i].tolist()
            h["depth_m"] = tool_depth_m(self.pose[i][2])
            h["tool_q"] = self.pose_q[i].tolist()
        i = self.index_at(self.needle_t, t_s)
        if i >= 0:
            h["needle"] = self.needles[i]
        i = self.index_at(self.wrench_t, t_s)
        if i >= 0:
            h["force"] = self.wrench[i].tolist()
        i = self.index_at(self.contact_t, t_s)
        if i >= 0:
            h["compression_m"], h["stress_pa"] = self.contact[i][:3].tolist(), self.contact[i][3:].tolist()
            h.setdefault("depth_m", float(self.contact[i][:3].sum()))  # no pose topic: total compression
        return h

    def timeline(self) -> dict:
        """The whole recording for the page's plots: force against time, and against depth."""
        t, f = decimate(self.wrench_t, self.wrench[:, 2]) if len(self.wrench_t) else (np.zeros(0), np.zeros(0))
        if len(self.pose_t):
            depth = np.maximum(0.0, -np.interp(t, self.pose_t, self.pose[:, 2]))
        elif len(self.contact_t):
            depth = np.interp(t, self.contact_t, self.contact[:, :3].sum(axis=1))
        else:
            depth = np.zeros_like(t)
        return {
            "type": "timeline",
            "duration_s": self.duration_s,
            "t_s": t.round(5).tolist(),
            "force_n": f.round(6).tolist(),
            "depth_m": depth.round(8).tolist(),
            "grid_t_s": self.grid_t.round(5).tolist(),
        }


class BagSource:
    """Timeline player over :class:`BagData`; the page seeks, plays and pauses it."""

    def __init__(self, paths: list[Path], rate_hz: float = 30.0, speed: float = 1.0):
        self.data = BagData(paths)
        self.rate_hz = rate_hz
        self.speed = speed
        # open at the first grid: before it the page would show an empty scene (grids start 2-3 s into a recording)
        self.t_s = float(self.data.grid_t[0]) if len(self.data.grid_t) else 0.0
        self.playing = False
        self._lock = threading.Lock()
        self._stop = threading.Event()
        # (t_s, grid index, diag index) last broadcast
        self._sent: tuple[float | None, int | None, int | None] = (None, None, None)
        self.frames = 0
        self.server = None

    def info(self) -> dict:
        needle = len(self.data.needles) > 0  # the bag carries tissue/needle: its tool was a needle
        d = SPEC_BY_NAME["tissue.needle.outer_diameter_m"].default
        return {
            "type": "info",
            "mode": "bag",
            "bags": [str(p) for p in self.data.paths],
            "sheet_m": [SPEC_BY_NAME["tissue.sheet.size_x_m"].default, SPEC_BY_NAME["tissue.sheet.size_y_m"].default],
            "tool_radius_m": SPEC_BY_NAME["tissue.tool.radius_m"].default,
            "rate_hz": self.rate_hz,
            "tool_shape": "needle" if needle else SPEC_BY_NAME["tissue.tool.shape"].default,
            "thickness_m": default_thickness_m(),
            "needle_outer_diameter_m": d,  # a bag has no parameters: the schema's default (the page says so)
            "needle_gauge": fr.needle_gauge(d),
            "needle_diameter_source": "the schema's default (a bag has no parameters)",
            "duration_s": self.data.duration_s,
            "n_grids": len(self.data.grids),
        }

    def hello(self) -> list[str]:
        return [json.dumps(self.info()), json.dumps(self.data.timeline())]

    def resend(self) -> None:
        with self._lock:
            self._sent = (None, None, None)  # a new page: the current frame again, with its grid

    def params(self) -> dict:
        return {"ok": False, "reason": "a bag has no parameter service: tune parameters against a live node", "params": []}

    def set_param(self, name: str, text: str) -> dict:
        return {"ok": False, "name": name, "reason": "a bag has no parameter service: tune parameters against a live node"}

    def seek(self, t_s: float) -> dict:
        with self._lock:
            self.t_s = float(np.clip(t_s, 0.0, self.data.duration_s))
            return {"ok": True, "t_s": self.t_s}

    def play(self, on: bool) -> dict:
        with self._lock:
            if on and self.t_s >= self.data.duration_s:
                self.t_s = 0.0
            self.playing = bool(on)
            return {"ok": True, "playing": self.playing, "t_s": self.t_s}

    def frame_at(self, t_s: float, force_grid: bool = False) -> tuple[dict, bytes, dict | None]:
        """(header, encoded frame, diagnostics record or None) at ``t_s``; the grid only when it changed."""
        d = self.data
        h = d.header_at(t_s)
        h["playing"] = self.playing
        prev = self._sent[0]
        if self.playing and prev is not None and prev < t_s and "force" in h:  # the largest force since the last frame
            lo, hi = np.searchsorted(d.wrench_t, [prev, t_s], side="right")
            if hi > lo:
                h["force_max"] = float(d.wrench[lo:hi, 2].max())
        gi = d.index_at(d.grid_t, t_s)
        di = d.index_at(d.diag_t, t_s)
        _, last_gi, last_di = self._sent
        grid = d.grids[gi] if gi >= 0 and (force_grid or gi != last_gi) else None
        if gi >= 0:
            h["grid_index"] = gi
        diag = d.diags[di] if di >= 0 and di != last_di else None
        self._sent = (t_s, gi, di)
        return h, encode_frame(h, grid), diag

    def run(self, server, duration_s: float | None = None) -> None:
        self.server = server
        period = 1.0 / self.rate_hz
        end = time.monotonic() + duration_s if duration_s else None
        last = time.monotonic()
        while not self._stop.is_set() and (end is None or time.monotonic() < end):
            now = time.monotonic()
            with self._lock:
                if self.playing:
                    self.t_s = min(self.t_s + (now - last) * self.speed, self.data.duration_s)
                    self.playing = self.t_s < self.data.duration_s
                t_s, changed = self.t_s, self._sent[0] != self.t_s
                if changed:
                    h, data, diag = self.frame_at(t_s)
            last = now
            if changed:
                if diag is not None:
                    server.broadcast_text(diag)
                server.broadcast_frame(h, data)
                self.frames += 1
            time.sleep(period)

    def stop(self) -> None:
        self._stop.set()

    def close(self) -> None:
        self._stop.set()
