"""rclpy QoS profiles of the contract's QoS classes (see :mod:`msgs_schema.topics`)."""

from __future__ import annotations

from rclpy.qos import DurabilityPolicy, HistoryPolicy, QoSProfile, ReliabilityPolicy

from .topics import TOPICS

PROFILES = {
    "haptic": QoSProfile(
        reliability=ReliabilityPolicy.BEST_EFFORT,
        history=HistoryPolicy.KEEP_LAST,
        depth=1,
        durability=DurabilityPolicy.VOLATILE,
    ),
    "display": QoSProfile(
        reliability=ReliabilityPolicy.RELIABLE,
        history=HistoryPolicy.KEEP_LAST,
        depth=1,
        durability=DurabilityPolicy.VOLATILE,
    ),
    "diagnostics": QoSProfile(
        reliability=ReliabilityPolicy.RELIABLE,
        history=HistoryPolicy.KEEP_LAST,
        depth=10,
        durability=DurabilityPolicy.VOLATILE,
    ),
    # what a typical device driver subscribes with (reliable): used by the bridge towards drivers
    "driver": QoSProfile(
        reliability=ReliabilityPolicy.RELIABLE,
        history=HistoryPolicy.KEEP_LAST,
        depth=1,
        durability=DurabilityPolicy.VOLATILE,
    ),
}


def qos_for(key: str) -> QoSProfile:
    """The contract's QoS profile of topic ``key`` (its class in :data:`msgs_schema.topics.TOPICS`)."""
    return PROFILES[TOPICS[key].qos]


def publisher(node, key: str, name: str | None = None):
    """A publisher of topic ``key`` with its contract type and QoS; ``name`` overrides the topic name."""
    spec = TOPICS[key]
    return node.create_publisher(spec.msg_class, name or spec.name, qos_for(key))


def subscription(node, key: str, callback, name: str | None = None, depth: int | None = None, raw: bool = False):
    """Subscribe with the contract's QoS for ``key``; ``depth`` overrides its history depth; ``raw``: the callback
    gets the serialized CDR bytes (see :func:`msgs_schema.convert.read_stamped_vec3_cdr`)."""
    spec = TOPICS[key]
    profile = qos_for(key)
    if depth is not None and depth != profile.depth:
        profile = QoSProfile(reliability=profile.reliability, history=profile.history, depth=depth, durability=profile.durability)
    return node.create_subscription(spec.msg_class, name or spec.name, callback, profile, raw=raw)
