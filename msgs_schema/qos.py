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
    "haptic_input": QoSProfile(
        reliability=ReliabilityPolicy.BEST_EFFORT,
        history=HistoryPolicy.KEEP_LAST,
        depth=10,
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
    return PROFILES[TOPICS[key].qos]


def publisher(node, key: str, name: str | None = None):
    spec = TOPICS[key]
    return node.create_publisher(spec.msg_class, name or spec.name, qos_for(key))


def subscription(node, key: str, callback, name: str | None = None, qos: str | None = None):
    """Subscribe with the contract's QoS for ``key`` (or the named QoS class ``qos``)."""
    spec = TOPICS[key]
    profile = PROFILES[qos] if qos else qos_for(key)
    return node.create_subscription(spec.msg_class, name or spec.name, callback, profile)
