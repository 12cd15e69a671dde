"""Every topic of skin-sim: relative name, standard message type, QoS, units, frame, rate.

Names are relative, so ``--ros-args -r __ns:=/bed1`` or remapping works. QoS classes:

- ``haptic``: best-effort, keep-last 1, volatile. A 1 kHz force loop wants the newest
  sample, never a queue of old ones: a retransmitted stale pose or force is worse than a
  lost one, and a reliable writer blocks or buffers when a reader stalls. A best-effort
  reader also matches reliable writers, so any device driver can feed the node.
  The node's pose and twist readers use history depth ``input_queue_depth`` (default 1; live
  replay uses 500, ``skin_sim_node/bags/live.py: LIVE_QUEUE_DEPTH``, so that a stalled node
  answers every sample in order).
- ``display``: reliable, keep-last 1, volatile. Display-rate data that RViz (whose
  default subscriptions are reliable) must receive; the newest frame only.
- ``diagnostics``: reliable, keep-last 10.
"""

from __future__ import annotations

from dataclasses import dataclass

FRAMES = {
    "tissue": "tissue",  # x, y in the sheet plane, sheet centred on the origin, z up, rest surface z = 0
    "tool": "tool_tip",
}


@dataclass(frozen=True)
class TopicSpec:
    """One topic of the contract: relative name, ``package/msg/Type``, QoS class, units, frame and rate."""

    name: str  # relative topic name
    type: str  # package/msg/Type
    qos: str  # haptic | display | diagnostics
    units: str
    frame: str
    rate: str
    description: str

    @property
    def msg_class(self):
        """The rclpy message class (imports the ROS message package)."""
        import importlib

        pkg, _, cls = self.type.split("/")
        return getattr(importlib.import_module(f"{pkg}.msg"), cls)


TOPICS = {
    # --- inputs of skin_sim_node
    "tool_pose": TopicSpec(
        "tool/pose", "geometry_msgs/msg/PoseStamped", "haptic", "m", FRAMES["tissue"], "device rate (1 kHz)",
        "Tool tip pose in the tissue frame. The orientation is used by the needle (tool.shape 'needle'): its axis toward "
        "the tip is the orientation applied to (0, 0, -1), so the identity points straight down into the tissue; a "
        "needle pose with a non-finite or non-unit quaternion is rejected. The flat punch and the sphere ignore it.",
    ),
    "tool_twist": TopicSpec(
        "tool/twist", "geometry_msgs/msg/TwistStamped", "haptic", "m/s, rad/s", FRAMES["tissue"], "device rate",
        "Optional tool tip velocity; without it the node differentiates the poses.",
    ),
    # --- outputs of skin_sim_node
    "tool_wrench": TopicSpec(
        "tool/wrench", "geometry_msgs/msg/WrenchStamped", "haptic", "N, N*m", FRAMES["tissue"], "haptic rate (1 kHz)",
        "Reaction force on the tool, in the tissue frame (force.z >= 0 pushes the tool out). "
        "Header stamp = stamp of the pose it answers.",
    ),
    "contact": TopicSpec(
        "tissue/contact", "sensor_msgs/msg/JointState", "haptic", "m, m/s, Pa", FRAMES["tissue"], "haptic rate, while read",
        "Contact state, one entry per layer (epidermis, dermis, fat): position = compression (m), "
        "velocity = compression rate (m/s), effort = layer stress (Pa, 0 when not affected).",
    ),
    "contact_model": TopicSpec(
        "tool/contact_model", "skin_sim_msgs/msg/ContactModel", "haptic", "m, m/s, N, N/m, N*s/m, 1, s", FRAMES["tissue"],
        "with each force (haptic rate), while read",
        "Local contact model for the device bridge (msgs_schema/contact_model.py, docs/devices.md): the answered pose "
        "x0, force f0, K = dF/dx, D = dF/dv, normal, validity radius, time-to-live, sequence number.",
    ),
    "height_map": TopicSpec(
        "tissue/height_map", "sensor_msgs/msg/Image", "display", "m", FRAMES["tissue"], "display rate (60 Hz), while read",
        "32FC1 surface height (m, z up) over the sheet; row 0 at y = -size_y/2, column 0 at x = -size_x/2.",
    ),
    "layer_heights": TopicSpec(
        "tissue/layer_heights", "sensor_msgs/msg/Image", "display", "m", FRAMES["tissue"], "display rate, while read",
        "32FC3: per cell the heights (m, z up) of the surface, the epidermis/dermis and the dermis/fat interfaces.",
    ),
    "mesh": TopicSpec(
        "tissue/mesh", "visualization_msgs/msg/Marker", "display", "m", FRAMES["tissue"], "mesh_rate_hz, while read",
        "TRIANGLE_LIST mesh of the deformed surface, coloured by the deepest affected layer under each vertex.",
    ),
    "needle": TopicSpec(
        "tissue/needle", "skin_sim_msgs/msg/NeedleState", "display", "m, N", FRAMES["tissue"], "display rate, while read",
        "The needle (tool.shape 'needle'): tip, axis, track entry, insertion, dimple, punctured layers, the layers' "
        "crossings along the track and the axial force's parts (interfaces/skin_sim_msgs/msg/NeedleState.msg).",
    ),
    "diagnostics": TopicSpec(
        "diagnostics", "diagnostic_msgs/msg/DiagnosticArray", "diagnostics", "-", "", "1 Hz",
        "Achieved rate, overruns, kernel time, input age, rejected inputs, watchdog state.",
    ),
    # --- device bridge side (relative to the bridge's device namespace)
    "crtk_measured_cp": TopicSpec(
        "measured_cp", "geometry_msgs/msg/PoseStamped", "haptic", "m", "device base", "device rate",
        "CRTK (sawSensablePhantom) measured Cartesian position of the stylus.",
    ),
    "crtk_measured_cv": TopicSpec(
        "measured_cv", "geometry_msgs/msg/TwistStamped", "haptic", "m/s", "device base", "device rate",
        "CRTK measured Cartesian velocity.",
    ),
    "crtk_measured_cf": TopicSpec(
        "measured_cf", "geometry_msgs/msg/WrenchStamped", "haptic", "N", "device base", "device rate",
        "CRTK measured Cartesian force: what the device applied over the servo tick that ended at the pose of the "
        "same stamp (the bridge's passivity observer books it).",
    ),
    "crtk_servo_cf": TopicSpec(
        "servo_cf", "geometry_msgs/msg/WrenchStamped", "haptic", "N", "device base", "device rate",
        "CRTK Cartesian force command.",
    ),
    "omni_pose": TopicSpec(
        "phantom/pose", "geometry_msgs/msg/PoseStamped", "haptic", "m", "device base", "device rate",
        "omni_common family pose topic.",
    ),
    "omni_force": TopicSpec(
        "phantom/force_feedback", "geometry_msgs/msg/WrenchStamped", "haptic", "N", "device base", "device rate",
        "Force command in the omni_common family (AleBarte Geomagic_Touch_ROS2_Drivers: touch/force_feedback).",
    ),
}  # fmt: skip


HAND_TOPICS = ("tool_pose", "tool_twist", "tool_wrench", "contact", "contact_model", "needle")
"""The topics each hand has its own of (issue 32): its tool's inputs, force, contact and local model, and its tool's
read-out. The others (the tissue's grid, mesh and diagnostics) are the tissue's, one per node."""


def hand_topic(key: str, hand_ns: str) -> str:
    """The relative name of topic ``key`` for the hand in namespace ``hand_ns`` (the node's ``hand_ns`` /
    ``second_hand_ns``): ``<hand_ns>/<name>`` for :data:`HAND_TOPICS`, the contract's name otherwise and for ''.

    Parameters
    ----------
    key : str
        Key of :data:`TOPICS`.
    hand_ns : str
        The hand's namespace ('' : the single-tool names).

    Returns
    -------
    str
    """
    name = TOPICS[key].name
    return f"{hand_ns}/{name}" if hand_ns and key in HAND_TOPICS else name
