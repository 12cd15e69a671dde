"""The skin-sim contract: topics, message types, QoS, units, frames and parameters.

Defined once here and imported by the node, the device bridge, the mock tool, the
replay tools and the tests. :mod:`msgs_schema.topics` and :mod:`msgs_schema.parameters`
import no ROS code; :mod:`msgs_schema.convert` and :mod:`msgs_schema.qos` do.
"""

from .topics import FRAMES, TOPICS, TopicSpec

__all__ = ["FRAMES", "TOPICS", "TopicSpec"]
