"""One hand of the node (issue 32): its session, its answer rate and its topics. Thin: no physics, no parameters.

A hand is one tool and the device that holds it. The node has one per ``hand_ns`` / ``second_hand_ns``; each hand's
tool presses the one tissue (:class:`~skin_sim_node.tools.hands.SharedSkin`). A hand's topics are the contract's
under its namespace (:func:`msgs_schema.topics.hand_topic`); a single hand with ``hand_ns`` '' has the single-tool
names. The node's lock orders every hand's ticks, so the tools step one after another on the shared tissue.
"""

from __future__ import annotations

import time
from collections import deque
from collections.abc import Callable

from sensor_msgs.msg import JointState
from skin_sim_msgs.msg import ContactModel

from msgs_schema import convert as cv
from msgs_schema.parameters import NodeParams, session_params
from msgs_schema.qos import publisher, subscription
from msgs_schema.topics import hand_topic

from ..rate import ServerRate
from ..session import HapticSession, TickResult
from ..tools import Tool

READERS_CHECK_NS = 100_000_000
"""How often the tick asks DDS whether ``tissue/contact`` and ``tool/contact_model`` have readers (100 ms).
Neither is published while nobody reads it, as image_transport's lazy publishers do: measured here, the two
publishes were most of what a tick costs beyond the wrench. A reader that joins gets them from the next check on;
``tool/wrench`` is always published."""

INBOX_LEN = 256
"""Inputs a hand keeps for the next holder of the node's lock (:attr:`Hand.inbox`): 0.26 s of 1 kHz poses, five times
the 50 ms watchdog. It fills only while poses keep arriving and no thread takes them for that long; then the oldest
go (counted in :attr:`Hand.inbox_dropped`; DDS's keep-last queue drops the same way), which the newest pose and twist
supersede anyway."""


class Hand:
    """One hand's session, server rate and publishers in the node.

    Parameters
    ----------
    node : rclpy.node.Node
        The node its topics belong to.
    ns : str
        The hand's namespace ('' : the single-tool topic names).
    tool : Tool
        Its tool (a :class:`~skin_sim_node.tools.hands.CoupledTool` of the shared tissue with two hands).
    params : NodeParams
    frame : str
        The tissue frame of its messages.
    sim_time : bool
        The node runs on ``use_sim_time`` (pose stamps are not on the system clock).
    log : callable(kind, message)
        The session's event log.
    index : int
        Its place in the node's hands (0: the first).
    """

    def __init__(self, node, ns: str, tool: Tool, params: NodeParams, frame: str, sim_time: bool, log: Callable, index: int = 0):
        self.ns = ns
        self.index = index
        self.session = HapticSession(tool, session_params(params), log=log)
        self.frame = frame
        self.sim_time = sim_time
        self.rate = ServerRate(params, time.perf_counter_ns(), pose_ages=not sim_time)
        self.last: TickResult | None = None
        self.last_tick_ns = time.perf_counter_ns()
        self.last_pub_ns = 0  # last wrench publish (idle heartbeat)
        self.last_pub_force = 0.0  # last published force (N): the idle heartbeat holds back only zeros
        self.n_idle_skipped = 0
        self.n_ticks = 0
        self.wrench_cdr = cv.WrenchCdr(frame)
        self.contact = JointState()
        self.model_msg = ContactModel()
        self.pub_wrench = publisher(node, "tool_wrench", self.topic("tool_wrench"))
        self.pub_contact = publisher(node, "contact", self.topic("contact"))
        self.pub_model = publisher(node, "contact_model", self.topic("contact_model"))
        self.readers_checked_ns = -READERS_CHECK_NS
        self.contact_read = self.model_read = True
        self.readouts: dict = {}  # a tool's own read-out topic (ToolNeeds.readout): key -> (publisher, message)
        self.inbox: deque = deque(maxlen=INBOX_LEN)
        """The hand's inputs not yet taken, in arrival order: ``("pose", stamp, frame, xyz, quat, rx_ns, ros_now_ns)``
        and ``("twist", stamp, frame, linear)``. Posted without the node's lock (a deque's append is atomic), taken
        by whichever thread next holds it, before any tick of this hand: a thread that waits for the lock never
        holds back the poses the watchdog sees."""
        self.inbox_dropped = 0
        self.poses_superseded = 0
        """Poses a newer pose of the same hand replaced in the inbox before any thread took them."""
        self._node = node
        self.add_readout()

    def topic(self, key: str) -> str:
        """The relative name of contract topic ``key`` for this hand."""
        return hand_topic(key, self.ns)

    def post(self, item: tuple) -> None:
        """Queue one input for the next holder of the node's lock (:attr:`inbox`); no lock taken."""
        if len(self.inbox) == INBOX_LEN:
            self.inbox_dropped += 1
        self.inbox.append(item)

    def subscribe(self, on_pose: Callable[[bytes], None], on_twist: Callable[[bytes], None], depth: int) -> None:
        """Its pose and twist readers, serialized (no rclpy message objects on the 1 kHz path)."""
        subscription(self._node, "tool_pose", on_pose, name=self.topic("tool_pose"), depth=depth, raw=True)
        subscription(self._node, "tool_twist", on_twist, name=self.topic("tool_twist"), depth=depth, raw=True)

    def set_params(self, params: NodeParams, now_ns: int) -> None:
        """A live parameter set: new session limits and a new server rate."""
        self.session.params = session_params(params)
        self.rate = ServerRate(params, now_ns, pose_ages=not self.sim_time)

    def add_readout(self) -> None:
        """The publisher of the tool's own read-out topic (:attr:`ToolNeeds.readout`), if it declares one: created for
        the first tool that needs it, kept across tool changes (ROS publishers are not destroyed under readers)."""
        ro = self.session.tool.needs.readout
        if ro is not None and ro.topic not in self.readouts:
            pub = publisher(self._node, ro.topic, self.topic(ro.topic))
            self.readouts[ro.topic] = (pub, pub.msg_type())

    def publish_readout(self, stamp_ns: int) -> None:
        """The tool's read-out topic (``tissue/needle``) at the display rate, while read (a few us; under the lock)."""
        ro = self.session.tool.needs.readout
        if ro is None:
            return
        pub, msg = self.readouts[ro.topic]
        if pub.get_subscription_count() == 0 or (state := self.session.readout()) is None:
            return
        pub.publish(ro.fill(msg, state, stamp_ns, self.frame))

    def publish(self, r: TickResult, now_ns: int, stamp_ns: int, heartbeat_hz: float, sink=None) -> None:
        """Publish a tick's wrench, and its contact model and contact while read (under the node's lock).

        Parameters
        ----------
        r : TickResult
        now_ns : int
            The node's monotonic clock.
        stamp_ns : int
            The stamp of its messages: the answered pose's, or the node's clock for a tick that answers none.
        heartbeat_hz : float
            ``idle_heartbeat_hz``: a tissue at rest, untouched, publishes at most at this rate (0: every tick).
        sink : callable(ContactModel) or None
            A composed bridge's hand-off of the contact model (no DDS hop).
        """
        force = r.force_z_n
        quiet = force == 0.0 and self.last_pub_force == 0.0  # never hold back a force still ramping down
        if heartbeat_hz > 0 and quiet and r.idle and not r.stale and now_ns - self.last_pub_ns < 1e9 / heartbeat_hz:
            self.n_idle_skipped += 1  # lod idle: the tissue is at rest and untouched; heartbeat publishes only
            return
        self.last_pub_ns = now_ns
        self.last_pub_force = force
        self.pub_wrench.publish(self.wrench_cdr.fill_from_tick(r, stamp_ns))
        if now_ns - self.readers_checked_ns >= READERS_CHECK_NS:
            self.readers_checked_ns = now_ns
            self.contact_read = self.pub_contact.get_subscription_count() > 0
            self.model_read = self.pub_model.get_subscription_count() > 0
        if self.model_read or sink is not None:  # the bridge renders it
            msg = cv.fill_contact_model_from_tick(
                self.model_msg, r, stamp_ns, self.frame, answer_period_s=self.rate.answer_period_s
            )
            if self.model_read:
                self.pub_model.publish(msg)
            if sink is not None:
                sink(msg)
        if self.contact_read:
            self.pub_contact.publish(cv.fill_contact_from_tick(self.contact, r, stamp_ns, self.frame))
