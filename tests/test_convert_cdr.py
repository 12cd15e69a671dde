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
