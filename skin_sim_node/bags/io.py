"""rosbag2 reading and writing with ``rosbags`` (MCAP and sqlite3): typestore, errors, QoS.

No rclpy and no ``rosbag2_py``: messages are CDR bytes in and out. Deserialised messages
are ``rosbags`` dataclasses, which the attribute-access readers of
:mod:`msgs_schema.convert` accept as they accept rclpy messages.
"""

from __future__ import annotations

import shutil
from collections.abc import Iterator
from contextlib import contextmanager
from functools import cache
from pathlib import Path
from typing import Any, Final

from rosbags.interfaces import Connection, Qos, QosDurability, QosHistory, QosLiveliness, QosReliability, QosTime
from rosbags.rosbag2 import Reader, Writer
from rosbags.rosbag2.enums import CompressionFormat, CompressionMode, StoragePlugin
from rosbags.typesys import Stores, get_typestore

from msgs_schema.topics import TOPICS

BAG_VERSION: Final = 9
"""rosbag2 metadata version written: 9 is what Jazzy's ``ros2 bag record`` writes."""

STORAGES = {"mcap": StoragePlugin.MCAP, "sqlite3": StoragePlugin.SQLITE3}

# The contract's QoS classes (msgs_schema.qos.PROFILES) as rosbags QoS records, so the offline
# path needs no rclpy. tests/test_bags.py checks they agree with the rclpy profiles.
_ZERO = QosTime(0, 0)
_QOS_CLASSES = {
    "haptic": (QosReliability.BEST_EFFORT, 1),
    "display": (QosReliability.RELIABLE, 1),
    "diagnostics": (QosReliability.RELIABLE, 10),
}


class BagError(Exception):
    """A bag that cannot be used; the message names the bag and the problem."""


class BagNotFoundError(BagError):
    """The path is not a rosbag2 folder or bag file."""


class TruncatedBagError(BagError):
    """A storage file cannot be read to its end (cut short or corrupt)."""


class NoPoseTopicError(BagError):
    """The bag has no tool pose topic."""


class EmptyTopicError(BagError):
    """A topic the replay needs is in the bag but holds no messages."""


class UnknownMessageTypeError(BagError):
    """A topic the replay needs carries a message type it cannot use."""


@cache
def typestore():
    """The ROS 2 Jazzy typestore of ``rosbags`` (geometry, sensor, visualization, diagnostic msgs); the project's own
    types are added by :func:`register_project_type`."""
    return get_typestore(Stores.ROS2_JAZZY)


PROJECT_MSG_DIR = Path(__file__).resolve().parents[2] / "interfaces" / "skin_sim_msgs" / "msg"
"""The project's message definitions (the source tree's ``interfaces/skin_sim_msgs/msg``)."""


def register_project_type(msgtype: str, msgdef: str | None = None) -> bool:
    """Teach :func:`typestore` one of the project's types (``skin_sim_msgs/msg/NAME``), which rosbags does not know.

    ``msgdef``: the definition stored in a bag, if any (an MCAP schema may append its dependencies); else the source
    tree's ``.msg``. Returns False if neither is there (the caller then plays or records without that topic)."""
    from rosbags.typesys import get_types_from_msg

    ts = typestore()
    if msgtype in ts.types:
        return True
    path = PROJECT_MSG_DIR / f"{msgtype.rsplit('/', 1)[-1]}.msg"
    text = msgdef if msgdef and msgdef.strip() else (path.read_text() if path.is_file() else None)
    if text is None:
        return False
    ts.register(get_types_from_msg(text.split("\n====", 1)[0], msgtype))
    return True


def qos_profiles(topic_key: str) -> list[Qos]:
    """Offered QoS of a contract topic (``msgs_schema.topics`` key) as written to metadata.yaml."""
    reliability, depth = _QOS_CLASSES[TOPICS[topic_key].qos]
    return [
        Qos(
            QosHistory.KEEP_LAST,
            depth,
            reliability,
            QosDurability.VOLATILE,
            _ZERO,
            _ZERO,
            QosLiveliness.AUTOMATIC,
            _ZERO,
            False,
        )
    ]


def deserialize(raw: bytes, msgtype: str):
    """CDR bytes of type ``msgtype`` -> a ``rosbags`` message (the project's type store, ``ContactModel`` included)."""
    return typestore().deserialize_cdr(raw, msgtype)


def serialize(msg, msgtype: str) -> bytes:
    """A ``rosbags`` message of type ``msgtype`` -> CDR bytes."""
    return bytes(typestore().serialize_cdr(msg, msgtype))


def new_message(msgtype: str):
    """A zero-filled ``rosbags`` message of ``msgtype`` (fill it with :mod:`msgs_schema.convert`)."""
    ts = typestore()
    cls = ts.types[msgtype]
    kwargs = {}
    for name, (kind, arg) in _fields(msgtype):
        kwargs[name] = _default(ts, kind, arg)
    return cls(**kwargs)


def _fields(msgtype: str):
    return typestore().fielddefs[msgtype][1]


def _default(ts, kind, arg):
    from rosbags.interfaces import Nodetype

    if kind == Nodetype.NAME:
        return new_message(arg)
    if kind == Nodetype.BASE:
        name = arg[0]
        return "" if name == "string" else (False if name == "bool" else (0.0 if name.startswith("float") else 0))
    if kind == Nodetype.SEQUENCE:
        return [] if arg[0][0] != Nodetype.BASE or arg[0][1][0] == "string" else _empty_array(arg[0][1][0])
    raise NotImplementedError(f"no default for field kind {kind}")


def _empty_array(base: str):
    import numpy as np

    dtypes = {"float64": np.float64, "float32": np.float32, "uint8": np.uint8, "int8": np.int8, "int32": np.int32}
    return np.zeros(0, dtype=dtypes.get(base, np.float64))


class BagWriter:
    """Write CDR messages to a new rosbag2 folder. Use as a context manager.

    Parameters
    ----------
    path : Path
        The bag folder to create (must not exist; ``overwrite`` removes an old bag there).
    storage : {"mcap", "sqlite3"}
    compress : bool
        MCAP chunk compression with zstd (what ``ros2 bag record --storage-preset-profile
        zstd_fast`` does: metadata.yaml shows no compression, every reader decompresses).
    custom_data : dict of str, optional
        Written to metadata.yaml ``custom_data``.
    overwrite : bool
        Remove an existing bag folder (one with a metadata.yaml) at ``path`` first.
    """

    def __init__(self, path, storage: str = "mcap", compress: bool = False, custom_data=None, overwrite: bool = False):
        self.path = Path(path)
        if storage not in STORAGES:
            raise ValueError(f"storage {storage!r}: choose one of {', '.join(STORAGES)}")
        if overwrite and (self.path / "metadata.yaml").exists():
            shutil.rmtree(self.path)
        self._writer = Writer(self.path, version=BAG_VERSION, storage_plugin=STORAGES[storage])
        if compress:
            if storage != "mcap":
                raise ValueError("compress needs storage mcap")
            self._writer.set_compression(CompressionMode.STORAGE, CompressionFormat.ZSTD)
        self._writer.set_custom_data("skin_sim.writer", "skin_sim_node.bags")
        for k, v in (custom_data or {}).items():
            self._writer.set_custom_data(str(k), str(v))
        self._connections: dict[str, Connection] = {}
        self._writer.open()

    def add_topic(self, topic: str, msgtype: str, qos: list[Qos] | None = None) -> None:
        """Declare a topic (done implicitly by the first write of a contract topic)."""
        if topic not in self._connections:
            self._connections[topic] = self._writer.add_connection(
                topic, msgtype, typestore=typestore(), offered_qos_profiles=qos or []
            )

    def write_raw(self, topic: str, msgtype: str, t_ns: int, data: bytes, qos: list[Qos] | None = None) -> None:
        """Write CDR bytes with bag timestamp ``t_ns``."""
        if topic not in self._connections:
            self.add_topic(topic, msgtype, qos)
        self._writer.write(self._connections[topic], int(t_ns), data)

    def write(self, topic: str, msgtype: str, t_ns: int, msg, qos: list[Qos] | None = None) -> bytes:
        """Serialise a ``rosbags`` message and write it; returns the CDR bytes."""
        data = serialize(msg, msgtype)
        self.write_raw(topic, msgtype, t_ns, data, qos)
        return data

    def close(self) -> None:
        """Finish the bag (writes its metadata)."""
        self._writer.close()

    def __enter__(self) -> BagWriter:
        return self

    def __exit__(self, exc_type, *_) -> None:
        if exc_type is None:
            self.close()
        else:
            self._writer.abort()


def storage_files(path: Path) -> list[Path]:
    """The storage files of a bag folder (or the file itself)."""
    path = Path(path)
    if path.is_file():
        return [path]
    return sorted(p for p in path.iterdir() if p.suffix in (".mcap", ".db3"))


def _truncated(path: Path, exc: BaseException) -> TruncatedBagError:
    files = storage_files(path) if path.exists() else []
    name = ", ".join(str(f) for f in files) or str(path)
    detail = (str(exc).strip().splitlines() or [""])[0][:200]  # one line: the error is printed as one
    return TruncatedBagError(f"bag file {name} is truncated or corrupt ({type(exc).__name__}: {detail})")


def custom_data(path) -> dict[str, str]:
    """A rosbag2 folder's ``metadata.yaml`` ``custom_data`` (what :class:`BagWriter` wrote); empty when there is none or
    ``path`` is a single storage file."""
    import yaml

    meta = Path(path) / "metadata.yaml"
    if not meta.is_file():
        return {}
    try:
        info = yaml.safe_load(meta.read_text()).get("rosbag2_bagfile_information", {})
    except (yaml.YAMLError, AttributeError):
        return {}
    return {str(k): str(v) for k, v in (info.get("custom_data") or {}).items()}


def recorded_params(path) -> Path | None:
    """The shipped parameter preset a bag names (``custom_data`` ``skin_sim.params``, as ``skin-sim record`` and the
    replays write it), when the installed package has it; None otherwise. ``skin-sim replay`` and the bag view take it
    when no ``--params`` is given."""
    from ..scenes import DEFAULT_PARAMS

    recorded = custom_data(path).get("skin_sim.params")
    shipped = DEFAULT_PARAMS.parent / recorded if recorded else None
    return shipped if shipped is not None and shipped.is_file() else None


@contextmanager
def open_bag(path) -> Iterator[Reader]:
    """Open a rosbag2 folder (or a single .mcap/.db3 file) for reading, with clear errors.

    Raises
    ------
    BagNotFoundError
        No such path, or a folder without metadata.yaml.
    TruncatedBagError
        The metadata or a storage file cannot be read.
    """
    path = Path(path)
    if not path.exists():
        raise BagNotFoundError(f"{path}: no such bag")
    if path.is_dir() and not (path / "metadata.yaml").exists():
        raise BagNotFoundError(f"{path}: not a rosbag2 folder (no metadata.yaml)")
    try:
        reader = Reader(path)
        reader.open()
    except BagError:
        raise
    except Exception as exc:
        raise _truncated(path, exc) from exc
    try:
        yield reader
    finally:
        try:
            reader.close()
        except Exception:
            pass


def topic_types(reader: Reader) -> dict[str, str]:
    """``{topic: msgtype}`` of an open bag."""
    return {c.topic: c.msgtype for c in reader.connections}


def iter_raw(path, reader: Reader, topics) -> Iterator[tuple[str, str, int, bytes]]:
    """``(topic, msgtype, bag_t_ns, cdr)`` of the given topics in bag time order.

    Raises
    ------
    TruncatedBagError
        If the storage ends early or a record is corrupt.
    """
    conns = [c for c in reader.connections if c.topic in set(topics)]
    if not conns:
        return
    read = dict.fromkeys((c.id for c in conns), 0)
    try:
        for conn, t_ns, raw in reader.messages(connections=conns):
            read[conn.id] += 1
            yield conn.topic, conn.msgtype, t_ns, raw
    except BagError:
        raise
    except Exception as exc:
        raise _truncated(Path(path), exc) from exc
    # a record zeroed mid-file can end the reader's scan early without an error: compare with the index
    short = [f"{c.topic} {read[c.id]} of {c.msgcount}" for c in conns if c.msgcount and read[c.id] < c.msgcount]
    if short:
        raise _truncated(Path(path), EOFError(f"read {', '.join(short)} messages listed in its metadata"))


def iter_messages(path, reader: Reader, topics) -> Iterator[tuple[str, str, int, Any]]:
    """``(topic, msgtype, bag_t_ns, message)``: :func:`iter_raw` with each record decoded.

    Raises
    ------
    TruncatedBagError
        Also when a record's bytes do not decode (zeroed or overwritten mid-file).
    """
    for topic, msgtype, t_ns, raw in iter_raw(path, reader, topics):
        try:
            msg = deserialize(raw, msgtype)
        except Exception as exc:
            raise _truncated(Path(path), exc) from exc
        yield topic, msgtype, t_ns, msg


def describe_topics(types: dict[str, str]) -> str:
    """``{topic: type}`` as one line, sorted (``none`` for an empty bag), for error messages."""
    return ", ".join(f"{t} [{m}]" for t, m in sorted(types.items())) or "none"
