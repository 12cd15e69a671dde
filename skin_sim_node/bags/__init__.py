"""Rosbag2 record and replay with ``rosbags`` (MCAP and sqlite3; no ``ros2 bag``, no ``rosbag2_py``).

- :mod:`.record`: ``skin-sim record``, a scene's inputs and outputs to a bag (rclpy).
- :mod:`.replay`: ``skin-sim replay``, offline through the model (no DDS) and ``--live``.
- :mod:`.compare`: ``skin-sim compare``, diff two output bags with tolerances.
- :mod:`.golden`: the golden bags under ``tests/data``.
- :mod:`.io`, :mod:`.inputs`, :mod:`.offline`, :mod:`.report`, :mod:`.recorder`, :mod:`.live`: the parts.

See ``docs/bags.md``.
"""
