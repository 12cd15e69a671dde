"""The node's raw-CDR path (msgs_schema/convert.py) against rclpy's own serialization."""

import random

import pytest

pytest.importorskip("rclpy")
from geometry_msgs.msg import PoseStamped, TwistStamped, WrenchStamped
from rclpy.serialization import deserialize_message, serialize_message

from msgs_schema import convert as cv

FRAMES = ["", "a", "ab", "abc", "tissue", "abcdefg", "abcdefgh", "device_base_link"]  # every alignment of the vector


@pytest.mark.parametrize("frame", FRAMES)
def test_pose_and_twist_read_from_cdr_as_rclpy_deserializes_them(frame):
    rng = random.Random(frame)
    for _ in range(20):
        t = rng.randrange(0, (2**31 - 1) * 10**9)
        xyz = tuple(rng.uniform(-1.0, 1.0) for _ in range(3))
        pose = cv.fill_pose(PoseStamped(), t, frame, xyz, quat=(0.1, 0.2, 0.3, 0.9))
        assert cv.read_stamped_vec3_cdr(serialize_message(pose)) == cv.read_pose(pose) == (t, frame, xyz)
        twist = cv.fill_twist(TwistStamped(), t, frame, xyz)
        assert cv.read_stamped_vec3_cdr(serialize_message(twist)) == cv.read_twist(twist)


@pytest.mark.parametrize("frame", FRAMES)
def test_wrench_cdr_deserializes_to_the_filled_message(frame):
    w = cv.WrenchCdr(frame)
    for t, f in ((0, (0.0, 0.0, 0.0)), (1_700_000_000_123_456_789, (0.25, -1.5, 3.3)), (999_999_999, (1e-9, 2.0, -0.0))):
        m = deserialize_message(w.fill(t, f), WrenchStamped)
        ref = cv.fill_wrench(WrenchStamped(), t, frame, f)
        assert m == ref


def test_undecodable_buffers_raise_one_line_value_errors():
    good = serialize_message(cv.fill_pose(PoseStamped(), 5, "tissue", (0.0, 0.0, 0.0)))
    for bad in (b"", b"\x00\x01\x00\x00", good[:30], b"\x07" * 84, good[:4] + b"\xff\xff\xff\x7f" * 4):
        with pytest.raises(ValueError) as exc:
            cv.read_stamped_vec3_cdr(bad)
        assert "\n" not in str(exc.value)


def test_big_endian_encapsulation_is_read():
    import struct

    name = b"tissue\0"
    body = struct.pack(">iII", 12, 34, len(name)) + name
    body += b"\0" * (-len(body) % 8) + struct.pack(">3d", 1.0, -2.0, 0.5)
    assert cv.read_stamped_vec3_cdr(b"\x00\x00\x00\x00" + body) == (12 * 10**9 + 34, "tissue", (1.0, -2.0, 0.5))


def test_a_frame_id_without_its_nul_is_refused():
    good = bytearray(serialize_message(cv.fill_pose(PoseStamped(), 5, "tissue", (0.0, 0.0, 0.0))))
    good[15 + 7] = ord("x")  # the NUL after "tissue"
    with pytest.raises(ValueError, match="NUL"):
        cv.read_stamped_vec3_cdr(bytes(good))


@pytest.mark.parametrize("frame", FRAMES)
def test_pose_cdr_deserializes_to_the_filled_message(frame):
    p = cv.PoseCdr(frame)
    for t, xyz, q in (
        (0, (0.0, 0.0, 0.0), (0.0, 0.0, 0.0, 1.0)),
        (1_700_000_000_123_456_789, (0.01, -0.02, 0.3), (0.1, 0.2, 0.3, 0.9)),
    ):
        m = deserialize_message(p.fill(t, xyz, q), PoseStamped)
        assert m == cv.fill_pose(PoseStamped(), t, frame, xyz, quat=q)


@pytest.mark.parametrize("frame", ["", "tissue", "abcdefgh"])
def test_contact_model_cdr_reads_what_rclpy_serializes(frame):
    """The bridge's raw reader of tool/contact_model gives the LocalModel read_contact_model gives the message."""
    import numpy as np
    from skin_sim_msgs.msg import ContactModel

    from msgs_schema.contact_model import ContactModelCdr, read_contact_model

    rng = np.random.default_rng(len(frame))
    codec = ContactModelCdr.from_message_class(ContactModel)
    for needle in (False, True):
        msg = ContactModel()
        msg.header.frame_id = frame
        msg.header.stamp.sec, msg.header.stamp.nanosec = 1_700_000_000, 123_456_789
        msg.sequence = 2**40 + 7
        for name, typ in ContactModel.get_fields_and_field_types().items():
            if typ.startswith("double["):
                getattr(msg, name)[:] = rng.normal(size=len(getattr(msg, name)))
            elif typ == "double":
                setattr(msg, name, float(rng.uniform(0.1, 1.0)))
        msg.friction_state = 0.5
        msg.needle_axis[:] = (0.0, 0.6, -0.8) if needle else (0.0, 0.0, 0.0)
        got, want = codec.read(serialize_message(msg)), read_contact_model(msg)
        scalars = ("sequence", "stamp_ns", "frame_id", "validity_radius_m", "time_to_live_s", "answer_period_s", "needle")
        for f in (*scalars, "tangential_stiffness_n_per_m", "slip_force_n"):
            assert getattr(got, f) == getattr(want, f), f
        arrays = ("x0_m", "v0_m_s", "f0_n", "stiffness_n_per_m", "damping_n_s_per_m", "normal", "normal_force_gradient_n_per_m")
        for f in (*arrays, "friction_anchor_m"):
            assert np.array_equal(getattr(got, f), getattr(want, f)), f
    with pytest.raises(ValueError, match="truncated ContactModel"):
        codec.read(serialize_message(msg)[:60])
    with pytest.raises(ValueError, match="no raw reader"):
        ContactModelCdr({"header": "std_msgs/Header", "flag": "boolean"})
