"""The server rate (issue 27): which poses are answered, and the rate the node settles at on this machine.

Pure (no rclpy, no model), shared by the node (:mod:`skin_sim_node.server.node`), the session's offline replay and
the bridge (:mod:`skin_sim_node.device.bridge`), which forwards a tool pose only when the node will answer it:

- :class:`AnswerThrottle` spaces the answers to at most ``rate_hz`` per second of pose stamps;
- :class:`RateGovernor` picks that rate from :data:`RATE_LADDER_HZ`: the node's ``rate_hz`` while the machine holds
  it, a lower rung while it does not, back up once the lower one has held for a while. The bridge renders the local
  contact model every device tick in between, so a slower server costs render accuracy (measured in
  ``docs/devices.md``), never a device tick: "model no more than a scene needs", applied to time.

The governor's decision is a function of counts the node takes from its own pose stamps (:class:`RateWindow`), so it
is unit-tested on recorded timings (``tests/test_rate.py``).
"""

from __future__ import annotations

from dataclasses import dataclass

ANSWER_ALL_HZ = 1000.0
"""At ``rate_hz`` of at least this (a Touch's 1 kHz servo rate, the default), input mode answers every pose: the
one-wrench-per-pose contract of live replay. Below it, :class:`AnswerThrottle` spaces the answers."""

RATE_LADDER_HZ = (1000.0, 500.0, 250.0, 125.0, 62.5)
"""The rates the governor steps through, each half the one above: a rung answers every 1st, 2nd, 4th, 8th or 16th
pose of a 1 kHz device, so the bridge's forwarding stays in phase with the device's ticks."""

HELD_ANSWERED_MIN = 0.97
"""A window holds its rate when at least this share of its due answers was made (the rest are missed slots: pose
stamps that arrived more than 1.5 periods apart, or answers the node could not make): the demo's verdict allows 5 %
(``skin_sim_node.demo.RATE_TOLERANCE``), and a margin of 2 % below it keeps the node on a rate that the verdict then
finds held (measured: at 1 kHz with 94-96 % per window the node stayed, and the demo's median fell to 94 %)."""

HELD_LATE_MAX = 0.05
"""...and at most this share of its answers came late (pose age at the answer above :data:`LATE_AGE_MIN_S` and two
periods): a queue that grows is a rate the machine does not hold even when every pose is still answered."""

LATE_AGE_MIN_S = 0.005
"""Least pose age (stamp to answer) that counts as late: 5 ms, the benchmark's gap aim; two periods above it."""

DOWN_AFTER_WINDOWS = 2
"""Consecutive windows that miss before the rate steps down (2 x 0.5 s: one window's hiccup, e.g. a reader joining,
is not a trend)."""

UP_AFTER_WINDOWS = 10
"""Consecutive held windows before the governor tries the rung above (5 s at 0.5 s windows); doubled after each try
that failed, up to :data:`UP_AFTER_MAX_WINDOWS`, so a machine that cannot hold a rate is not asked every 5 s."""

UP_AFTER_MAX_WINDOWS = 120
"""Longest wait before trying the rung above again (60 s)."""

MIN_WINDOW_ANSWERS = 20
"""A window with fewer due answers than this says nothing about the rate (no device, or a slow publisher)."""


class AnswerThrottle:
    """Input mode's server-rate lever: at most ``rate_hz`` answered poses per second of pose stamps.

    A pose is answered when its stamp reaches the next due time (less an eighth of a period for stamp jitter); the
    due time then advances one period, or restarts half a period after a pose that came long after it. A pose
    not answered is kept (the next answered one steps the model over both stamps), and the bridge renders the
    contact model in between: ``rate_hz:=250`` with a 1 kHz device answers every fourth pose.

    Parameters
    ----------
    rate_hz : float
        The node's ``rate_hz``; :data:`ANSWER_ALL_HZ` or more answers every pose.
    """

    def __init__(self, rate_hz: float):
        self._next_ns: int | None = None
        self.period_ns = 0
        self.set_rate(rate_hz)

    def set_rate(self, rate_hz: float) -> None:
        """Apply a new ``rate_hz`` (a live parameter change); the next pose is answered."""
        self.period_ns = 0 if rate_hz >= ANSWER_ALL_HZ else int(round(1e9 / rate_hz))
        self._next_ns = None

    def set_period_s(self, period_s: float) -> None:
        """Apply an answer period (s) as announced in a contact model (0: every pose); the next pose is due."""
        self.period_ns = int(round(period_s * 1e9)) if period_s > 0 else 0
        self._next_ns = None

    def due(self, stamp_ns: int) -> bool:
        """Whether the pose stamped ``stamp_ns`` is answered now."""
        period = self.period_ns
        if period == 0:
            return True
        nxt = self._next_ns
        if nxt is not None and nxt - period // 8 <= stamp_ns <= nxt + 2 * period:
            self._next_ns = max(nxt + period, stamp_ns - period // 2)
            return True
        if nxt is not None and stamp_ns < nxt - period // 8 and stamp_ns > nxt - 2 * period:
            return False
        self._next_ns = stamp_ns + period  # the first pose, a long gap or a new time line: answer and restart
        return True


@dataclass(frozen=True)
class RateWindow:
    """What the node counted over one governor window (from its pose stamps and its own clock).

    Attributes
    ----------
    rate_hz : float
        The rate the window ran at.
    answered : int
        Poses answered.
    missed : int
        Answer slots at that rate that no answered pose filled: for consecutive answered stamps ``dt`` apart,
        ``max(round(dt / period) - 1, 0)`` (a pose the reader's queue overwrote, or one forwarded late). Gaps longer
        than the watchdog are the hand stopping, not the machine, and are not counted.
    late : int
        Answers whose pose was older than ``max(LATE_AGE_MIN_S, 2 / rate_hz)`` when answered.
    """

    rate_hz: float
    answered: int
    missed: int
    late: int = 0

    @property
    def held(self) -> bool | None:
        """True if the window held its rate, False if not, None if it had too few answers to tell."""
        due = self.answered + self.missed
        if due < MIN_WINDOW_ANSWERS:
            return None
        return self.answered >= HELD_ANSWERED_MIN * due and self.late <= HELD_LATE_MAX * max(self.answered, 1)


def missed_slots(stamps_ns, rate_hz: float, gap_limit_s: float) -> int:
    """Missed answer slots in a run of answered pose stamps (:attr:`RateWindow.missed`).

    Parameters
    ----------
    stamps_ns : sequence of int
        Consecutive answered pose stamps (ns).
    rate_hz : float
        The rate they were answered at.
    gap_limit_s : float
        Gaps at least this long are a pause of the input, not missed slots (the node's ``watchdog_s``).

    Returns
    -------
    int
    """
    period = 1e9 / rate_hz
    n = 0
    for a, b in zip(stamps_ns, stamps_ns[1:]):
        dt = b - a
        if 0 < dt < gap_limit_s * 1e9:
            n += max(int(round(dt / period)) - 1, 0)
    return n


class RateGovernor:
    """Steps the node's answer rate down :data:`RATE_LADDER_HZ` while the machine does not hold it, and back up.

    Parameters
    ----------
    max_rate_hz : float
        The node's ``rate_hz``: the rate it starts at and never exceeds.
    min_rate_hz : float
        The lowest rate it steps down to.

    Attributes
    ----------
    rate_hz : float
        The rate now.
    reason : str
        Why the rate is what it is (the last change, or "target").
    changes : int
        How many times the rate changed.
    """

    def __init__(self, max_rate_hz: float, min_rate_hz: float):
        self.max_rate_hz = float(max_rate_hz)
        rungs = [r for r in RATE_LADDER_HZ if min_rate_hz <= r < self.max_rate_hz]
        self.rungs = (self.max_rate_hz, *rungs)
        self.level = 0
        self.reason = "target"
        self.changes = 0
        self._bad = 0
        self._good = 0
        self._up_after = UP_AFTER_WINDOWS
        self._probing = False
        self._made_hz = 0.0  # answers made a second: the better of the bad windows since the last good one

    @property
    def rate_hz(self) -> float:
        """The rate the node answers at now."""
        return self.rungs[self.level]

    def update(self, w: RateWindow) -> str | None:
        """Take one window's counts; returns a one-line message when the rate changes, else None.

        Parameters
        ----------
        w : RateWindow

        Returns
        -------
        str or None
        """
        held = w.held
        if held is None or w.rate_hz != self.rate_hz:
            return None
        if held:
            self._bad = 0
            if self._probing:  # the rung tried from below has held: it is the rate now
                self._probing = False
                self._up_after = UP_AFTER_WINDOWS
            self._good += 1
            if self.level > 0 and self._good >= self._up_after:
                return self._step(-1, f"{self.rungs[self.level]:g} Hz held for {self._good} windows: trying the rung above")
            return None
        self._good = 0
        self._bad += 1
        due = w.answered + w.missed
        made_hz = self.rate_hz * w.answered / due  # the answers the machine made, a second
        self._made_hz = max(self._made_hz, made_hz) if self._bad > 1 else made_hz  # the better of the bad windows
        if self._probing or (self._bad >= DOWN_AFTER_WINDOWS and self.level < len(self.rungs) - 1):
            probed = self._probing
            if probed:
                self._up_after = min(2 * self._up_after, UP_AFTER_MAX_WINDOWS)
                self._probing = False
            if self.level == len(self.rungs) - 1:
                return None
            why = (
                f"{self.rate_hz:g} Hz not held: {w.answered} of {due} due answers made, {w.late} late, "
                f"{self._made_hz:.0f} answers a second at best (the machine's CPU; see diagnostics cpu_pct)"
            )
            # a rung tried from below falls back to the rung that held, judged on one window; else what was made
            return self._step(1 if probed else self._down_to(self._made_hz) - self.level, why)
        return None

    def _down_to(self, made_hz: float) -> int:
        """The level a rung that missed steps down to: the highest rung that ``made_hz`` (the answers made a second,
        the better of its bad windows) would hold (:data:`HELD_ANSWERED_MIN` of the rung), and at least one rung down
        (windows that made every answer but late ones). An overloaded rung spends almost nothing on the answers it
        skips, so what it made is about what the machine makes; a rung tried from below that fails falls back one
        rung instead (:meth:`update`), and the governor tries the rung above later, as before.

        One rung at a time, a two-hand node that started at 1 kHz on two cores took three rungs and 3 s of overload
        (its windows made 153 of 499, then 128 of 252, then 100 of 126 due answers) to reach the rate it held, and
        its devices' commands stopped for over 5 ms in that time (docs/two_hands.md, "Session 15"): what the machine
        made is the rung it holds, so the governor goes there at once."""
        level = self.level + 1
        while level < len(self.rungs) - 1 and HELD_ANSWERED_MIN * self.rungs[level] > made_hz:
            level += 1
        return level

    def _step(self, direction: int, why: str) -> str:
        old = self.rate_hz
        self.level += direction
        self._bad = self._good = 0
        self._probing = direction < 0
        self.changes += 1
        self.reason = why
        return f"server rate {old:g} -> {self.rate_hz:g} Hz: {why}"


def device_tick_messages(
    node_rate_hz: float,
    device_rate_hz: float = 1000.0,
    device_twist: bool = True,
    measured_force: bool = True,
    forward_twist: bool = False,
    forward_every_pose: bool = False,
    contact_readers: bool = False,
    in_process: bool = False,
) -> dict[str, float]:
    """rclpy messages per device tick, per process: the device path's message budget (issue 27).

    Each message in or out of an rclpy process costs about 0.1-0.3 ms of CPU here (serialized: the lower end), far
    more than the model's 6-9 us step, so this count sets the CPU floor.

    Parameters
    ----------
    node_rate_hz : float
        The rate the node answers at (its server rate).
    device_rate_hz : float
        The device's servo rate (a Touch: 1 kHz).
    device_twist, measured_force : bool
        The driver publishes ``measured_cv`` / ``measured_cf`` and the bridge reads them (CRTK).
    forward_twist : bool
        The bridge forwards the device's velocity as ``tool/twist`` too.
    forward_every_pose : bool
        The bridge forwards every device pose (before issue 27), not only those the node answers.
    contact_readers : bool
        Someone reads ``tissue/contact`` (published only then).
    in_process : bool
        Node and bridge in one process (``skin-sim bridge --with-node``): pose and contact model handed over in
        memory; the node publishes only ``tool/wrench`` (counted under ``node``).

    Returns
    -------
    dict
        ``bridge``, ``node`` and ``total`` messages per device tick.
    """
    answered = min(node_rate_hz, device_rate_hz) / device_rate_hz
    device_side = 2.0 + device_twist + measured_force  # the pose and the force command, velocity and applied force
    if in_process:
        return {
            "bridge": device_side,
            "node": answered * (1 + contact_readers),
            "total": device_side + answered * (1 + contact_readers),
        }
    forwarded = 1.0 if forward_every_pose else answered
    bridge = device_side + forwarded * (1 + forward_twist) + answered
    node = forwarded * (1 + forward_twist) + answered * (2 + contact_readers)
    return {"bridge": bridge, "node": node, "total": bridge + node}


STEP_DOWN_GRACE_NS = 50_000_000
"""After a step down the node announces the new period at once but applies its throttle this much later (50 ms, the
contact model's time to live): by then a bridge forwards at the new period, so the node never skips a pose the bridge
forwarded, and the offline replay of what it received is the node's own answer (a skipped pose shifts the presliding
anchor's sampled path: 0.116 N in one demo run before this)."""

GOVERNOR_WINDOW_NS = 500_000_000
"""The rate governor's window (0.5 s: 500 answers at 1 kHz, enough to count a 5 % miss; two bad windows step down
within a second, before a hand notices a changed feel)."""


class ServerRate:
    """The node's server rate in one object: the answer throttle, the governor of ``rate_policy: follow`` and its
    window's counts, and the period the contact models announce. Pure: the node feeds it stamps and clocks.

    Parameters
    ----------
    p : NodeParams
        ``rate_hz``, ``rate_policy``, ``min_rate_hz``, ``loop_mode``, ``input_queue_depth``, ``watchdog_s``.
    now_ns : int
        The caller's monotonic clock (the governor's windows).
    pose_ages : bool
        Pose stamps are on the system clock (not ``use_sim_time``): their age at the answer counts as lateness.
    """

    def __init__(self, p, now_ns: int, pose_ages: bool = True):
        self.params = p
        self.pose_ages = pose_ages
        self.throttle = AnswerThrottle(p.rate_hz)  # input mode: a rate below 1 kHz spaces the answers
        # A node with input_queue_depth above 1 was asked to answer every sample in order (live replay, tests that
        # count answers): it keeps rate_hz, as skipping poses would break that contract.
        follow = p.rate_policy == "follow" and p.loop_mode == "input" and p.input_queue_depth <= 1
        self.governor = RateGovernor(p.rate_hz, min(p.min_rate_hz, p.rate_hz)) if follow else None
        self._pending: tuple[float, int] | None = None  # (rate, when): a step down's throttle, applied after the grace
        self._reset(now_ns)

    def _reset(self, now_ns: int) -> None:
        self._start_ns = now_ns
        self._answered = self._missed = self._late = 0
        self._last_stamp: int | None = None

    def due(self, stamp_ns: int, now_ns: int | None = None) -> bool:
        """Whether the pose stamped ``stamp_ns`` is answered (input mode: :class:`AnswerThrottle`); ``now_ns`` (the
        caller's monotonic clock) applies a pending step down's throttle once its grace has passed."""
        if self._pending is not None and now_ns is not None and now_ns >= self._pending[1]:
            self.throttle.set_rate(self._pending[0])
            self._pending = None
        return self.throttle.due(stamp_ns)

    @property
    def rate_hz(self) -> float:
        """The rate the node answers at now."""
        return self.governor.rate_hz if self.governor is not None else float(self.params.rate_hz)

    @property
    def answer_period_s(self) -> float:
        """The period the contact models announce: the bridge forwards a pose this often (0: every pose)."""
        p = self.params
        rate = p.rate_hz if p.loop_mode == "timer" else self.rate_hz
        return 0.0 if rate >= ANSWER_ALL_HZ else 1.0 / rate

    def answered(self, stamp_ns: int, now_ns: int, wall_ns: int) -> str | None:
        """Count one answered pose into the governor's window (``now_ns`` monotonic, ``wall_ns`` the system clock);
        at the window's end the governor decides. Returns its one-line message when the rate changes."""
        gov = self.governor
        if gov is None:
            return None
        period_ns = 1e9 / gov.rate_hz
        last = self._last_stamp
        if last is not None and 0 < stamp_ns - last < self.params.watchdog_s * 1e9:
            self._missed += max(int(round((stamp_ns - last) / period_ns)) - 1, 0)
        self._last_stamp = stamp_ns
        self._answered += 1
        if self.pose_ages:  # the pose's age on the system clock (its stamp's, from a device or the bridge)
            self._late += wall_ns - stamp_ns > max(LATE_AGE_MIN_S * 1e9, 2 * period_ns)
        if now_ns - self._start_ns < GOVERNOR_WINDOW_NS:
            return None
        old = gov.rate_hz
        msg = gov.update(RateWindow(gov.rate_hz, self._answered, self._missed, self._late))
        self._reset(now_ns)
        if msg is not None:
            if gov.rate_hz < old:  # announced now, applied after the grace (STEP_DOWN_GRACE_NS)
                self._pending = (gov.rate_hz, now_ns + STEP_DOWN_GRACE_NS)
            else:  # up: answer more at once (nothing a bridge forwards is skipped)
                self._pending = None
                self.throttle.set_rate(gov.rate_hz)
        return msg

    def diagnostics(self) -> dict[str, str]:
        """The diagnostics key-values of the server rate."""
        gov = self.governor
        return {
            "server_rate_hz": f"{self.rate_hz:.1f}",
            "rate_policy": self.params.rate_policy if gov is not None else "fixed",
            "rate_reason": gov.reason if gov is not None else "rate_hz",
            "rate_changes_total": str(gov.changes if gov is not None else 0),
            "answer_period_ms": f"{self.answer_period_s * 1e3:.2f}",
        }
