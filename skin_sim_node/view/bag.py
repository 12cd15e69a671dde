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
from msgs_schema.tissue import LAYER_NAMES
from msgs_schema.topics import TOPICS, hand_topic

from ..bags.io import (
    BagError,
    custom_data,
    deserialize,
    iter_raw,
    open_bag,
    recorded_params,
    register_project_type,
    topic_types,
)
from . import frames as fr
from .frames import decimate, default_thickness_m, diag_message, encode_frame, tool_depth_m

KEYS = ("tool_pose", "tool_wrench", "contact", "layer_heights", "diagnostics", "needle")
HAND_KEYS = ("tool_pose", "tool_wrench", "contact", "needle")
"""The keys read per hand in a two-hand bag (each under its namespace: ``msgs_schema.topics.HAND_TOPICS``); the others
are the tissue's."""


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


def bag_hands(paths) -> tuple[str, ...]:
    """The hands the bags say they hold (``custom_data`` ``skin_sim.hands``, e.g. ``right,left``: the first hand first), of
    the first bag that says; () when none does (a single-hand bag, or one written before issue 32)."""
    for path in paths:
        named = custom_data(path).get("skin_sim.hands", "")
        if named:
            return tuple(n.strip() for n in named.split(","))
    return ()


def bag_params(paths, params: Path | None = None) -> tuple[Path | None, str]:
    """The parameter file the hands' tools are drawn from: ``params`` (``--params``), else the shipped preset the bags
    name in ``skin_sim.params`` (as ``skin-sim replay`` takes it); (None, why) when there is neither."""
    if params is not None:
        return Path(params), str(params)
    for path in paths:
        shipped = recorded_params(path)
        if shipped is not None:
            return shipped, f"{shipped.name} (recorded with the bag)"
    return None, "the schema's defaults (the bag names no shipped preset: give --params)"


def hand_tools(params: Path | None) -> tuple[dict, list[tuple[str, float]]]:
    """The geometry the page draws and each hand's tool ``(shape, radius_m)`` from parameter file ``params``, as the node
    builds them (:func:`skin_sim_node.configure.hand_configs`: the first hand's ``tissue.tool.*``, the second's
    ``second_tool_shape`` / ``second_tool_radius_m``); the schema's defaults without a file."""
    from ..configure import configure, hand_configs
    from ..model.config import load_yaml

    flat: dict[str, Any] = load_yaml(params) if params is not None else {}
    if not flat.get("second_hand_ns"):  # the bag has two hands whatever the file says: the second takes second_tool_*
        flat["second_hand_ns"] = "left" if flat.get("hand_ns") != "left" else "right"
    cfgs = hand_configs(flat, configure(flat)[1])

    def value(name):
        return flat.get(name, SPEC_BY_NAME[name].default)

    geometry = {
        "sheet_m": [value("tissue.sheet.size_x_m"), value("tissue.sheet.size_y_m")],
        "thickness_m": [value(f"tissue.layers.{n}.thickness_m") for n in LAYER_NAMES],
        "needle_outer_diameter_m": value("tissue.needle.outer_diameter_m"),
    }
    return geometry, [(c.tool_shape, c.tool_radius_m) for c in cfgs]


def hand_topic_keys(types: dict[str, str], hands: tuple[str, ...]) -> dict[str, tuple[int, str]]:
    """Bag topic -> (hand index, contract key): each hand's topics (:data:`HAND_KEYS`) under its namespace
    (``msgs_schema.topics.hand_topic``) and of the right type, and the tissue's (grid, diagnostics: hand 0) by
    :func:`find_topic`. With fewer than two hands, every key by :func:`find_topic` (one hand, as before)."""
    out: dict[str, tuple[int, str]] = {}
    for key in KEYS:
        if len(hands) < 2 or key not in HAND_KEYS:
            topic = find_topic(types, key)
            if topic is not None:
                out[topic] = (0, key)
            continue
        for i, ns in enumerate(hands):
            topic = "/" + hand_topic(key, ns).lstrip("/")
            if types.get(topic) == TOPICS[key].type:
                out[topic] = (i, key)
    return out


class HandSeries:
    """One hand's recorded topics as arrays on bag time (s from the recording's start): pose, wrench, contact, needle."""

    def __init__(self, ns: str, series: dict[str, list], t0_ns: int):
        self.ns = ns

        def table(key, width):
            rows = sorted(series[key], key=lambda r: r[0])
            a = np.array(rows, dtype=np.float64).reshape(-1, width)
            return ((a[:, 0] - t0_ns) * 1e-9) if len(a) else np.zeros(0), a[:, 1:]

        self.pose_t, pose = table("tool_pose", 8)
        self.pose, self.pose_q = pose[:, :3], pose[:, 3:]
        self.wrench_t, self.wrench = table("tool_wrench", 4)
        self.contact_t, self.contact = table("contact", 7)
        needles = sorted(series["needle"], key=lambda r: r[0])
        self.needle_t = np.array([(t - t0_ns) * 1e-9 for t, _ in needles])
        track = fr.TrackMemory()  # the deepest insertion of each track, in bag order: a seek shows the track so far
        self.needles = [track.update(n) for _, n in needles]

    def fields_at(self, t_s: float, since_s: float | None = None) -> dict[str, Any]:
        """This hand's part of the frame header at ``t_s`` (tool, depth, needle, force, contact); with ``since_s`` (playing)
        also the largest force since then (``force_max``, as the live view's)."""
        h: dict[str, Any] = {}
        i = BagData.index_at(self.pose_t, t_s)
        if i >= 0:
            h["tool"] = self.pose[i].tolist()
            h["depth_m"] = tool_depth_m(self.pose[i][2])
            h["tool_q"] = self.pose_q[i].tolist()
        i = BagData.index_at(self.needle_t, t_s)
        if i >= 0:
            h["needle"] = self.needles[i]
        i = BagData.index_at(self.wrench_t, t_s)
        if i >= 0:
            h["force"] = self.wrench[i].tolist()
            if since_s is not None and since_s < t_s:
                lo, hi = np.searchsorted(self.wrench_t, [since_s, t_s], side="right")
                if hi > lo:
                    h["force_max"] = float(self.wrench[lo:hi, 2].max())
        i = BagData.index_at(self.contact_t, t_s)
        if i >= 0:
            h["compression_m"], h["stress_pa"] = self.contact[i][:3].tolist(), self.contact[i][3:].tolist()
            h.setdefault("depth_m", float(self.contact[i][:3].sum()))  # no pose topic: total compression
        return h

    def timeline(self) -> dict:
        """This hand's whole recording for the page's plots: force against time, and depth at those times."""
        t, f = decimate(self.wrench_t, self.wrench[:, 2]) if len(self.wrench_t) else (np.zeros(0), np.zeros(0))
        if len(self.pose_t):
            depth = np.maximum(0.0, -np.interp(t, self.pose_t, self.pose[:, 2]))
        elif len(self.contact_t):
            depth = np.interp(t, self.contact_t, self.contact[:, :3].sum(axis=1))
        else:
            depth = np.zeros_like(t)
        return {"t_s": t.round(5).tolist(), "force_n": f.round(6).tolist(), "depth_m": depth.round(8).tolist()}


class BagData:
    """All contract topics of the bags, as arrays on bag time (ns).

    ``hands``: the hands' namespaces (``skin_sim.hands`` of a two-hand bag, :func:`bag_hands`): each hand's topics are
    read under its namespace into its own :class:`HandSeries` (``self.hands``, the first hand first). Without (or with one
    hand) the bag plays one hand, each topic found by :func:`find_topic`. The first hand's arrays are also this object's
    (``pose_t``, ``wrench``, ...)."""

    def __init__(self, paths: list[Path], hands: tuple[str, ...] = ()):
        self.paths = [Path(p) for p in paths]
        names = tuple(hands) if len(hands) > 1 else ("",)
        per_hand: list[dict[str, list]] = [{k: [] for k in HAND_KEYS} for _ in names]
        series: dict[str, list] = {k: [] for k in KEYS if k not in HAND_KEYS}
        for path in self.paths:
            with open_bag(path) as reader:
                types = topic_types(reader)
                topics = hand_topic_keys(types, names)
                for needle_topic in [t for t, (_, k) in topics.items() if k == "needle"]:
                    conn = next(c for c in reader.connections if c.topic == needle_topic)
                    if not register_needle_type(getattr(conn, "msgdef", None) and getattr(conn.msgdef, "data", None)):
                        topics.pop(needle_topic)  # no definition to read it with: the bag plays without the needle
                if not topics:
                    raise BagError(f"{path}: none of the skin-sim topics ({', '.join(TOPICS[k].name for k in KEYS)})")
                total = sum(c.msgcount for c in reader.connections if c.topic in topics)
                for topic, msgtype, t_ns, raw in tqdm(
                    iter_raw(path, reader, list(topics)), total=total, desc=f"reading {path.name}", unit="msg", leave=False
                ):
                    hand, key = topics[topic]
                    rows = per_hand[hand][key] if key in HAND_KEYS else series[key]
                    msg = deserialize(raw, msgtype)
                    if key == "tool_pose":
                        q = msg.pose.orientation
                        rows.append((t_ns, *cv.read_pose(msg)[2], q.x, q.y, q.z, q.w))
                    elif key == "needle":
                        rows.append((t_ns, fr.read_needle(msg)))
                    elif key == "tool_wrench":
                        rows.append((t_ns, *cv.read_wrench(msg)[2]))
                    elif key == "contact":
                        _, comp, _, stress = cv.read_contact(msg)
                        rows.append((t_ns, *comp[:3], *stress[:3]))
                    elif key == "layer_heights":
                        rows.append((t_ns, cv.read_image(msg).astype(np.float32)))
                    else:
                        for st in msg.status:
                            values = {kv.key: kv.value for kv in st.values}
                            if "achieved_rate_hz" in values:
                                rows.append((t_ns, diag_message(int(st.level), st.message, values)))
        everything = [*series.values(), *(s for h in per_hand for s in h.values())]
        if not any(everything):
            raise BagError(f"{', '.join(map(str, self.paths))}: the skin-sim topics are present but empty")
        self.t0_ns = min(s[0][0] for s in everything if s)
        self.t1_ns = max(max(r[0] for r in s) for s in everything if s)
        self.hands = [HandSeries(ns, h, self.t0_ns) for ns, h in zip(names, per_hand)]
        first = self.hands[0]
        self.pose_t, self.pose, self.pose_q = first.pose_t, first.pose, first.pose_q
        self.wrench_t, self.wrench = first.wrench_t, first.wrench
        self.contact_t, self.contact = first.contact_t, first.contact
        self.needle_t, self.needles = first.needle_t, first.needles
        grids = sorted(series["layer_heights"], key=lambda r: r[0])
        self.grid_t = np.array([(t - self.t0_ns) * 1e-9 for t, _ in grids])
        self.grids = [g for _, g in grids]
        diags = sorted(series["diagnostics"], key=lambda r: r[0])
        self.diag_t = np.array([(t - self.t0_ns) * 1e-9 for t, _ in diags])
        self.diags = [d for _, d in diags]

    @property
    def duration_s(self) -> float:
        return (self.t1_ns - self.t0_ns) * 1e-9

    @staticmethod
    def index_at(ts: np.ndarray, t_s: float) -> int:
        """Index of the newest sample at or before ``t_s`` (-1: none yet)."""
        return int(np.searchsorted(ts, t_s, side="right")) - 1

    def header_at(self, t_s: float, since_s: float | None = None) -> dict:
        """The frame header at ``t_s``: the first hand's fields at the top level, with two hands each hand's in ``hands``
        (:func:`frames.add_hands`, as the live view's); ``since_s``: see :meth:`HandSeries.fields_at`."""
        h: dict[str, Any] = {"t_s": t_s, "duration_s": self.duration_s}
        return fr.add_hands(h, [(s.ns, s.fields_at(t_s, since_s)) for s in self.hands])

    def timeline(self) -> dict:
        """The whole recording for the page's plots: force against time, and against depth (the first hand's; with two
        hands ``hands`` has each hand's, the first included)."""
        out = {"type": "timeline", "duration_s": self.duration_s, **self.hands[0].timeline()}
        out["grid_t_s"] = self.grid_t.round(5).tolist()
        if len(self.hands) > 1:
            out["hands"] = [{"ns": s.ns, **s.timeline()} for s in self.hands]
        return out


class BagSource:
    """Timeline player over :class:`BagData`; the page seeks, plays and pauses it.

    A two-hand bag (``skin_sim.hands``) plays both hands; their tools are drawn from ``params`` (``--params``), else the
    shipped preset the bag names (``skin_sim.params``), else the schema's defaults (:func:`bag_params`)."""

    tools: list[tuple[str, float]] = []  # each hand's tool (shape, radius_m): a two-hand bag's
    geometry: dict = {}
    tools_source = ""

    def __init__(self, paths: list[Path], rate_hz: float = 30.0, speed: float = 1.0, params: Path | None = None):
        self.data = BagData(paths, bag_hands(paths))
        if len(self.data.hands) > 1:  # a two-hand bag: each hand's tool as the node built it from the bag's preset
            path, self.tools_source = bag_params(paths, params)
            self.geometry, self.tools = hand_tools(path)
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
            **self.hands_info(),
        }

    def hands_info(self) -> dict:
        """A two-hand bag's page entries: the tools, sheet, layers and needle of its parameter file (:func:`bag_params`)
        and ``hands`` (:func:`frames.hands_info`, as the live view's); nothing for one hand (its page is unchanged)."""
        if len(self.data.hands) < 2:
            return {}
        g, tools = self.geometry, self.tools
        d = g["needle_outer_diameter_m"]
        shape = "needle" if len(self.data.needles) > 0 else tools[0][0]
        return {
            "sheet_m": g["sheet_m"],
            "thickness_m": g["thickness_m"],
            "tool_shape": shape,
            "tool_radius_m": tools[0][1],
            "needle_outer_diameter_m": d,
            "needle_gauge": fr.needle_gauge(d),
            "needle_diameter_source": self.tools_source,
            "tools_source": self.tools_source,
            **fr.hands_info([(s.ns, *tool) for s, tool in zip(self.data.hands, tools)]),
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
        prev = self._sent[0]
        h = d.header_at(t_s, prev if self.playing else None)  # playing: each hand's largest force since the last frame
        h["playing"] = self.playing
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
