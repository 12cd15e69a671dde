"""An in-process rclpy observer of a running skin_sim_node: records its outputs, injects inputs.

Used by the demo, the integration tests and the benchmarks. It owns its own rclpy
context and spins it in a background thread, so it can live inside pytest or a CLI. In the runtime, not the lab,
because the demo (and ``skin-sim view --bench``) observe the node with it.
"""

from __future__ import annotations

import threading
import time
from collections.abc import Callable

import numpy as np
import rclpy

from msgs_schema import convert as cv
from msgs_schema.qos import publisher, subscription

from ..ros_util import make_executor, spin_context

RECORD_DEPTH = 200  # samples; 0.2 s at 1 kHz


class Monitor:
    """Subscribes to the node's outputs; every record carries the local ROS-clock arrival time.

    Records: ``wrench`` (rx_ns, stamp_ns, fz), ``contact`` (rx_ns, stamp_ns, compression[3],
    stress[3]), ``height_map``/``layer_heights`` (rx_ns, stamp_ns, array), ``mesh`` (rx_ns, stamp_ns,
    vertex count), ``diagnostics`` (rx_ns, {key: value}).
    """

    def __init__(
        self,
        name: str = "skin_sim_monitor",
        keep_images: int = 4000,
        executor: str = "events",
        images: bool = True,
        record_depth: int = RECORD_DEPTH,
        contact: bool = True,
        mesh: bool = False,
    ):
        """``record_depth``: reader history of wrench/contact. Deep (default) to record every sample;
        1 to time arrivals as a device sees them (a stalled observer would timestamp a backlog late).
        ``images`` and ``contact`` off: only ``tool/wrench`` and ``diagnostics`` (the benchmarks' observer).
        ``mesh`` on: also ``tissue/mesh`` (off by default: the node builds the mesh only while it is read)."""
        self.context = rclpy.Context()
        rclpy.init(context=self.context)
        self.node = rclpy.create_node(name, context=self.context)
        self._clock = self.node.get_clock()
        self.wrench: list[tuple[int, int, float]] = []
        self.contact: list = []
        self.height_map: list = []
        self.layer_heights: list = []
        self.diagnostics: list = []
        self.mesh: list[tuple[int, int, int]] = []  # rx_ns, stamp_ns, vertex count
        self._keep_images = keep_images
        self._lock = threading.Lock()
        # an observer records every sample: a deep reader queue, so its own stalls lose nothing
        subscription(self.node, "tool_wrench", self._on_wrench, depth=record_depth)
        if contact:
            subscription(self.node, "contact", self._on_contact, depth=record_depth)
        if images:
            subscription(self.node, "height_map", lambda m: self._on_image(m, self.height_map))
            subscription(self.node, "layer_heights", lambda m: self._on_image(m, self.layer_heights))
        if mesh:
            subscription(self.node, "mesh", lambda m: self.mesh.append((self._now(), cv.stamp_ns(m.header), len(m.points))))
        subscription(self.node, "diagnostics", self._on_diag)
        self._executor = make_executor(executor, self.context)
        self._executor.add_node(self.node)
        self._stop = threading.Event()
        self._thread = threading.Thread(target=self._spin, name="monitor-spin", daemon=True)
        self._thread.start()

    def _now(self) -> int:
        return self._clock.now().nanoseconds

    def _spin(self) -> None:
        spin_context(self._executor, self.context, self._stop)

    def _on_wrench(self, msg) -> None:
        stamp, _, f = cv.read_wrench(msg)
        self.wrench.append((self._now(), stamp, f[2]))

    def _on_contact(self, msg) -> None:
        stamp, comp, _, stress = cv.read_contact(msg)
        self.contact.append((self._now(), stamp, comp, stress))

    def _on_image(self, msg, store: list) -> None:
        stamp = cv.stamp_ns(msg.header)
        store.append((self._now(), stamp, cv.read_image(msg)))
        if len(store) > self._keep_images:
            del store[: len(store) - self._keep_images]

    def _on_diag(self, msg) -> None:
        for st in msg.status:
            self.diagnostics.append((self._now(), {kv.key: kv.value for kv in st.values}, st.level, st.message))

    # --- helpers ----------------------------------------------------------------------
    def publisher(self, key: str):
        """A publisher of contract topic ``key`` on the monitor's node."""
        return publisher(self.node, key)

    def wait_for(self, predicate: Callable[[], bool], timeout_s: float = 20.0, what: str = "condition") -> None:
        """Wait until ``predicate()`` is true.

        Raises
        ------
        TimeoutError
            Not within ``timeout_s``, naming ``what``.
        """
        end = time.monotonic() + timeout_s
        while time.monotonic() < end:
            if predicate():
                return
            time.sleep(0.02)
        raise TimeoutError(f"monitor: {what} not met within {timeout_s} s")

    def forces(self) -> np.ndarray:
        """(n, 3) array of rx_ns, stamp_ns, fz."""
        data = list(self.wrench)
        return np.array(data, dtype=np.float64).reshape(-1, 3)

    def now_ns(self) -> int:
        """The monitor's clock now (ns)."""
        return self._now()

    def close(self) -> None:
        """Stop the spin thread, destroy the node and shut its context down."""
        self._stop.set()
        self._thread.join(timeout=2.0)
        try:
            self.node.destroy_node()
        finally:
            rclpy.try_shutdown(context=self.context)


class StreamObserver(Monitor):
    """The benchmarks' observer (``skin-sim bench``, ``skin-sim view --bench``): a :class:`Monitor` of ``tool/wrench``
    and ``diagnostics`` only, in its own rclpy context.

    No ``contact`` or image readers: at 4 kHz each reader is 4000 Python callbacks a second in this
    process, and an observer that cannot keep up would count its own losses as the node's missed ticks.
    """

    def __init__(self, name: str, record_depth: int):
        super().__init__(name, images=False, contact=False, record_depth=record_depth)
