"""Force limits: what the session publishes of the model's force. No model and no rclpy.

In order: a non-finite force (or model state) publishes 0 and asks for a reset to rest, the force is clamped
to ``max_force_n``, its rate of change is bounded by a token bucket on the model's clock (the pose stamps), and a
stale input
publishes 0 (a safety stop is not rate limited).
"""

from __future__ import annotations

import math
from collections.abc import Callable

from msgs_schema.parameters import SessionParams

from .events import FORCE_CLAMPED, FORCE_NON_FINITE, FORCE_RATE_LIMITED, EventSink

RATE_ALLOWANCE_S = 1e-3
"""Allowance of the force-rate bound (a token bucket on the model's clock: the stamp interval of each answered
pose, :attr:`TickInput.rate_dt_ns`): over any W seconds of pose stamps the published force changes by at most
``max_force_rate_n_per_s * (W + RATE_ALLOWANCE_S)``. A tick may spend its own interval's change plus what earlier
ticks left unspent, up to the larger of its interval and one 1 kHz servo period: a slow loop (250 Hz) still gets
``rate * dt`` per tick. On the stamps, not the caller's clock, so that poses processed in a burst after a stall get
the answer the offline replay gives them (tests/test_timing_policy.py)."""


class ForceLimits:
    """The session's force safety: non-finite reset, clamp, rate bound, watchdog zero.

    Parameters
    ----------
    params : SessionParams
        ``max_force_n`` and ``max_force_rate_n_per_s``, read at every call (the session replaces it on a live
        parameter change; a lowered clamp applies at once).
    event : callable(kind, message) -> kind
        Where the safety events go (:class:`~skin_sim_node.session.events.EventLog`).

    Attributes
    ----------
    force_n : float
        The last published force (N), the rate bound's reference.
    """

    def __init__(self, params: SessionParams, event: EventSink):
        self.params = params
        self._event = event
        self.force_n = 0.0
        self._rate_budget_n = math.inf  # force-rate token bucket, capped at each tick

    def apply(
        self,
        force: float,
        elapsed_ns: int,
        stale: bool,
        state_finite: Callable[[], bool] | None = None,
        rises_only: bool = False,
    ) -> tuple[float, bool]:
        """The force to publish for the model's ``force``, and whether the model must be reset to rest.

        Parameters
        ----------
        force : float
            The model's force (N, along +z).
        elapsed_ns : int
            Model time since the previous step (ns; the pose stamps' interval): the rate bound's clock.
        stale : bool
            The input watchdog fired: publish 0.
        state_finite : callable() -> bool, optional
            Asked (only while the force is finite) whether the model's state is still finite; None skips it
            (the session asks every 64 ticks).
        rises_only : bool
            The rate bound limits rises only (a tool that declares it, ``ToolNeeds.rises_only``): a falling force takes
            energy from no one, and a puncture's drop is the event the hand must feel within one tick, not spread over
            several.

        Returns
        -------
        force : float
            The force to publish (N), also kept in :attr:`force_n`.
        reset : bool
            The model's force or state was non-finite: the caller resets it to rest.
        """
        p = self.params
        if stale:  # a safety stop: 0 at once, not rate limited (and the held tissue's force is no rate event)
            self.force_n = 0.0
            self._rate_budget_n = 0.0
            return 0.0, False
        reset = not math.isfinite(force) or (state_finite is not None and not state_finite())
        if reset:
            self._event(FORCE_NON_FINITE, f"model state became non-finite (force {force}): published 0, tissue reset to rest")
            force = 0.0
        if force > p.max_force_n:
            self._event(FORCE_CLAMPED, f"force {force:.2f} N clamped to max_force_n = {p.max_force_n} N")
            force = p.max_force_n
        if p.max_force_rate_n_per_s > 0:
            rate = p.max_force_rate_n_per_s
            elapsed_s = max(elapsed_ns, 0) * 1e-9
            budget = min(self._rate_budget_n + rate * elapsed_s, rate * max(elapsed_s, RATE_ALLOWANCE_S))
            if abs(force - self.force_n) > budget and not (rises_only and force < self.force_n):
                self._event(
                    FORCE_RATE_LIMITED,
                    f"force step {self.force_n:.3f} -> {force:.3f} N after {max(elapsed_ns, 0) * 1e-6:.2f} ms limited "
                    f"to {budget:.3f} N by max_force_rate_n_per_s = {rate:g} N/s",
                )
                force = self.force_n + math.copysign(budget, force - self.force_n)
            change = max(force - self.force_n, 0.0) if rises_only else abs(force - self.force_n)
            self._rate_budget_n = budget - change
            force = min(force, p.max_force_n)  # the clamp is the hard limit, also right after a live lowering
        self.force_n = force
        return force, reset
