"""Rosbag2 record and replay with ``rosbags`` (MCAP and sqlite3; no ``ros2 bag``, no ``rosbag2_py``).

- :mod:`.record`: ``skin-sim record``, a scene's inputs and outputs to a bag (rclpy).
- :mod:`.replay`: ``skin-sim replay``, offline through the model (no DDS) and ``--live``.
- :mod:`.compare`: ``skin-sim compare``, diff two output bags with tolerances.
- :mod:`.golden`: the golden bags under ``tests/data``.
- :mod:`.io`, :mod:`.inputs`, :mod:`.offline`, :mod:`.report`, :mod:`.recorder`, :mod:`.live`: the parts.
- :mod:`.monitor` (the in-process observer of a node) and :mod:`.plots` (cross-section figures): the demo and the
  report use them, so they are runtime, not lab (issue 28).

See ``docs/bags.md``.
"""
