"""The local contact model message (issue 12): what the node sends the device bridge with each force.

The node publishes ``skin_sim_msgs/msg/ContactModel`` on ``tool/contact_model`` (QoS class
``haptic``: best-effort, keep-last 1; a lost model is covered by the previous one until its
time-to-live runs out). The bridge renders it from the device's own pose every servo tick
(:mod:`skin_sim_node.device.render`): with the presliding friction (``tangential_stiffness_n_per_m > 0``, issue 30)::

    F(x) = F_n(x) n - k_t s(x) + (f0 - F(x0)),   F_n(x) = F_n0 + grad(F_n) . (x - x0),
    s = (I - n n^T) (x - z),  z <- z + (|s| - r) s / |s|  when |s| > r = mu F_n(x) / k_t,

the anchor ``z`` starting from ``friction_anchor_m`` and following the device's own positions (no velocity); with
the legacy velocity law (``slip_speed_m_s > 0``, issue 19; skin_sim_node no longer sends it, the figures' baseline
does) ``F(x, v) = F_n(x) (n - mu v_t / sqrt(|v_t|^2 + v_s^2)) + (f0 - F_law(x0, v0))``; else
``F(x, v) = f0 + K (x - x0) + D (v - v0)``. With a needle law (:class:`NeedleLaw`, issue 22) the axial part
follows the needle's piecewise law with its rupture ahead and its Dahl friction (``ContactModel.msg`` spells it out)
and the rest ``f0 + (I - u u^T) K (x - x0)``. ``K`` and ``D`` are always the law's linearisation at ``x0``,
``v0``, for consumers that render only them. The message
definition is ``interfaces/skin_sim_msgs/msg/ContactModel.msg``, built by ``scripts/setup.sh``; why a
package and not a layout in standard messages: ``docs/devices.md``.

:class:`LocalModel` is the plain (no ROS) form; :func:`fill_contact_model` and
:func:`read_contact_model` convert with attribute access only, so they work on rclpy messages and
on ``rosbags`` dataclasses alike. This module imports no ROS code.
"""

from __future__ import annotations

import math
import struct
from dataclasses import dataclass, field, replace

import numpy as np

MSG_TYPE = "skin_sim_msgs/msg/ContactModel"

DEFAULT_TTL_S = 0.05
"""Time-to-live of a model (s). The node's input watchdog (``watchdog_s`` = 50 ms): a model older than
that comes from a server that has stopped answering, and 50 ms is 5 server periods at the slowest
rate of the rate lever (100 Hz), so one or two lost models never start a fade."""

DEFAULT_VALIDITY_RADIUS_M = 2e-3
"""Validity radius (m). A linearisation of the tissue holds while the tool stays within a fraction of
the layer thicknesses (dermis ~1.3 mm, docs/model.md); 2 mm is 20 periods of a brisk 0.1 m/s drag at
1 kHz and 5 at 250 Hz, so an ordinary stroke never leaves the model between updates."""


STALE_RADIUS_M = 10.0
"""Validity radius of the zero model a stale tick sends (m): larger than any device workspace (a Touch's is
160 x 120 x 70 mm), so the bridge renders the zero force wherever the tool is."""


@dataclass(frozen=True)
class NeedleLaw:
    """The needle's axial law at ``x0`` (fields and equations as the needle block of ``ContactModel.msg``).

    Along the track's unit axis ``axis`` (toward the tip), ``s = axis . (x - x0)``; the axial resistance (N, > 0
    resists insertion) is ``R_e(s) + F_c(s) z(s)``: ``R_e`` linear in ``s`` (its own slope behind ``x0``, where the
    cutting force fades) up to ``rupture_distance_m`` and, from
    the first ``s`` that reaches it, the post-rupture line (latched); ``F_c`` the Dahl friction's Coulomb level,
    growing with the inserted length; ``z`` the Dahl state, integrated over the device's own moves.
    """

    axis: tuple[float, float, float]
    axial_force_n: float = 0.0
    axial_gradient_n_per_m: float = 0.0
    axial_gradient_behind_n_per_m: float = 0.0
    rupture_distance_m: float = 0.0
    post_rupture_force_n: float = 0.0
    post_rupture_gradient_n_per_m: float = 0.0
    friction_capacity_n: float = 0.0
    friction_capacity_gradient_n_per_m: float = 0.0
    friction_state: float = 0.0
    dahl_length_m: float = 1e-3

    FIELDS = (
        "axial_force_n",
        "axial_gradient_n_per_m",
        "axial_gradient_behind_n_per_m",
        "rupture_distance_m",
        "post_rupture_force_n",
        "post_rupture_gradient_n_per_m",
        "friction_capacity_n",
        "friction_capacity_gradient_n_per_m",
        "friction_state",
        "dahl_length_m",
    )
    """The scalar fields, named as in the message."""

    def scaled(self, k: float) -> NeedleLaw:
        """The law with every force and gradient times ``k`` (the session's limits scale the whole force)."""
        forces = {f: getattr(self, f) * k for f in self.FIELDS if f.endswith(("_n", "_n_per_m"))}
        return replace(self, **forces)

    @property
    def resistance_n(self) -> float:
        """``R(0)``: the axial resistance at ``x0``, friction included (N)."""
        return self.axial_force_n + self.friction_capacity_n * self.friction_state

    @property
    def finite(self) -> bool:
        """Every number finite, the axis a unit vector, ``|z| <= 1`` and ``x_0 > 0``."""
        vals = (*self.axis, *(getattr(self, f) for f in self.FIELDS))
        return (
            all(math.isfinite(v) for v in vals)
            and abs(math.hypot(*self.axis) - 1.0) < 1e-6
            and abs(self.friction_state) <= 1.0
            and self.dahl_length_m > 0.0
        )


@dataclass(frozen=True)
class LocalModel:
    """One local contact model, tissue frame, SI units (fields as ``ContactModel.msg``).

    ``stiffness_n_per_m`` and ``damping_n_s_per_m`` are (3, 3) with the force on the tool as
    output: ``normal . K . normal <= 0`` for a tissue that pushes back harder the deeper it is pressed.
    ``normal_force_n``, ``normal_force_gradient_n_per_m`` (3,), ``friction_coefficient``,
    ``tangential_stiffness_n_per_m``, ``friction_anchor_m`` (3,) and ``slip_force_n`` carry the presliding friction
    (module docstring; ``slip_force_n = mu F_n0``, the slip level at ``x0``); ``slip_speed_m_s`` the legacy velocity
    law; all zero (the defaults): no law, the linear form.
    """

    sequence: int
    stamp_ns: int
    frame_id: str
    x0_m: np.ndarray
    v0_m_s: np.ndarray
    f0_n: np.ndarray
    stiffness_n_per_m: np.ndarray
    damping_n_s_per_m: np.ndarray
    normal: np.ndarray
    validity_radius_m: float = DEFAULT_VALIDITY_RADIUS_M
    time_to_live_s: float = DEFAULT_TTL_S
    normal_force_n: float = 0.0
    normal_force_gradient_n_per_m: np.ndarray = field(default_factory=lambda: np.zeros(3))
    friction_coefficient: float = 0.0
    slip_speed_m_s: float = 0.0
    needle: NeedleLaw | None = None
    tangential_stiffness_n_per_m: float = 0.0
    friction_anchor_m: np.ndarray = field(default_factory=lambda: np.zeros(3))
    slip_force_n: float = 0.0
    answer_period_s: float = 0.0
    coupling_rate_n_per_s: np.ndarray = field(default_factory=lambda: np.zeros(3))

    def __post_init__(self):
        for name, shape in (
            ("coupling_rate_n_per_s", (3,)),
            ("friction_anchor_m", (3,)),
            ("normal_force_gradient_n_per_m", (3,)),
            ("x0_m", (3,)),
            ("v0_m_s", (3,)),
            ("f0_n", (3,)),
            ("normal", (3,)),
            ("stiffness_n_per_m", (3, 3)),
            ("damping_n_s_per_m", (3, 3)),
        ):
            object.__setattr__(self, name, np.asarray(getattr(self, name), dtype=float).reshape(shape))

    @property
    def finite(self) -> bool:
        """True if every number is finite and the radius and time-to-live are >= 0."""
        arrays = (
            self.x0_m, self.v0_m_s, self.f0_n, self.stiffness_n_per_m, self.damping_n_s_per_m, self.normal,
            self.coupling_rate_n_per_s,
        )  # fmt: skip
        law = (self.normal_force_n, self.friction_coefficient, self.slip_speed_m_s, self.tangential_stiffness_n_per_m)
        return (
            all(bool(np.isfinite(a).all()) for a in arrays)
            and bool(np.isfinite(self.normal_force_gradient_n_per_m).all())
            and bool(np.isfinite(self.friction_anchor_m).all())
            and math.isfinite(self.slip_force_n)
            and self.tangential_stiffness_n_per_m >= 0
            and all(math.isfinite(c) for c in law)
            and self.friction_coefficient >= 0
            and self.slip_speed_m_s >= 0
            and math.isfinite(self.validity_radius_m)
            and self.validity_radius_m >= 0
            and math.isfinite(self.time_to_live_s)
            and self.time_to_live_s >= 0
            and (self.needle is None or self.needle.finite)
        )


def fill_contact_model(msg, m: LocalModel):
    """Fill a ``ContactModel`` message the caller owns (preallocated on the haptic path)."""
    msg.header.stamp.sec, msg.header.stamp.nanosec = divmod(int(m.stamp_ns), 1_000_000_000)
    msg.header.frame_id = m.frame_id
    msg.sequence = int(m.sequence)
    msg.x0_m[:] = m.x0_m
    msg.v0_m_s[:] = m.v0_m_s
    msg.f0_n[:] = m.f0_n
    msg.stiffness_n_per_m[:] = m.stiffness_n_per_m.ravel()
    msg.damping_n_s_per_m[:] = m.damping_n_s_per_m.ravel()
    msg.normal[:] = m.normal
    msg.validity_radius_m = float(m.validity_radius_m)
    msg.time_to_live_s = float(m.time_to_live_s)
    msg.normal_force_n = float(m.normal_force_n)
    msg.normal_force_gradient_n_per_m[:] = m.normal_force_gradient_n_per_m
    msg.friction_coefficient = float(m.friction_coefficient)
    msg.slip_speed_m_s = float(m.slip_speed_m_s)
    msg.tangential_stiffness_n_per_m = float(m.tangential_stiffness_n_per_m)
    msg.friction_anchor_m[:] = m.friction_anchor_m
    msg.slip_force_n = float(m.slip_force_n)
    fill_needle_law(msg, m.needle)
    msg.answer_period_s = float(m.answer_period_s)
    msg.coupling_rate_n_per_s[:] = m.coupling_rate_n_per_s
    return msg


def fill_needle_law(msg, law: NeedleLaw | None) -> None:
    """The needle block of a ``ContactModel`` message (all zeros for ``None``: no needle law)."""
    msg.needle_axis[:] = (0.0, 0.0, 0.0) if law is None else law.axis
    for f in NeedleLaw.FIELDS:
        setattr(msg, f, 0.0 if law is None else float(getattr(law, f)))


def read_needle_law(msg) -> NeedleLaw | None:
    """The needle block of a ``ContactModel`` message; ``None`` when its axis is zero (no needle law)."""
    axis = tuple(float(c) for c in msg.needle_axis)
    if not any(axis):
        return None
    return NeedleLaw(axis, **{f: float(getattr(msg, f)) for f in NeedleLaw.FIELDS})  # type: ignore[arg-type]


def read_contact_model(msg) -> LocalModel:
    """``ContactModel`` message -> :class:`LocalModel` (copies the arrays)."""
    return LocalModel(
        sequence=int(msg.sequence),
        stamp_ns=int(msg.header.stamp.sec) * 1_000_000_000 + int(msg.header.stamp.nanosec),
        frame_id=msg.header.frame_id,
        x0_m=np.array(msg.x0_m, dtype=float),
        v0_m_s=np.array(msg.v0_m_s, dtype=float),
        f0_n=np.array(msg.f0_n, dtype=float),
        stiffness_n_per_m=np.array(msg.stiffness_n_per_m, dtype=float).reshape(3, 3),
        damping_n_s_per_m=np.array(msg.damping_n_s_per_m, dtype=float).reshape(3, 3),
        normal=np.array(msg.normal, dtype=float),
        validity_radius_m=float(msg.validity_radius_m),
        time_to_live_s=float(msg.time_to_live_s),
        normal_force_n=float(msg.normal_force_n),
        normal_force_gradient_n_per_m=np.array(msg.normal_force_gradient_n_per_m, dtype=float),
        friction_coefficient=float(msg.friction_coefficient),
        slip_speed_m_s=float(msg.slip_speed_m_s),
        needle=read_needle_law(msg),
        tangential_stiffness_n_per_m=float(msg.tangential_stiffness_n_per_m),
        friction_anchor_m=np.array(msg.friction_anchor_m, dtype=float),
        slip_force_n=float(msg.slip_force_n),
        answer_period_s=float(msg.answer_period_s),
        coupling_rate_n_per_s=np.array(msg.coupling_rate_n_per_s, dtype=float),
    )


def fill_contact_model_from_tick(
    msg,
    result,
    t_ns: int,
    frame: str,
    ttl_s: float = DEFAULT_TTL_S,
    radius_m: float = DEFAULT_VALIDITY_RADIUS_M,
    answer_period_s: float = 0.0,
):
    """``tool/contact_model`` from a haptic tick's result (``skin_sim_node.session.TickResult``, read by attribute).

    ``f0`` is the published force (after the session's clamp, rate bound and watchdog); ``K``, ``D`` and the
    normal are the model's tangent (:class:`skin_sim_node.model.contact.ContactTangent`), scaled as the force was;
    the friction's ``F_n0 = n . f0`` and ``grad F_n = K^T n`` come from the same published tangent, with its anchor,
    stiffness (scaled) and slip level ``mu F_n0``, so the law gives ``f0`` at ``x0`` and its linearisation there is
    ``K``. A stale tick (no
    valid tool input for ``watchdog_s``; the tissue keeps its state, issue 31) sends a zero model valid anywhere
    (:data:`STALE_RADIUS_M`): the node says "no force"; the bridge blends into it, and out of it when poses resume, over
    its longest crossfade (20 ms, issue 31), so a stall is felt as a fade, never a step.
    """
    msg.header.stamp.sec, msg.header.stamp.nanosec = divmod(int(t_ns), 1_000_000_000)
    msg.header.frame_id = frame
    msg.sequence = int(result.seq)
    tg = result.tangent
    msg.x0_m[:] = result.x0_m
    msg.v0_m_s[:] = result.velocity_m_s
    msg.f0_n[:] = 0.0 if result.stale else result.force_n
    if result.stale:
        msg.stiffness_n_per_m[:] = 0.0
        msg.damping_n_s_per_m[:] = 0.0
        msg.normal_force_n = 0.0
        msg.normal_force_gradient_n_per_m[:] = 0.0
        msg.friction_coefficient = 0.0
        msg.slip_speed_m_s = 0.0
        msg.tangential_stiffness_n_per_m = 0.0
        msg.friction_anchor_m[:] = 0.0
        msg.slip_force_n = 0.0
    else:
        k = np.asarray(tg.stiffness_n_per_m)
        n = np.asarray(tg.normal, dtype=float)
        msg.stiffness_n_per_m[:] = k.ravel()
        msg.damping_n_s_per_m[:] = np.asarray(tg.damping_n_s_per_m).ravel()
        msg.normal_force_n = float(n @ np.asarray(result.force_n, dtype=float))
        msg.normal_force_gradient_n_per_m[:] = k.T @ n
        mu = float(getattr(tg, "friction_coefficient", 0.0))
        k_t = float(getattr(tg, "tangential_stiffness_n_per_m", 0.0))
        anchor = getattr(tg, "friction_anchor_m", None)
        law = mu > 0.0 and k_t > 0.0 and anchor is not None
        msg.friction_coefficient = mu if law else 0.0
        msg.slip_speed_m_s = 0.0  # the velocity law is gone from the node (issue 30)
        msg.tangential_stiffness_n_per_m = k_t if law else 0.0
        msg.friction_anchor_m[:] = anchor if law else 0.0
        msg.slip_force_n = mu * msg.normal_force_n if law else 0.0
    fill_needle_law(msg, None if result.stale else getattr(tg, "needle", None))
    msg.normal[:] = tg.normal
    msg.validity_radius_m = float(STALE_RADIUS_M if result.stale else radius_m)
    msg.time_to_live_s = float(ttl_s)
    msg.answer_period_s = float(answer_period_s)
    # a tick that answers no pose (a held republish, stamped now) carries no rate: its age would restart from zero
    rate = None if result.stale or not getattr(result, "answered", True) else getattr(tg, "coupling_rate_n_per_s", None)
    msg.coupling_rate_n_per_s[:] = 0.0 if rate is None else rate
    return msg


_CDR_CODES = {"uint64": "Q", "int64": "q", "double": "d"}


class ContactModelCdr:
    """Serialized ``ContactModel`` -> :class:`LocalModel` without an rclpy message object (the bridge's raw reader).

    The message is a ``std_msgs/Header`` followed by 8-byte fields only (``uint64`` and ``float64`` scalars and
    fixed arrays), so after the header's frame id, aligned to 8 bytes, the body is one ``struct`` record: its
    format is built once from the message's own field list (:meth:`from_message_class`), so a field added to
    ``ContactModel.msg`` is read without touching this code. Checked against rclpy's own serialization in
    ``tests/test_convert_cdr.py``.

    Parameters
    ----------
    fields_and_types : mapping of str to str
        The message's ``get_fields_and_field_types()``: ``header`` first, then 8-byte fields.

    Raises
    ------
    ValueError
        For a field that is not ``uint64``, ``int64``, ``float64`` or a fixed ``float64`` array.
    """

    def __init__(self, fields_and_types):
        items = list(fields_and_types.items())
        if not items or items[0] != ("header", "std_msgs/Header"):
            raise ValueError("ContactModel must start with its std_msgs/Header")
        self._layout: list[tuple[str, int, int]] = []  # name, first index, count (0: scalar)
        fmt, i = "", 0
        for name, typ in items[1:]:
            base, _, count = typ.partition("[")
            code = _CDR_CODES.get(base)
            if code is None or (count and base != "double"):
                raise ValueError(f"ContactModel field {name}: {typ} has no raw reader (8-byte fields only)")
            n = int(count.rstrip("]")) if count else 0
            fmt += f"{n}{code}" if n else code
            self._layout.append((name, i, n))
            i += max(n, 1)
        self._fmt = fmt
        self.size = struct.calcsize("<" + fmt)

    @classmethod
    def from_message_class(cls, msg_class) -> ContactModelCdr:
        """The reader of a generated message class (``skin_sim_msgs.msg.ContactModel``)."""
        return cls(msg_class.get_fields_and_field_types())

    def fields(self, data: bytes) -> dict:
        """The message's fields by name (arrays as tuples) plus ``stamp_ns`` and ``frame_id``.

        Raises
        ------
        ValueError
            One line, for a buffer that is not such a message.
        """
        if len(data) < 16 or data[0] != 0 or data[1] not in (0, 1):
            raise ValueError(f"not a CDR-encapsulated message ({len(data)} bytes)")
        e = "<" if data[1] == 1 else ">"
        sec, nsec, n = struct.unpack_from(e + "iII", data, 4)
        off = 4 + ((12 + n + 7) & ~7)
        if n == 0 or off + self.size > len(data):
            raise ValueError(f"truncated ContactModel ({len(data)} bytes, {off + self.size} expected)")
        vals = struct.unpack_from(e + self._fmt, data, off)
        out: dict = {"stamp_ns": sec * 1_000_000_000 + nsec, "frame_id": data[16 : 15 + n].decode("utf-8", "replace")}
        for name, i, cnt in self._layout:
            out[name] = vals[i : i + cnt] if cnt else vals[i]
        return out

    def read(self, data: bytes) -> LocalModel:
        """The :class:`LocalModel` of a serialized ``ContactModel`` (as :func:`read_contact_model` of the message)."""
        f = self.fields(data)
        axis = tuple(float(c) for c in f["needle_axis"])
        needle = NeedleLaw(axis, **{k: float(f[k]) for k in NeedleLaw.FIELDS}) if any(axis) else None  # type: ignore[arg-type]
        return LocalModel(
            sequence=int(f["sequence"]),
            stamp_ns=f["stamp_ns"],
            frame_id=f["frame_id"],
            x0_m=f["x0_m"],
            v0_m_s=f["v0_m_s"],
            f0_n=f["f0_n"],
            stiffness_n_per_m=f["stiffness_n_per_m"],
            damping_n_s_per_m=f["damping_n_s_per_m"],
            normal=f["normal"],
            validity_radius_m=float(f["validity_radius_m"]),
            time_to_live_s=float(f["time_to_live_s"]),
            normal_force_n=float(f["normal_force_n"]),
            normal_force_gradient_n_per_m=f["normal_force_gradient_n_per_m"],
            friction_coefficient=float(f["friction_coefficient"]),
            slip_speed_m_s=float(f["slip_speed_m_s"]),
            needle=needle,
            tangential_stiffness_n_per_m=float(f["tangential_stiffness_n_per_m"]),
            friction_anchor_m=f["friction_anchor_m"],
            slip_force_n=float(f["slip_force_n"]),
            answer_period_s=float(f.get("answer_period_s", 0.0)),
            coupling_rate_n_per_s=f.get("coupling_rate_n_per_s", (0.0, 0.0, 0.0)),
        )
