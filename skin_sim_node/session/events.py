"""The session's event kinds (diagnostics keys) and the log that counts them and logs each kind once."""

from __future__ import annotations

from collections import Counter
from collections.abc import Callable

# Rejection / event kinds (diagnostics keys).
NON_FINITE = "non_finite_input"
OUTSIDE_WORKSPACE = "outside_workspace"
BAD_ORIENTATION = "bad_orientation"
UNKNOWN_FRAME = "unknown_frame"
STAMP_BACKWARDS = "stamp_backwards"
STAMP_DUPLICATE = "stamp_duplicate"
STALE_STAMP = "stale_stamp"
FUTURE_STAMP = "future_stamp"
STAMP_RESYNC = "stamp_resync"
TELEPORT = "teleport"
WATCHDOG = "watchdog_stale_input"
STALL_RESUMED = "stall_resumed"
STALL_RELEASED = "stall_released"
FORCE_CLAMPED = "force_clamped"
FORCE_NON_FINITE = "force_non_finite"
FORCE_RATE_LIMITED = "force_rate_limited"
TICK_CLAMPED = "tick_interval_clamped"
# Model-regime events (docs/stability.md): where the paper's model stops making sense.
TOOL_BELOW_TISSUE = "tool_below_tissue"
REUSS_BOUND = "reuss_compression_bound"
CONTACT_SEPARATED = "contact_separated"
TOOL_OFF_SHEET = "tool_off_sheet"
PATCH_CLIPPED = "patch_clipped"
DEGENERATE_WAVE_SPEED = "degenerate_wave_speed"

REGIME_EVENTS = frozenset(
    (TOOL_BELOW_TISSUE, REUSS_BOUND, CONTACT_SEPARATED, TOOL_OFF_SHEET, PATCH_CLIPPED, DEGENERATE_WAVE_SPEED)
)
"""Counted in :attr:`EventLog.regime_counts`, not :attr:`EventLog.counts` (rejections and safety actions): they
occur in ordinary use (every fast release separates) and the model bounds them itself."""

EventSink = Callable[[str, str], str]
"""``event(kind, message) -> kind``: how the input policy and the force limits report an event."""


class EventLog:
    """Counts every event, logs each kind once, and keeps the kinds raised since the last tick.

    Parameters
    ----------
    log : callable(kind, message), optional
        Called once per event kind (its first occurrence).

    Attributes
    ----------
    counts : Counter
        Occurrences of each rejection and safety event.
    regime_counts : Counter
        Occurrences of each model-regime event (:data:`REGIME_EVENTS`).
    """

    def __init__(self, log: Callable[[str, str], None] | None = None):
        self._log = log
        self.counts: Counter[str] = Counter()
        self.regime_counts: Counter[str] = Counter()
        self._logged: set[str] = set()
        self._pending: list[str] = []

    def __call__(self, kind: str, message: str) -> str:
        """Count one occurrence of ``kind`` (logging ``message`` if it is the first) and return ``kind``.

        Parameters
        ----------
        kind : str
            The event kind (a module constant).
        message : str
            What happened, for the log.

        Returns
        -------
        str
            ``kind``, so that a rejection can ``return event(kind, message)``.
        """
        (self.regime_counts if kind in REGIME_EVENTS else self.counts)[kind] += 1
        self._pending.append(kind)
        if kind not in self._logged:
            self._logged.add(kind)
            if self._log:
                self._log(kind, message)
        return kind

    def take(self) -> tuple[str, ...]:
        """The kinds raised since the previous call, in order (each occurrence), and forget them.

        Returns
        -------
        tuple of str
        """
        if not self._pending:
            return ()
        events = tuple(self._pending)
        self._pending.clear()
        return events
