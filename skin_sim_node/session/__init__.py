"""Haptic session: validated tool input -> model tick -> safe force. No rclpy.

The live node and the offline replay both drive the model through :class:`HapticSession`, so
they apply the same input checks, velocity estimate and force limits. Cut along its seams:

- :mod:`.events`: the event kinds (diagnostics keys) and the log that counts them;
- :mod:`.inputs`: the input and stamp policy (:class:`InputPolicy`) and the velocity estimate;
- :mod:`.limits`: the force limits (:class:`ForceLimits`: non-finite reset, clamp, rate bound);
- :mod:`.haptic`: the tick that composes them with the model's step and builds the :class:`TickResult`.
"""

from msgs_schema.parameters import SessionParams

from .events import (
    CONTACT_SEPARATED,
    DEGENERATE_WAVE_SPEED,
    FORCE_CLAMPED,
    FORCE_NON_FINITE,
    FORCE_RATE_LIMITED,
    FUTURE_STAMP,
    NON_FINITE,
    OUTSIDE_WORKSPACE,
    PATCH_CLIPPED,
    REGIME_EVENTS,
    REUSS_BOUND,
    STALE_STAMP,
    STALL_RELEASED,
    STALL_RESUMED,
    STAMP_BACKWARDS,
    STAMP_DUPLICATE,
    STAMP_RESYNC,
    TELEPORT,
    TICK_CLAMPED,
    TOOL_BELOW_TISSUE,
    TOOL_OFF_SHEET,
    UNKNOWN_FRAME,
    WATCHDOG,
    EventLog,
)
from .haptic import NO_CONTACT, HapticSession, TickResult
from .inputs import AnswerThrottle, InputPolicy, TickInput, velocity_estimate
from .limits import RATE_ALLOWANCE_S, ForceLimits

__all__ = [
    "AnswerThrottle",
    "CONTACT_SEPARATED",
    "DEGENERATE_WAVE_SPEED",
    "FORCE_CLAMPED",
    "FORCE_NON_FINITE",
    "FORCE_RATE_LIMITED",
    "FUTURE_STAMP",
    "NON_FINITE",
    "OUTSIDE_WORKSPACE",
    "NO_CONTACT",
    "PATCH_CLIPPED",
    "RATE_ALLOWANCE_S",
    "REGIME_EVENTS",
    "REUSS_BOUND",
    "STALE_STAMP",
    "STAMP_BACKWARDS",
    "STAMP_DUPLICATE",
    "STALL_RELEASED",
    "STALL_RESUMED",
    "STAMP_RESYNC",
    "TELEPORT",
    "TICK_CLAMPED",
    "TOOL_BELOW_TISSUE",
    "TOOL_OFF_SHEET",
    "UNKNOWN_FRAME",
    "WATCHDOG",
    "EventLog",
    "ForceLimits",
    "HapticSession",
    "InputPolicy",
    "SessionParams",
    "TickInput",
    "TickResult",
    "velocity_estimate",
]
