"""Live source: follows a running skin_sim_node through its own topics and parameter service.

Its own process and rclpy context. Readers use the contract's QoS (``msgs_schema.qos``: haptic
topics best-effort keep-last 1, display topics reliable keep-last 1), and the executor is spun
only once per display frame, so whatever the node publishes at 1 kHz, this process takes at
most one sample per topic per frame: the newest. Parameters go through the node's
``rcl_interfaces`` services (``AsyncParameterClient``), so the node's own checks decide and its
rejection reason reaches the page.
"""

from __future__ import annotations

import json
import re
import threading
import time
from typing import Any

import numpy as np

from msgs_schema import convert as cv
from msgs_schema.parameters import NODE_NAME, SPEC_BY_NAME
from msgs_schema.tissue import LAYER_NAMES
from msgs_schema.topics import hand_topic

from .frames import (
    TrackMemory,
    add_hands,
    default_thickness_m,
    diag_message,
    encode_frame,
    friction_anchor,
    hands_info,
    needle_gauge,
    read_needle,
    tool_depth_m,
)

TUNABLE = re.compile(r"stiffness|damping|friction|tolerance")
"""Parameters the page lists first (issue 14: stiffness, damping, friction, mode tolerance); the rest are
one click away. Matched against the names the node reports at run time, so new ones appear by themselves."""
GEOMETRY_EXTRA = ("tissue.tool.shape", *(f"tissue.layers.{n}.thickness_m" for n in LAYER_NAMES))
"""Parameters the page draws besides sheet size and tool radius: the tool's shape and the layer thicknesses."""
NEEDLE_DIAMETER = "tissue.needle.outer_diameter_m"
"""The needle's outer diameter: the page draws the needle this thick (read like the tool's shape; a node without it:
the schema's default)."""
HAND_PARAMS = ("hand_ns", "second_hand_ns", "second_tool_shape", "second_tool_radius_m")
"""The node's hands (issue 32): each hand's namespace and the second hand's tool. Read with the geometry; a node with two
hands makes the view follow both (each hand's topics are the contract's under its namespace: topics.hand_topic)."""
SERVICE_TIMEOUT_S = 3.0  # a parameter call that takes longer than this is reported as unanswered
SERVICE_WAIT_S = 10.0
"""How long a call first waits for the node's parameter services to be discovered. A view process that
has just started may not yet know them; a request sent before the service's reader matched is lost."""
SERVICE_TRIES = 2  # a request lost while discovery completes is sent once more


def parse_value(text: str, ptype: int):
    """The page's text as the parameter's ROS type; unparsable text goes as a string, so the node answers.

    ``ptype`` is an ``rcl_interfaces/ParameterType`` code (1 bool, 2 integer, 3 double, 4 string).
    """
    t = text.strip()
    try:
        if ptype == 1 and t.lower() in ("true", "false"):
            return t.lower() == "true"
        if ptype == 2:
            return int(t)
        if ptype == 3:
            return float(t)
    except ValueError:
        pass
    return text


class _HandState:
    """One hand's newest samples and their callbacks (run inside spin_once, in the source thread).

    The first hand's state lives on the :class:`LiveSource` itself (its single-hand attributes, unchanged); a second
    hand's on a :class:`HandFeed`.
    """

    pose = None  # the newest tool/pose
    wrench = None  # the newest tool/wrench
    force_max = None  # the largest force z since the last frame (a 1 ms spike between two 30 Hz frames is shown)
    contact_model = None  # the newest tool/contact_model: its friction anchor is drawn (issue 30)
    needle = None  # the newest tissue/needle as the page's record (frames.read_needle), None without a needle
    track: TrackMemory

    def _on_wrench(self, msg) -> None:
        self.wrench = msg
        fz = msg.wrench.force.z
        self.force_max = fz if self.force_max is None else max(self.force_max, fz)

    def _on_needle(self, msg) -> None:
        self.needle = self.track.update(read_needle(msg))

    def hand_fields(self, grid_stamp_s: float | None) -> dict[str, Any]:
        """This hand's part of a frame header (tool, force, needle, anchor); resets the largest force since the last frame.

        Parameters
        ----------
        grid_stamp_s : float or None
            Stamp of the newest grid (s): the header then says how far it is from this hand's wrench (``grid_dt_s``).

        Returns
        -------
        dict
        """
        h: dict[str, Any] = {}
        if self.pose is not None:
            _, _, xyz = cv.read_pose(self.pose)
            h["tool"] = list(xyz)
            q = self.pose.pose.orientation
            h["tool_q"] = [q.x, q.y, q.z, q.w]  # the needle's axis (frames.pose_axis); the punch and sphere ignore it
            h["depth_m"] = tool_depth_m(xyz[2])
        if self.wrench is not None:
            stamp, _, f = cv.read_wrench(self.wrench)
            h["force"] = list(f)
            h["stamp_s"] = stamp * 1e-9
            if grid_stamp_s is not None and stamp:
                h["grid_dt_s"] = grid_stamp_s - stamp * 1e-9
            if self.force_max is not None:
                h["force_max"] = float(self.force_max)
            self.force_max = None
        if self.needle is not None:
            h["needle"] = self.needle
        anchor = friction_anchor(self.contact_model)
        if anchor is not None:
            h["anchor"] = anchor
        return h


class HandFeed(_HandState):
    """A second hand the view follows: its namespace, its tool as the node configures it, its newest samples.

    Parameters
    ----------
    ns : str
        The hand's namespace (``second_hand_ns``).
    shape : str
        Its tool's shape (``second_tool_shape``).
    radius_m : float
        Its tool's radius (``second_tool_radius_m``).
    """

    def __init__(self, ns: str, shape: str, radius_m: float):
        self.ns, self.shape, self.radius_m = ns, shape, radius_m
        self.track = TrackMemory()
        self.subs: list = []


class LiveSource(_HandState):
    """rclpy node ``skin_sim_view`` in ``namespace``; :meth:`run` publishes frames to a ViewServer.

    ``hands``: the hands' namespaces to follow (first, and second if any) instead of the node's ``hand_ns`` /
    ``second_hand_ns``; None (default) follows the node's.
    """

    def __init__(
        self,
        namespace: str = "",
        rate_hz: float = 30.0,
        node_name: str = NODE_NAME,
        contact: bool = False,
        hands: tuple[str, ...] | None = None,
    ):
        import rclpy
        from rclpy.executors import SingleThreadedExecutor
        from rclpy.parameter_client import AsyncParameterClient

        from msgs_schema.qos import subscription

        self.rate_hz = rate_hz
        self.context = rclpy.Context()
        rclpy.init(context=self.context)
        self.node = rclpy.create_node("skin_sim_view", namespace=namespace or "", context=self.context)
        self.namespace = self.node.get_namespace()
        self.executor = SingleThreadedExecutor(context=self.context)
        self.executor.add_node(self.node)
        self._spin_lock = threading.Lock()
        self.client = AsyncParameterClient(self.node, node_name)
        self.pose = self.wrench = self.contact = None
        self.grid: np.ndarray | None = None
        self.grid_new = False
        self.grid_count = 0
        self.diag: dict | None = None
        self._diag_new = False
        self.contact_on = contact  # a reader of tissue/contact makes the node publish it every tick (lazy): opt-in
        subscription(self.node, "layer_heights", self._on_grid)
        subscription(self.node, "diagnostics", self._on_diag)
        self.needle = None  # the newest tissue/needle as the page's record (frames.read_needle), None without a needle
        self.track = TrackMemory()
        self.needle_topic = False
        self.contact_model = None  # the newest tool/contact_model: its friction anchor is drawn (issue 30)
        self.hands_override = tuple(hands) if hands else None
        self.hand_ns = self.hands_override[0] if self.hands_override else ""  # the first hand's namespace
        self.others: list[HandFeed] = []  # a second hand, when the node has one (issue 32)
        self._subs: list = []  # the first hand's subscriptions (made again when its namespace changes)
        self._subscribe_first(self.hand_ns)
        self.needle_diameter_m = SPEC_BY_NAME[NEEDLE_DIAMETER].default
        self.sheet_m = (SPEC_BY_NAME["tissue.sheet.size_x_m"].default, SPEC_BY_NAME["tissue.sheet.size_y_m"].default)
        self.tool_radius_m = SPEC_BY_NAME["tissue.tool.radius_m"].default
        self.tool_shape = SPEC_BY_NAME["tissue.tool.shape"].default
        self.thickness_m = default_thickness_m()
        self.form: str | None = None  # the node's tissue.form once known: "layered" engages every layer from first contact
        self._stop = threading.Event()
        self.frames = 0

    # --- hands (issue 32) ----------------------------------------------------------------
    others: list[HandFeed] = []  # a second hand (also for a source built without __init__, in tests)
    hand_ns = ""

    def _hand_subscriptions(self, target: _HandState, ns: str, contact: bool = False) -> tuple[list, bool]:
        """Subscribe ``target`` to hand ``ns``'s pose, wrench, needle read-out and contact model (and tissue/contact).

        Returns
        -------
        (list, bool)
            The subscriptions, and whether the message package has tissue/needle.
        """
        from msgs_schema.qos import subscription

        subs = [
            subscription(self.node, "tool_pose", lambda m: setattr(target, "pose", m), name=hand_topic("tool_pose", ns)),
            subscription(self.node, "tool_wrench", target._on_wrench, name=hand_topic("tool_wrench", ns)),
        ]
        if contact:
            subs.append(subscription(self.node, "contact", lambda m: setattr(self, "contact", m), name=hand_topic("contact", ns)))
        needle = False
        try:  # the contract's tissue/needle, when the message package has it (an older build does not)
            subs.append(subscription(self.node, "needle", target._on_needle, name=hand_topic("needle", ns)))
            needle = True
        except (ImportError, AttributeError, KeyError):
            pass
        try:  # the contract's tool/contact_model, when the message package has it
            name = hand_topic("contact_model", ns)
            subs.append(subscription(self.node, "contact_model", lambda m: setattr(target, "contact_model", m), name=name))
        except (ImportError, AttributeError, KeyError):
            pass
        return subs, needle

    def _subscribe_first(self, ns: str) -> None:
        self._subs, self.needle_topic = self._hand_subscriptions(self, ns, self.contact_on)

    def _set_hands(self, first: str, second: str, shape: str, radius_m: float) -> bool:
        """Follow the hands ``first`` and ``second`` ('' : none); True if that changed what the view follows.

        A changed namespace drops that hand's subscriptions and samples and subscribes its new topics (under the spin
        lock: the display loop spins in another thread)."""
        others = [(h.ns, h.shape, h.radius_m) for h in self.others]
        want = [(second, shape, radius_m)] if second else []
        if first == self.hand_ns and others == want:
            return False
        with self._spin_lock:
            if first != self.hand_ns:
                for sub in self._subs:
                    self.node.destroy_subscription(sub)
                self.pose = self.wrench = self.contact = self.contact_model = self.needle = self.force_max = None
                self.track = TrackMemory()
                self.hand_ns = first
                self._subscribe_first(first)
            if [(h.ns, h.shape, h.radius_m) for h in self.others] != want:
                for h in self.others:
                    for sub in h.subs:
                        self.node.destroy_subscription(sub)
                feeds = [HandFeed(*w) for w in want]
                for f in feeds:
                    f.subs = self._hand_subscriptions(f, f.ns)[0]
                self.others = feeds
        return True

    # --- callbacks (run inside spin_once, in the source thread) -----------------------
    grid_stamp_s: float | None = None
    contact: Any = None  # the newest tissue/contact (with --contact)

    def _on_grid(self, msg) -> None:
        self.grid = cv.read_image(msg)
        self.grid_stamp_s = cv.stamp_ns(msg.header) * 1e-9
        self.grid_new = True
        self.grid_count += 1

    def _on_diag(self, msg) -> None:
        for st in msg.status:
            values = {kv.key: kv.value for kv in st.values}
            if "achieved_rate_hz" in values:
                self.diag = diag_message(
                    int.from_bytes(st.level, "little") if isinstance(st.level, bytes) else st.level, st.message, values
                )
                self._diag_new = True

    # --- ROS calls --------------------------------------------------------------------
    def _spin(self, n: int = 8) -> None:
        with self._spin_lock:
            for _ in range(n):  # one pass per ready entity; keep-last 1 readers hold one sample each
                self.executor.spin_once(timeout_sec=0)

    def _wait(self, future, what: str):
        end = time.monotonic() + SERVICE_TIMEOUT_S
        while not future.done():
            if time.monotonic() > end:
                raise TimeoutError(
                    f"{what}: no answer from {self.namespace.rstrip('/')}/{NODE_NAME} within {SERVICE_TIMEOUT_S} s"
                )
            if self._stop.is_set() or not self._running:
                self._spin(4)
            time.sleep(0.005)
        return future.result()

    _running = False
    server = None  # the ViewServer, once :meth:`run` starts

    def _call(self, call, what: str, wait_s: float = SERVICE_WAIT_S, tries: int = SERVICE_TRIES):
        """``call()`` returns a future; wait for the services, send, and resend if unanswered."""
        if not self.client.wait_for_services(timeout_sec=wait_s):
            raise TimeoutError(
                f"{what}: the parameter services of {self.namespace.rstrip('/')}/{NODE_NAME} "
                f"were not found within {wait_s:.0f} s (is the node running in this "
                "namespace and ROS_DOMAIN_ID?)"
            )
        for attempt in range(tries):
            try:
                return self._wait(call(), what)
            except TimeoutError:
                if attempt == tries - 1:
                    raise

    def _get(self, names: list[str], **call) -> dict:
        res = self._call(lambda: self.client.get_parameters(names), "get_parameters", **call)
        from rclpy.parameter import parameter_value_to_python

        return {n: (v.type, parameter_value_to_python(v)) for n, v in zip(names, res.values)}

    def refresh_geometry(self, wait_s: float = SERVICE_WAIT_S) -> bool:
        """Sheet size and tool radius from the node (its grid and patch), defaults if it does not answer.

        Returns
        -------
        bool
            Whether the node answered within ``wait_s``.
        """
        try:
            names = [
                "tissue.sheet.size_x_m", "tissue.sheet.size_y_m", "tissue.tool.radius_m", "tissue.form", *GEOMETRY_EXTRA,
                NEEDLE_DIAMETER, *HAND_PARAMS,
            ]  # fmt: skip
            self._set_geometry(self._get(names, wait_s=wait_s, tries=1))
        except TimeoutError:
            return False
        return True

    def _set_geometry(self, got: dict) -> bool:
        """Take sheet size and tool radius from a get_parameters answer; True if they changed.

        A node without one of them (rclpy then answers no values at all) leaves the defaults."""
        try:
            new = (
                (float(got["tissue.sheet.size_x_m"][1]), float(got["tissue.sheet.size_y_m"][1])),
                float(got["tissue.tool.radius_m"][1]),
            )
        except (KeyError, TypeError, ValueError):
            return False
        extra = (
            str(got.get("tissue.tool.shape", (0, self.tool_shape))[1]),
            [float(got.get(n, (0, t))[1]) for n, t in zip(GEOMETRY_EXTRA[1:], self.thickness_m)],
        )
        diameter = float(got.get(NEEDLE_DIAMETER, (0, self.needle_diameter_m))[1])
        changed = (new, extra, diameter) != (
            (self.sheet_m, self.tool_radius_m), (self.tool_shape, self.thickness_m), self.needle_diameter_m
        )  # fmt: skip
        self.sheet_m, self.tool_radius_m = new
        self.tool_shape, self.thickness_m = extra
        self.needle_diameter_m = diameter
        if self.tool_shape != "needle":  # the node's tool is no needle (any more): draw none
            self.needle = None
        if "tissue.form" in got:
            self.form = str(got["tissue.form"][1])
        return self._take_hands(got) or changed

    def _take_hands(self, got: dict) -> bool:
        """Follow the hands of a get_parameters answer (or of the ``hands`` override); True if they changed.

        A node without the hand parameters (rclpy then answers no values at all) has one hand, of the single-tool names."""
        if self.hands_override is not None:
            first, second = self.hands_override[0], (self.hands_override[1:] or ("",))[0]
        else:
            first, second = str(got.get("hand_ns", (0, ""))[1]), str(got.get("second_hand_ns", (0, ""))[1])
        shape = str(got.get("second_tool_shape", (0, SPEC_BY_NAME["second_tool_shape"].default))[1])
        radius = float(got.get("second_tool_radius_m", (0, SPEC_BY_NAME["second_tool_radius_m"].default))[1])
        for h in self.others:
            if h.shape != "needle":
                h.needle = None
        return self._set_hands(first, second, shape, radius)

    def params(self) -> dict:
        """The node's parameters as it reports them now, tunable ones flagged (none hard-coded)."""
        try:
            names = sorted(self._call(lambda: self.client.list_parameters([], 0), "list_parameters").result.names)
            got = self._get(names)
            descs = self._call(lambda: self.client.describe_parameters(names), "describe_parameters").descriptors
        except TimeoutError as exc:
            return {"ok": False, "reason": str(exc), "params": [], "retry": True}
        if self._set_geometry(got) and self.server is not None:
            self.server.broadcast_text(self.info())  # the node was not found at start: the page had defaults
        out = []
        for d in descs:
            ptype, value = got[d.name]
            if ptype not in (1, 2, 3, 4) or d.read_only:
                continue
            out.append(
                {
                    "name": d.name,
                    "type": ptype,
                    "value": value,
                    "description": d.description,
                    "tunable": bool(TUNABLE.search(d.name)),
                }
            )
        return {"ok": True, "node": f"{self.namespace.rstrip('/')}/{NODE_NAME}", "params": out}

    def set_param(self, name: str, text: str) -> dict:
        """Set one parameter through the node's SetParameters service; returns its verdict and reason."""
        from rclpy.parameter import Parameter

        try:
            got = self._get([name])
        except TimeoutError as exc:
            return {"ok": False, "name": name, "reason": str(exc)}
        ptype = got.get(name, (0, None))[0]
        if ptype == 0:
            return {"ok": False, "name": name, "reason": f"the node has no parameter {name!r}"}
        value = parse_value(text, ptype)
        try:
            res = self._call(lambda: self.client.set_parameters([Parameter(name, value=value)]), "set_parameters")
        except TimeoutError as exc:
            return {"ok": False, "name": name, "reason": str(exc)}
        r = res.results[0]
        geometry = ("tissue.sheet.size_x_m", "tissue.sheet.size_y_m", "tissue.tool.radius_m", *GEOMETRY_EXTRA, NEEDLE_DIAMETER)
        if r.successful and name in geometry:
            threading.Thread(target=self._after_geometry_change, daemon=True).start()
        return {
            "ok": bool(r.successful),
            "name": name,
            "value": value if r.successful else got[name][1],
            "reason": r.reason or ("applied" if r.successful else "rejected (no reason given)"),
        }

    def _after_geometry_change(self) -> None:
        self.refresh_geometry()
        assert self.server is not None  # a parameter is set from the page: the display loop runs
        self.server.broadcast_text(self.info())

    # --- page ---------------------------------------------------------------------------
    def info(self) -> dict:
        return {
            "type": "info",
            "mode": "live",
            "namespace": self.namespace,
            "sheet_m": list(self.sheet_m),
            "tool_radius_m": self.tool_radius_m,
            "tool_shape": self.tool_shape,
            "thickness_m": self.thickness_m,
            "rate_hz": self.rate_hz,
            "needle_outer_diameter_m": self.needle_diameter_m,
            "needle_gauge": needle_gauge(self.needle_diameter_m),
            **self.hands_info(),
        }

    def hands_info(self) -> dict:
        """``{"hands": [...]}`` with two hands (each: ``ns``, ``shape``, ``radius_m``; the first is the tool above), else
        nothing: a single-hand page is unchanged."""
        return hands_info(
            [(self.hand_ns, self.tool_shape, self.tool_radius_m), *((h.ns, h.shape, h.radius_m) for h in self.others)]
        )

    def resend(self) -> None:
        self.grid_new = self.grid is not None  # a new page needs the grid once

    def hello(self) -> list[str]:
        msgs = [json.dumps(self.info())]
        if self.diag:
            msgs.append(json.dumps(self.diag))
        return msgs

    def header(self) -> dict:
        """The frame header: the first hand's tool and force at the top level (the single-hand page's fields); with two
        hands, ``hands`` lists each hand's (``ns`` and the same fields), the first hand's included."""
        h: dict[str, Any] = {"t": time.time(), "seq": self.frames}
        hands = [(self.hand_ns, self.hand_fields(self.grid_stamp_s))]
        add_hands(h, hands + [(o.ns, o.hand_fields(self.grid_stamp_s)) for o in self.others])
        if self.contact is not None:
            _, comp, _, stress = cv.read_contact(self.contact)
            h["compression_m"], h["stress_pa"] = comp.tolist(), stress.tolist()
            h["layers"] = int(sum(1 for x in stress if x > 0))
        elif self.form == "layered" and "force" in h:
            h["layers"] = len(LAYER_NAMES) if np.linalg.norm(h["force"]) > 0 else 0  # all in series from first contact
        return h

    def run(self, server, duration_s: float | None = None) -> None:
        """Display loop: spin once per frame, broadcast the newest state; until :meth:`stop` or ``duration_s``."""
        self.server = server
        self._running = True
        period = 1.0 / self.rate_hz
        end = time.monotonic() + duration_s if duration_s else None
        nxt = time.monotonic()
        try:
            while not self._stop.is_set() and (end is None or time.monotonic() < end):
                self._spin()
                if self._diag_new:
                    self._diag_new = False
                    server.broadcast_text(self.diag)
                h = self.header()
                grid = None
                if self.grid_new and self.grid is not None:
                    grid, self.grid_new = self.grid, False
                data = encode_frame(h, grid)
                server.broadcast_frame(h, data)
                self.frames += 1
                nxt += period
                time.sleep(max(0.0, nxt - time.monotonic()))
                if nxt < time.monotonic() - period:
                    nxt = time.monotonic()  # fell behind (descheduled): do not burst to catch up
        finally:
            self._running = False

    def stop(self) -> None:
        self._stop.set()

    def close(self) -> None:
        import rclpy

        self._stop.set()
        try:
            self.node.destroy_node()
        finally:
            rclpy.try_shutdown(context=self.context)
