"""An in-process rclpy recorder: raw (CDR) subscriptions written to a bag, as ``ros2 bag record`` does.

It owns its own rclpy context (like :class:`skin_sim_node.bags.monitor.Monitor`) and spins it in a
thread. Subscriptions are ``raw=True``: the callback gets the CDR bytes, which go to the bag
unchanged with the local ROS-clock receive time as bag timestamp. A writer thread drains a
queue into the :class:`BagWriter`, so callbacks never wait on the disk.
"""

from __future__ import annotations

import os
import queue
import threading

import rclpy
from rclpy.qos import HistoryPolicy, QoSProfile

from msgs_schema.qos import publisher, qos_for
from msgs_schema.topics import TOPICS

from ..ros_util import make_executor, spin_context
from .io import BagWriter, qos_profiles

INPUT_KEYS = ("tool_pose", "tool_twist")
OUTPUT_KEYS = ("tool_wrench", "contact", "height_map", "layer_heights", "diagnostics")


def reader_qos(key: str) -> QoSProfile:
    """The contract QoS with a deep reader queue: a Python executor falls behind in bursts at
    1 kHz, and a keep-last-1 reader would then drop what a deeper one catches up on."""
    q = qos_for(key)
    depth = 10 if TOPICS[key].qos == "display" else 1000
    return QoSProfile(reliability=q.reliability, durability=q.durability, history=HistoryPolicy.KEEP_LAST, depth=depth)


def use_scene_env(env: dict[str, str]) -> None:
    """Adopt a scene's DDS domain and discovery range in this process (before any rclpy init)."""
    os.environ["ROS_DOMAIN_ID"] = env["ROS_DOMAIN_ID"]
    os.environ["ROS_AUTOMATIC_DISCOVERY_RANGE"] = env.get("ROS_AUTOMATIC_DISCOVERY_RANGE", "LOCALHOST")
    os.environ.pop("ROS_LOCALHOST_ONLY", None)


class Recorder:
    """Record contract topics to ``writer`` (or keep them in memory when ``writer`` is None).

    Parameters
    ----------
    keys : iterable of str or (str, str)
        ``msgs_schema.topics`` keys to record under the contract's names, or ``(key, name)``: contract topic ``key``
        under the relative name ``name`` (a hand's topic, :func:`msgs_schema.topics.hand_topic`), counted as ``name``.
    writer : BagWriter, optional
    name : str
        Node name.
    keep : bool
        Also keep ``(rx_ns, key, cdr)`` in :attr:`records` (for the live comparison).
    executor : {"single", "events"}
        ``single`` (default): measured in live replay, the wheel's EventsExecutor ``spin_once``
        stalled the publishing thread of this process for up to 50 ms (p99 37 ms late).
    """

    def __init__(
        self, keys, writer: BagWriter | None = None, name: str = "skin_sim_recorder", keep: bool = False, executor: str = "single"
    ):
        self.context = rclpy.Context()
        rclpy.init(context=self.context)
        self.node = rclpy.create_node(name, context=self.context)
        self.writer = writer
        self.keep = keep
        self.records: list[tuple[int, str, bytes]] = []
        topics = [(k, TOPICS[k].name) if isinstance(k, str) else tuple(k) for k in keys]
        self.counts = {key if name == TOPICS[key].name else name: 0 for key, name in topics}
        self._topics: dict[str, tuple[str, str, str]] = {}  # label -> (key, bag topic, type)
        self._queue: queue.SimpleQueue = queue.SimpleQueue()
        self._clock = self.node.get_clock()
        for (key, name), label in zip(topics, self.counts):
            spec = TOPICS[key]
            self._topics[label] = (key, "/" + name, spec.type)
            if writer is not None:
                writer.add_topic("/" + name, spec.type, qos_profiles(key))
            self.node.create_subscription(spec.msg_class, name, self._callback(label), reader_qos(key), raw=True)
        self._executor = make_executor(executor, self.context)
        self._executor.add_node(self.node)
        self._stop = threading.Event()
        self._spin_thread = threading.Thread(target=self._spin, name="recorder-spin", daemon=True)
        self._write_thread = threading.Thread(target=self._drain, name="recorder-write", daemon=True)
        self._spin_thread.start()
        self._write_thread.start()

    def _callback(self, key: str):
        def on_message(raw: bytes) -> None:
            rx = self._clock.now().nanoseconds
            self.counts[key] += 1
            if self.keep:
                self.records.append((rx, key, raw))
            if self.writer is not None:
                self._queue.put((rx, key, raw))

        return on_message

    def _spin(self) -> None:
        spin_context(self._executor, self.context, self._stop)

    def _drain(self) -> None:
        while True:
            item = self._queue.get()
            if item is None:
                return
            rx, label, raw = item
            assert self.writer is not None  # only a recorder with a writer queues records
            _, topic, msgtype = self._topics[label]
            self.writer.write_raw(topic, msgtype, rx, raw)

    def publisher(self, key: str):
        """A publisher of contract topic ``key`` on the recorder's node."""
        return publisher(self.node, key)

    def now_ns(self) -> int:
        """The recorder's clock now (ns): the stamps of what it writes."""
        return self._clock.now().nanoseconds

    def close(self) -> None:
        """Stop spinning, flush the queue to the writer (the caller closes the writer)."""
        self._stop.set()
        self._spin_thread.join(timeout=2.0)
        self._queue.put(None)
        self._write_thread.join()
        try:
            self.node.destroy_node()
        finally:
            rclpy.try_shutdown(context=self.context)
