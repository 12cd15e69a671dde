"""Input and stamp policy: which tool samples are accepted, and what the next tick runs at.

Pose and twist checks (non-finite, frame), stamp checks (backwards, repeated, stale or future against the
receiver's clock, resync onto a restarted publisher's time line), teleport detection, the input watchdog,
the interval a tick advances, and the velocity estimate. No model and no rclpy: :meth:`InputPolicy.take`
says what the tick runs at, and :class:`~skin_sim_node.session.haptic.HapticSession` runs the model.
"""

from __future__ import annotations

import math
from typing import NamedTuple

from msgs_schema.parameters import SessionParams

from ..rate import ANSWER_ALL_HZ, AnswerThrottle  # noqa: F401  (re-exported: the session's throttle)
from . import events as ev

LIFTED = (0.0, 0.0, 1.0)
"""The tool position before any pose: 1 m above the rest surface, off the tissue."""

AT_REST = (0.0, 0.0, 0.0)

DOWN = (0.0, 0.0, -1.0)
"""The tool axis of an identity orientation: straight down into the tissue (``tool_pose`` in msgs_schema/topics.py)."""
QUATERNION_NORM_TOLERANCE = 1e-3
"""How far a pose's quaternion norm may be from 1 for a tool that uses its orientation (:attr:`ToolNeeds.orientation`): a driver's
double-precision rotation is within 1e-12, a float32 one within 1e-6; a norm off by more is an uninitialised or
corrupt orientation (the all-zero quaternion of a default-constructed message among them), rejected rather than
guessed (stated choice)."""


def quaternion_axis(qx: float, qy: float, qz: float, qw: float) -> tuple[float, float, float]:
    """The unit quaternion ``(x, y, z, w)`` applied to ``(0, 0, -1)``: minus the rotation matrix's third column."""
    return (-2.0 * (qx * qz + qw * qy), -2.0 * (qy * qz - qw * qx), -(1.0 - 2.0 * (qx * qx + qy * qy)))


class TickInput(NamedTuple):
    """What one tick runs the model at (:meth:`InputPolicy.take`).

    Attributes
    ----------
    answered : bool
        The tick consumes a newly accepted pose.
    stale : bool
        The input watchdog fired: no valid pose for ``watchdog_s``.
    pos : tuple of 3 float
        Tool position (tissue frame, m). When stale: the last pose, held (a stall keeps the tissue's state), or that
        pose lifted to ``z = 1 m`` once the stall is past ``stall_hold_s`` (the tool taken as gone).
    velocity : tuple of 3 float
        Tool velocity (m/s): the estimate for an answered pose, zero otherwise.
    dt_s : float
        Interval the model advances (s): at most ``max_dt_s`` but for an answered pose with :attr:`from_pos`, whose
        interval the session steps in parts.
    release : bool
        End contact before the step: the tool teleported, or a stall outlasted ``stall_hold_s`` (the tool is gone).
    hold : bool
        No new pose: the model is not stepped (``dt_s`` is 0) and, while the input is fresh, the force is held; in a
        stall (``stale`` too, shorter than ``stall_hold_s``) the published force is zero and the tissue keeps its
        state. Model time follows the pose stamps; a pose-less tick does not advance it.
    rate_dt_ns : int
        The interval the force-rate bound allows a change over (ns): the stamp interval of an answered pose,
        the caller's interval otherwise.
    restart : bool
        Contact restarts (the first pose after a start, a resync, a stall past ``stall_hold_s``, or a teleport): the
        tool has been where it is for an unknown time, so the model starts from the quasi-static state (dampers and viscoelastic
        arms relaxed).
    axis : tuple of 3 float
        The tool's unit axis toward its tip, from the pose's orientation (:func:`quaternion_axis`; for a tool that declares it).
    from_pos : tuple of 3 float or None
        Where the model's previous step ran (an answered pose that continues contact): an interval ``dt_s`` over
        ``max_dt_s`` is stepped in parts along the line from it to ``pos`` (a gap in the poses, or the rest of a
        stall); None: one step.
    """

    answered: bool
    stale: bool
    pos: tuple[float, float, float]
    velocity: tuple[float, float, float]
    dt_s: float
    release: bool
    hold: bool = False
    rate_dt_ns: int = 0
    restart: bool = False
    axis: tuple[float, float, float] = DOWN
    from_pos: tuple[float, float, float] | None = None


def velocity_estimate(
    params: SessionParams, pose_stamp_ns: int, pose, prev_stamp_ns: int | None, prev_pose, twist_stamp_ns: int | None, twist
) -> tuple[float, float, float]:
    """The tool velocity at a pose: the twist if its stamp is close enough, else the pose difference, capped.

    Parameters
    ----------
    params : SessionParams
        ``twist_max_skew_s`` (how close the twist's stamp must be) and ``max_tool_speed_m_s`` (the cap).
    pose_stamp_ns, pose : int, tuple of 3 float
        The pose the tick answers.
    prev_stamp_ns, prev_pose : int or None, tuple of 3 float
        The accepted pose before it (None: none).
    twist_stamp_ns, twist : int or None, tuple of 3 float
        The last accepted twist (None: none).

    Returns
    -------
    tuple of 3 float
        Velocity (m/s), of magnitude at most ``max_tool_speed_m_s``; zero without a twist or an earlier pose.
    """
    if twist_stamp_ns is not None and abs(twist_stamp_ns - pose_stamp_ns) * 1e-9 <= params.twist_max_skew_s:
        v = twist
    elif prev_stamp_ns is not None and pose_stamp_ns > prev_stamp_ns:
        dt = (pose_stamp_ns - prev_stamp_ns) * 1e-9
        v = tuple((a - b) / dt for a, b in zip(pose, prev_pose))
    else:
        v = AT_REST
    s = math.sqrt(v[0] * v[0] + v[1] * v[1] + v[2] * v[2])
    if s > params.max_tool_speed_m_s:
        v = tuple(c * params.max_tool_speed_m_s / s for c in v)
    return v


class InputPolicy:
    """Accepts or rejects tool samples and decides what each tick runs at.

    Parameters
    ----------
    params : SessionParams
        Read at every call (the session replaces it on a live parameter change).
    event : callable(kind, message) -> kind
        Where rejections and policy events go (:class:`~skin_sim_node.session.events.EventLog`).

    Attributes
    ----------
    pose_stamp_ns, pose : int or None, tuple of 3 float
        The last accepted pose (stamp ns, tissue frame m).
    pose_rx_ns : int or None
        Arrival time of that pose on the caller's clock (the watchdog's).
    twist_stamp_ns, twist : int or None, tuple of 3 float
        The last accepted twist.
    stale : bool
        The watchdog state of the last :meth:`take`.
    answered_stamp_ns : int
        Stamp of the last pose a tick answered (0 before any).
    """

    def __init__(self, params: SessionParams, event: ev.EventSink):
        self.params = params
        self._event = event
        self.pose_stamp_ns: int | None = None  # last accepted pose
        self.pose = LIFTED
        self.axis = DOWN  # the last accepted pose's tool axis
        self.orientation_required = False  # the tool uses the orientation (ToolNeeds.orientation): a bad one is rejected
        self.pose_rx_ns: int | None = None  # caller clock when it arrived
        self._prev_pose_stamp_ns: int | None = None
        self._prev_pose = LIFTED
        self.twist_stamp_ns: int | None = None
        self.twist = AT_REST
        self._teleported = False
        self._backwards_run = 0
        self._last_used_stamp_ns: int | None = None  # stamp of the pose the last tick used (model time)
        self._model_pos = LIFTED  # where the model's last step ran the tool
        self._held = False  # a stall held the tissue since the last answered pose
        self._released = False  # a stall outlasted stall_hold_s on the caller's clock since the last answered pose
        self._pending = False  # a pose arrived that no tick has consumed
        self.stale = True
        self.answered_stamp_ns = 0

    def on_pose(
        self, stamp_ns: int, frame: str, xyz, now_ns: int | None = None, rx_ns: int | None = None, quat=None
    ) -> str | None:
        """Validate and store a tool pose.

        Parameters
        ----------
        stamp_ns : int
            The pose's stamp.
        frame : str
            Its frame id; must be ``tissue_frame``.
        xyz : sequence of 3 float
            Tool position (m).
        now_ns : int, optional
            The receiver's clock in the stamps' time base (ROS time), for the stamp age check (None skips it,
            as offline replay does).
        rx_ns : int, optional
            Arrival time on the clock that :meth:`take` gets (default ``now_ns``, else the stamp).
        quat : sequence of 4 float, optional
            The pose's orientation ``(x, y, z, w)`` (default identity). Non-finite: rejected; with
            :attr:`orientation_required` a norm off 1 by more than :data:`QUATERNION_NORM_TOLERANCE` is
            rejected too, and the tool axis is :func:`quaternion_axis` of the normalised quaternion.

        Returns
        -------
        str or None
            None if accepted, else the rejection kind.
        """
        p = self.params
        x, y, z = (float(c) for c in xyz)
        if not (math.isfinite(x) and math.isfinite(y) and math.isfinite(z)):
            return self._event(ev.NON_FINITE, f"rejected tool pose with non-finite position ({x}, {y}, {z})")
        if x * x + y * y + z * z > p.workspace_radius_m * p.workspace_radius_m:
            return self._event(
                ev.OUTSIDE_WORKSPACE,
                f"rejected tool pose at ({x:.3g}, {y:.3g}, {z:.3g}) m: farther than workspace_radius_m = "
                f"{p.workspace_radius_m:g} m from the tissue origin (a device or mapping fault, not a hand)",
            )
        if frame != p.tissue_frame:
            return self._event(ev.UNKNOWN_FRAME, f"rejected tool pose in frame '{frame}', expected '{p.tissue_frame}'")
        axis = DOWN
        if quat is not None:
            qx, qy, qz, qw = (float(c) for c in quat)
            norm = math.hypot(qx, qy, qz, qw)  # no overflow for large finite components (those are then not unit)
            if not all(math.isfinite(c) for c in (qx, qy, qz, qw)):
                return self._event(ev.NON_FINITE, f"rejected tool pose with non-finite orientation ({qx}, {qy}, {qz}, {qw})")
            if self.orientation_required:
                if abs(norm - 1.0) > QUATERNION_NORM_TOLERANCE:
                    return self._event(
                        ev.BAD_ORIENTATION,
                        f"rejected tool pose: orientation quaternion ({qx:.3g}, {qy:.3g}, {qz:.3g}, {qw:.3g}) has norm "
                        f"{norm:.4g}, not 1 (the tool's axis comes from it)",
                    )
                axis = quaternion_axis(qx / norm, qy / norm, qz / norm, qw / norm)
        if now_ns is not None and p.max_stamp_age_s > 0:
            age = (now_ns - stamp_ns) * 1e-9
            if age > p.max_stamp_age_s:
                return self._event(
                    ev.STALE_STAMP,
                    f"rejected tool pose: stamp is {age:.3f} s old (limit {p.max_stamp_age_s} s); "
                    "check clock sync or use_sim_time",
                )
            if -age > p.max_future_s:
                return self._event(
                    ev.FUTURE_STAMP, f"rejected tool pose: stamp is {-age:.3f} s in the future; check clock sync or use_sim_time"
                )
        if self.pose_stamp_ns is not None and stamp_ns <= self.pose_stamp_ns:
            self._backwards_run += 1
            if self._backwards_run < p.resync_after:
                if stamp_ns == self.pose_stamp_ns:
                    return self._event(ev.STAMP_DUPLICATE, "rejected tool pose with a repeated stamp")
                return self._event(
                    ev.STAMP_BACKWARDS, f"rejected tool pose: stamp went back {(self.pose_stamp_ns - stamp_ns) * 1e-6:.3f} ms"
                )
            self._event(ev.STAMP_RESYNC, f"{self._backwards_run} poses behind the last stamp: following the new time line")
            self.pose_stamp_ns = self._last_used_stamp_ns = None
            self._teleported = True
        self._backwards_run = 0
        if self.pose_stamp_ns is not None and not self._teleported:
            dist = math.dist((x, y, z), self.pose)
            dt = (stamp_ns - self.pose_stamp_ns) * 1e-9
            if dist > p.teleport_distance_m or dist > p.max_tool_speed_m_s * max(dt, 1e-3):
                self._teleported = True
                self._event(ev.TELEPORT, f"tool jumped {dist * 1e3:.1f} mm in {dt * 1e3:.2f} ms: contact restarted")
        self._prev_pose_stamp_ns, self._prev_pose = self.pose_stamp_ns, self.pose
        self.pose_stamp_ns, self.pose, self.axis = stamp_ns, (x, y, z), axis
        self.pose_rx_ns = rx_ns if rx_ns is not None else (now_ns if now_ns is not None else stamp_ns)
        self._pending = True
        return None

    def on_twist(self, stamp_ns: int, frame: str, linear) -> str | None:
        """Validate and store a tool twist (its linear part): as :meth:`on_pose`, with ``linear`` the velocity (m/s).

        Returns
        -------
        str or None
            None if accepted, else the rejection kind.
        """
        vx, vy, vz = (float(c) for c in linear)
        if not (math.isfinite(vx) and math.isfinite(vy) and math.isfinite(vz)):
            return self._event(ev.NON_FINITE, f"rejected tool twist with non-finite velocity ({vx}, {vy}, {vz})")
        if frame != self.params.tissue_frame:
            return self._event(ev.UNKNOWN_FRAME, f"rejected tool twist in frame '{frame}', expected '{self.params.tissue_frame}'")
        self.twist_stamp_ns, self.twist = stamp_ns, (vx, vy, vz)
        return None

    def take(self, now_ns: int, elapsed_ns: int) -> TickInput:
        """What the next tick runs at; consumes the pending pose.

        The stamps define the model's time. A new pose advances the model by its stamp's difference to the pose
        the previous step used (several poses per tick lose no time; an interval over ``max_dt_s`` is stepped in
        parts, :attr:`TickInput.from_pos`). A tick without a new pose holds the model and the force while the input
        is fresh, so it neither eats the next pose's time (a step of dt = 0, where the Kelvin-Voigt chain is a rigid
        damper) nor changes the answer to any pose: the live node answers a pose stream as the offline replay of it
        does, however the poses arrived.

        A stall is not a restart (issue 31). Once the watchdog fires the published force is zero, and the tissue
        keeps its state, unstepped, with the tool held at its last pose: what the tool holds (a track cut through the
        layers), the viscoelastic arms, the friction anchor and the patch persist. When poses resume the model
        continues over the whole stamp gap, in parts along the line from the held pose to the new one (relaxing as
        under a hand that held still, then moved), exactly as the offline replay of the same poses steps it. A
        stall longer than ``stall_hold_s`` (on the caller's clock live, on the stamps offline) is the tool gone: the
        tissue is released, relaxing lifted off, and the next pose restarts contact. So are a teleport and a resync
        (a new time line): the restarts are explicit events.

        Parameters
        ----------
        now_ns : int
            The caller's clock (the one ``rx_ns`` is on).
        elapsed_ns : int
            Caller-clock time since the previous tick.

        Returns
        -------
        TickInput
        """
        p = self.params
        waited = None if self.pose_rx_ns is None else (now_ns - self.pose_rx_ns) * 1e-9
        stale = waited is None or waited > p.watchdog_s
        if stale and not self.stale:
            self._event(
                ev.WATCHDOG,
                f"no valid tool pose for {p.watchdog_s * 1e3:.0f} ms: force set to zero; the tissue keeps its state "
                f"for stall_hold_s = {p.stall_hold_s:g} s",
            )
        self.stale = stale
        answered = self._pending and not stale
        if not answered and not stale:
            return TickInput(False, False, self.pose, AT_REST, 0.0, False, hold=True, rate_dt_ns=0)
        if not answered:
            return self._stalled(waited, elapsed_ns)
        self._pending = False
        stamp = self.pose_stamp_ns
        assert stamp is not None  # a pending pose has a stamp
        last = self._last_used_stamp_ns
        gap_ns = 0 if last is None else stamp - last
        held, self._held = self._held, False
        gone = last is not None and not self._teleported and gap_ns * 1e-9 > self._hold_s()
        if gone:
            self._event(
                ev.STALL_RELEASED,
                f"no tool pose for {gap_ns * 1e-9:.3g} s of stamps (stall_hold_s = {p.stall_hold_s:g} s): the tool was "
                "taken as gone, contact restarted",
            )
        # contact restarts (the first pose after a start, a resync, a stall past stall_hold_s, and a teleport) step
        # by max_dt_s: the tool has been where it is for an unknown time, so contact starts from the quasi-static
        # state (dampers relaxed) and not through a rigid damper (a 1 mm restart in 1 ms raised 200 N before the
        # force clamp)
        restart = last is None or self._teleported or gone
        release = self._teleported or gone
        self._teleported = False
        self._last_used_stamp_ns = stamp
        self.answered_stamp_ns = stamp
        from_pos: tuple[float, float, float] | None = self._model_pos
        self._model_pos = self.pose
        gone_and_back, self._released = self._released, False
        v = AT_REST if release or gone_and_back else self._velocity(stamp)  # a jump (teleport, tool gone and back): none
        if restart:
            dt_ns = int(p.max_dt_s * 1e9)
            rate_dt_ns = elapsed_ns if last is None else gap_ns
            from_pos = None
        else:
            rate_dt_ns = dt_ns = gap_ns
            if held:  # the force was zero through the stall: it comes back at the rate bound, from this tick's interval
                rate_dt_ns = max(elapsed_ns, 0)
                self._event(
                    ev.STALL_RESUMED,
                    f"tool poses resumed after {gap_ns * 1e-6:.0f} ms: the tissue continued from its held state (a "
                    "stall is not a restart)",
                )
            if dt_ns * 1e-9 > p.max_dt_s:
                self._event(
                    ev.TICK_CLAMPED,
                    f"tick interval {dt_ns * 1e-6:.1f} ms stepped in parts of at most max_dt_s = {p.max_dt_s * 1e3:.0f} ms",
                )
        return TickInput(
            True, False, self.pose, v, max(dt_ns, 0) * 1e-9, release, hold=False, rate_dt_ns=max(rate_dt_ns, 0),
            restart=restart, axis=self.axis, from_pos=from_pos,
        )  # fmt: skip

    def _hold_s(self) -> float:
        """How long a stall keeps the tissue's state (s): ``stall_hold_s``, at least the watchdog's delay (so 0
        releases at the watchdog); the live caller's clock and the offline stamps use the one bound."""
        return max(self.params.stall_hold_s, self.params.watchdog_s)

    def _velocity(self, stamp: int) -> tuple[float, float, float]:
        """:func:`velocity_estimate` at the pending pose (stamped ``stamp``)."""
        return velocity_estimate(
            self.params, stamp, self.pose, self._prev_pose_stamp_ns, self._prev_pose, self.twist_stamp_ns, self.twist
        )

    def _stalled(self, waited: float | None, elapsed_ns: int) -> TickInput:
        """A tick of a stale input (:meth:`take`): the tool held at its last pose while the stall is shorter than
        ``stall_hold_s``; after that (or before any pose) lifted off, the tissue released and relaxing."""
        p = self.params
        dt = min(max(elapsed_ns, 0) * 1e-9, p.max_dt_s)  # the caller's own stall does not jump the tissue ahead
        if waited is not None and waited <= self._hold_s() and self._last_used_stamp_ns is not None:
            # held: the model is not stepped (the resumed pose steps it over the whole gap, as the offline replay does,
            # and a stalled machine spends nothing on a tissue nobody touches); the published force is zero
            self._held = True
            held = self._model_pos  # where the model last ran the tool
            return TickInput(False, True, held, AT_REST, 0.0, False, hold=True, rate_dt_ns=max(elapsed_ns, 0), axis=self.axis)
        release = self._last_used_stamp_ns is not None
        self._released = self._released or release  # the next pose: a tool gone and back (no velocity)
        if release and waited is not None:
            self._event(
                ev.STALL_RELEASED,
                f"no tool pose for {waited:.3g} s (stall_hold_s = {p.stall_hold_s:g} s): the tool was taken as gone, the "
                "tissue released",
            )
        self._last_used_stamp_ns = None
        self._held = False
        self._model_pos = LIFTED
        lifted = (self.pose[0], self.pose[1], 1.0)
        return TickInput(False, True, lifted, AT_REST, dt, release, rate_dt_ns=max(elapsed_ns, 0), axis=self.axis)
