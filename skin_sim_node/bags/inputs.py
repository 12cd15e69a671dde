"""Tool inputs of a bag: pose and twist topics, foreign names, frames and device conventions.

Reads a bag's pose (and optional twist) messages, maps them into the tissue frame the way
the live chain does (a device convention goes through :class:`skin_sim_node.device.mapping.DeviceMapping`,
as the bridge does), and returns them merged in header-stamp order.
"""

from __future__ import annotations

import argparse
from collections import Counter
from dataclasses import dataclass, field
from pathlib import Path

from msgs_schema import convert as cv
from msgs_schema.topics import FRAMES, TOPICS, hand_topic

from ..device.mapping import CONVENTIONS, DEFAULTS, DeviceMapping
from ..device.mapping import parse_vec3 as _vec3
from .io import EmptyTopicError, NoPoseTopicError, UnknownMessageTypeError, describe_topics, iter_messages, open_bag, topic_types

POSE_TYPE = TOPICS["tool_pose"].type
TWIST_TYPE = TOPICS["tool_twist"].type
TWIST_FIRST, POSE = 0, 1  # sort rank at equal stamps: a twist is applied before the pose it goes with


@dataclass(frozen=True)
class InputOptions:
    """How to find and map the tool inputs of a bag.

    Parameters
    ----------
    pose_topic, twist_topic : str, optional
        Topic names; default ``tool/pose`` and ``tool/twist``, or the device topics of
        ``convention`` under ``device_ns``. ``twist_topic=""``: ignore twists.
    frame : str, optional
        The bag's frame_id to treat as the tissue frame.
    convention : {"crtk", "omni"}, optional
        The pose topic is a device driver's, in the device frame: map it with ``mapping``.
    device_ns : str
        Namespace of the device topics (the bridge's ``device_ns``).
    mapping : DeviceMapping
        Device -> tissue mapping (the bridge's defaults unless given).
    """

    pose_topic: str | None = None
    twist_topic: str | None = None
    frame: str | None = None
    convention: str | None = None
    device_ns: str = str(DEFAULTS["device_ns"])
    mapping: DeviceMapping = field(default_factory=DeviceMapping)

    def topics(self) -> tuple[str, str | None, bool]:
        """(pose topic, twist topic or None, twist topic given explicitly)."""
        if self.convention:
            pose_key, twist_key, _ = CONVENTIONS[self.convention]
            ns = self.device_ns.strip("/")

            def dev(key):
                return f"{ns}/{TOPICS[key].name}" if ns else TOPICS[key].name

            pose, twist = dev(pose_key), dev(twist_key) if twist_key else None
        else:
            pose, twist = TOPICS["tool_pose"].name, TOPICS["tool_twist"].name
        explicit = self.twist_topic is not None
        if self.pose_topic:
            pose = self.pose_topic
        if explicit:
            twist = self.twist_topic or None
        return pose, twist, explicit


@dataclass
class Inputs:
    """Tool inputs in the tissue frame, merged in stamp order.

    ``events``: ``(stamp_ns, rank, frame, xyz, quat)`` with rank :data:`TWIST_FIRST` (a twist, xyz
    is the velocity; quat None) or :data:`POSE` (quat: the orientation x, y, z, w). ``first_bag_ns``: bag time of the first input.
    """

    bag: Path
    pose_topic: str
    twist_topic: str | None
    events: list[tuple[int, int, str, tuple[float, float, float], tuple[float, float, float, float] | None]]
    n_poses: int
    n_twists: int
    first_bag_ns: int
    pose_frames: dict[str, int] = field(default_factory=dict)  # frame_id -> poses, as recorded (before any mapping)

    def frame_hint(self, tissue_frame: str) -> str | None:
        """What to do when poses arrive in frames other than ``tissue_frame`` (None: all poses are in it)."""
        foreign = {f: n for f, n in self.pose_frames.items() if f != tissue_frame}
        if not foreign:
            return None
        held = ", ".join(f"'{f}' ({n} poses)" for f, n in sorted(foreign.items(), key=lambda kv: -kv[1]))
        top = max(foreign, key=lambda f: foreign[f])
        return (
            f"{self.pose_topic} holds poses in frame {held}; the model answers only frame '{tissue_frame}': "
            f"map one with --frame {top} (it is then treated as the tissue frame), or --convention crtk|omni "
            "for a device driver's frame"
        )

    @property
    def poses(self):
        """The pose events only: ``(stamp_ns, frame_id, xyz)`` in bag order."""
        return [(e[0], e[2], e[3]) for e in self.events if e[1] == POSE]


def _find(types: dict[str, str], topic: str) -> str | None:
    """The bag's topic for a name given with or without the leading slash."""
    for name in (topic, "/" + topic.lstrip("/"), topic.lstrip("/")):
        if name in types:
            return name
    return None


def _check_type(bag: Path, types: dict[str, str], topic: str, kind: str, expected: str) -> None:
    if types[topic] != expected:
        raise UnknownMessageTypeError(
            f"{bag}: unknown message type '{types[topic]}' on {kind} topic '{topic}' (expected {expected})"
        )


def read_inputs(bag, opts: InputOptions, tissue_frame: str = FRAMES["tissue"]) -> Inputs:
    """Read and map the tool inputs of ``bag``.

    Raises
    ------
    NoPoseTopicError
        The pose topic is not in the bag (the message lists the topics present).
    UnknownMessageTypeError
        The pose or twist topic carries another message type.
    BagNotFoundError, TruncatedBagError
        See :func:`skin_sim_node.bags.io.open_bag`.
    """
    bag = Path(bag)
    want_pose, want_twist, explicit_twist = opts.topics()
    with open_bag(bag) as reader:
        types = topic_types(reader)
        pose_topic = _find(types, want_pose)
        if pose_topic is None:
            raise NoPoseTopicError(
                f"{bag}: no pose topic '/{want_pose.lstrip('/')}'; topics present: {describe_topics(types)} "
                "(choose one with --pose-topic, or --convention crtk|omni for a device driver's bag)"
            )
        _check_type(bag, types, pose_topic, "pose", POSE_TYPE)
        twist_topic = _find(types, want_twist) if want_twist else None
        if want_twist and twist_topic is None and explicit_twist:
            raise NoPoseTopicError(f"{bag}: no twist topic '/{want_twist.lstrip('/')}'; topics present: {describe_topics(types)}")
        if twist_topic:
            _check_type(bag, types, twist_topic, "twist", TWIST_TYPE)
        events = []
        n_pose = n_twist = 0
        frames: Counter[str] = Counter()
        first = None
        m = opts.mapping if opts.convention else None
        for topic, _, t_ns, msg in iter_messages(bag, reader, [pose_topic, twist_topic] if twist_topic else [pose_topic]):
            first = t_ns if first is None else first
            quat = None
            if topic == pose_topic:
                stamp, frame, xyz = cv.read_pose(msg)
                o = msg.pose.orientation
                quat = (float(o.x), float(o.y), float(o.z), float(o.w))
                rank = POSE
                n_pose += 1
                frames[frame] += 1
                if m is not None:
                    xyz, frame, quat = m.to_tissue(xyz), tissue_frame, m.orientation_to_tissue(quat)
            else:
                stamp, frame, xyz = cv.read_twist(msg)
                rank = TWIST_FIRST
                n_twist += 1
                if m is not None:
                    xyz, frame = m.velocity_to_tissue(xyz), tissue_frame
            if opts.frame is not None and frame == opts.frame:
                frame = tissue_frame
            # stamp 0: bag time, as the bridge; the orientation (x, y, z, w) rides along (the needle's axis), None for a twist
            events.append((stamp or t_ns, rank, frame, (float(xyz[0]), float(xyz[1]), float(xyz[2])), quat))
    if n_pose == 0:
        raise EmptyTopicError(
            f"{bag}: pose topic '{pose_topic}' holds no messages ({n_twist} on the twist topic); nothing to replay. "
            "Was the recording stopped before the tool moved, or is the pose on another topic (--pose-topic)?"
        )
    events.sort(key=lambda e: (e[0], e[1]))
    return Inputs(bag, pose_topic, twist_topic, events, n_pose, n_twist, first or 0, dict(frames))


def read_hand_inputs(bag, hands, frame: str | None = None, tissue_frame: str = FRAMES["tissue"]) -> list[Inputs]:
    """Each hand's tool inputs of a bag (issue 32): ``<hand>/tool/pose`` and, when recorded, ``<hand>/tool/twist``.

    Parameters
    ----------
    bag : path
    hands : sequence of str
        The hands' namespaces (:func:`skin_sim_node.bags.offline.hands_of`); '' is the single-tool names.
    frame : str, optional
        The bag's frame_id to treat as the tissue frame (as :attr:`InputOptions.frame`).
    tissue_frame : str

    Returns
    -------
    list of Inputs
        One per hand, in the order of ``hands``.

    Raises
    ------
    NoPoseTopicError
        A hand's pose topic is not in the bag.
    """
    bag = Path(bag)
    with open_bag(bag) as reader:
        types = topic_types(reader)
    out = []
    for ns in hands:
        pose, twist = hand_topic("tool_pose", ns), hand_topic("tool_twist", ns)
        if _find(types, pose) is None:
            raise NoPoseTopicError(
                f"{bag}: no pose topic '/{pose}' of hand '{ns}'; topics present: {describe_topics(types)} (the parameter "
                f"file's hands are {', '.join(repr(h) for h in hands)}: its hand_ns and second_hand_ns; replay a "
                "single-hand bag with a single-hand --params)"
            )
        opts = InputOptions(pose_topic=pose, twist_topic=twist if _find(types, twist) else "", frame=frame)
        out.append(read_inputs(bag, opts, tissue_frame))
    return out


# --- command-line options (shared by replay and live replay) --------------------------------
def add_input_arguments(ap: argparse.ArgumentParser) -> None:
    """The ``foreign bags`` option group (topics, frame, device convention and mapping) of ``replay`` and ``view``."""
    g = ap.add_argument_group("foreign bags")
    g.add_argument("--pose-topic", help="pose topic (default tool/pose, or the convention's device topic)")
    g.add_argument("--twist-topic", help="twist topic (default tool/twist or the convention's; '' to ignore twists)")
    g.add_argument("--frame", help="the bag's frame_id to treat as the tissue frame")
    g.add_argument("--convention", choices=sorted(CONVENTIONS), help="pose topic is a device driver's (device frame)")
    g.add_argument("--device-ns", default=DEFAULTS["device_ns"], help="device topic namespace (default 'device')")
    g.add_argument("--offset-m", type=_vec3, help="tissue position of the device origin, 'x y z' (m); as the bridge")
    g.add_argument("--scale", type=float, help="tissue m per device m; as the bridge")
    g.add_argument("--axes", help="tissue x, y, z as signed device axes, e.g. xyz or x-zy; as the bridge")


def input_options(args: argparse.Namespace) -> InputOptions:
    """The :class:`InputOptions` of parsed :func:`add_input_arguments` options."""
    kw = {k: v for k, v in (("offset_m", args.offset_m), ("scale", args.scale), ("axes", args.axes)) if v is not None}
    mapping = DeviceMapping(**kw)
    return InputOptions(args.pose_topic, args.twist_topic, args.frame, args.convention, args.device_ns, mapping)
