"""Haptic session: validated tool input -> model tick -> safe force. No rclpy.

The live node and the offline replay both drive the model through this class, so
they apply the same input checks, velocity estimate and force limits. Times are
integer nanoseconds: message stamps for inputs, the caller's clock for ``now_ns``.
"""

from __future__ import annotations

import math
from collections import Counter
from collections.abc import Callable
from dataclasses import dataclass

import numpy as np

from .model import SkinModel
from .model import kernels as kn

# Rejection / event kinds (diagnostics keys).
NON_FINITE = "non_finite_input"
UNKNOWN_FRAME = "unknown_frame"
STAMP_BACKWARDS = "stamp_backwards"
STAMP_DUPLICATE = "stamp_duplicate"
STALE_STAMP = "stale_stamp"
FUTURE_STAMP = "future_stamp"
STAMP_RESYNC = "stamp_resync"
TELEPORT = "teleport"
WATCHDOG = "watchdog_stale_input"
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
"""Counted in :attr:`HapticSession.regime_counts`, not :attr:`HapticSession.counts` (rejections and safety
actions): they occur in ordinary use (every fast release separates) and the model bounds them itself."""

RATE_ALLOWANCE_S = 1e-3
"""Allowance of the force-rate bound (a token bucket on the caller's clock): over any window of W
seconds the published force changes by at most ``max_force_rate_n_per_s * (W + RATE_ALLOWANCE_S)``.
A tick may spend its own interval's change plus what earlier ticks left unspent, up to the larger of
its interval and one 1 kHz servo period: a slow loop (250 Hz) still gets ``rate * dt`` per tick,
poses processed in a burst after a stall share one period's change, and a stamp that jumps ahead
buys nothing."""

DEGENERATE_RETURN_S = 1.0
"""A layer whose fundamental mode needs longer than this for a quarter period (``pi / (2 lambda_11)``)
to return has a degenerate wave speed: skin visibly recovers from an indent well within a second,
while the paper's eq 9 (``lambda_11 = 0.0032 rad/s``) takes 490 s. Such a layer is released from
rest (``B*_mn = 0``, as eq 9 itself), since with no restoring force in human time a release velocity
``v`` would carry it ``v / lambda_11`` (31 m at 0.1 m/s) away."""


@dataclass(frozen=True)
class SessionParams:
    """Input and safety parameters (see ``msgs_schema.parameters`` for sources and bounds)."""

    tissue_frame: str = "tissue"
    watchdog_s: float = 0.05
    max_stamp_age_s: float = 1.0  # 0 disables the check (offline replay)
    max_force_n: float = 10.0
    teleport_distance_m: float = 0.02
    max_tool_speed_m_s: float = 3.0
    twist_max_skew_s: float = 0.005
    max_dt_s: float = 0.1
    max_future_s: float = 0.05  # a stamp this far ahead of the clock is rejected (clock skew allowance)
    resync_after: int = 50  # this many consecutive backwards stamps: accept the new time line
    max_force_rate_n_per_s: float = 1000.0  # see msgs_schema.parameters; 0 disables


class HapticSession:
    """Owns a :class:`SkinModel` and turns input samples into force ticks.

    Parameters
    ----------
    model : SkinModel
    params : SessionParams
    log : callable(kind, message), optional
        Called once per event kind (the first occurrence); every occurrence is counted
        in :attr:`counts` (rejections, safety actions) or :attr:`regime_counts` (:data:`REGIME_EVENTS`).
    """

    def __init__(self, model: SkinModel, params: SessionParams, log: Callable[[str, str], None] | None = None):
        self.model = None
        self.params = params
        self._log = log
        self.counts: Counter[str] = Counter()
        self.regime_counts: Counter[str] = Counter()
        self._logged: set[str] = set()
        self.pose_stamp_ns: int | None = None  # last accepted pose
        self.pose = (0.0, 0.0, 1.0)
        self.pose_rx_ns: int | None = None  # caller clock when it arrived
        self._prev_pose_stamp_ns: int | None = None
        self._prev_pose = (0.0, 0.0, 1.0)
        self.twist_stamp_ns: int | None = None
        self.twist = (0.0, 0.0, 0.0)
        self._teleported = False
        self._backwards_run = 0
        self._ticks = 0
        self._last_used_stamp_ns: int | None = None  # stamp of the pose the last tick used
        self._pending = False  # a pose arrived that no tick has consumed
        self._advanced_since_pose_ns = 0
        self.stale = True
        self.force_n = 0.0
        self._rate_budget_n = math.inf  # force-rate token bucket, capped at each tick
        self.answered_stamp_ns = 0
        self.velocity = (0.0, 0.0, 0.0)
        self.set_model(model)

    # --- events -----------------------------------------------------------------------
    def _event(self, kind: str, message: str) -> str:
        (self.regime_counts if kind in REGIME_EVENTS else self.counts)[kind] += 1
        if kind not in self._logged:
            self._logged.add(kind)
            if self._log:
                self._log(kind, message)
        return kind

    def set_model(self, model: SkinModel) -> None:
        """Swap in a new model (a live tissue parameter change); the tissue restarts at rest."""
        self.model = model
        lam11 = model.basis.lam.min(axis=1)  # each layer's fundamental, rad/s
        with np.errstate(divide="ignore"):
            quarter_s = np.where(lam11 > 0, 0.5 * math.pi / lam11, math.inf)
        self._degenerate = quarter_s > DEGENERATE_RETURN_S
        if self._degenerate.any():
            names = ", ".join(la.name for la, d in zip(model.cfg.layers, self._degenerate) if d)
            self._event(
                DEGENERATE_WAVE_SPEED,
                f"degenerate wave speed: {names} take {quarter_s.max():.3g} s to return (c = "
                f"{min(la.wave_speed_m_per_s for la in model.cfg.layers):.3g} m/s); released from rest",
            )
        cfg = model.cfg
        self._patch_free = (0.5 * (cfg.sheet_size_m[0] - cfg.patch_size_m[0]), 0.5 * (cfg.sheet_size_m[1] - cfg.patch_size_m[1]))

    # --- inputs -----------------------------------------------------------------------
    def on_pose(self, stamp_ns: int, frame: str, xyz, now_ns: int | None = None, rx_ns: int | None = None) -> str | None:
        """Validate and store a tool pose. Returns None if accepted, else the rejection kind.

        ``now_ns``: the receiver's clock in the stamps' time base (ROS time), for the stamp
        age check (None skips it, as offline replay does). ``rx_ns``: arrival time on the
        clock that :meth:`tick` gets (default ``now_ns``, else the stamp).
        """
        x, y, z = (float(c) for c in xyz)
        if not (math.isfinite(x) and math.isfinite(y) and math.isfinite(z)):
            return self._event(NON_FINITE, f"rejected tool pose with non-finite position ({x}, {y}, {z})")
        if frame != self.params.tissue_frame:
            return self._event(UNKNOWN_FRAME, f"rejected tool pose in frame '{frame}', expected '{self.params.tissue_frame}'")
        if now_ns is not None and self.params.max_stamp_age_s > 0:
            age = (now_ns - stamp_ns) * 1e-9
            if age > self.params.max_stamp_age_s:
                return self._event(
                    STALE_STAMP,
                    f"rejected tool pose: stamp is {age:.3f} s old (limit {self.params.max_stamp_age_s} s); "
                    "check clock sync or use_sim_time",
                )
            if -age > self.params.max_future_s:
                return self._event(
                    FUTURE_STAMP, f"rejected tool pose: stamp is {-age:.3f} s in the future; check clock sync or use_sim_time"
                )
        if self.pose_stamp_ns is not None:
            if stamp_ns <= self.pose_stamp_ns:
                self._backwards_run += 1
                if self._backwards_run < self.params.resync_after:
                    if stamp_ns == self.pose_stamp_ns:
                        return self._event(STAMP_DUPLICATE, "rejected tool pose with a repeated stamp")
                    return self._event(
                        STAMP_BACKWARDS, f"rejected tool pose: stamp went back {(self.pose_stamp_ns - stamp_ns) * 1e-6:.3f} ms"
                    )
                self._event(STAMP_RESYNC, f"{self._backwards_run} poses behind the last stamp: following the new time line")
                self.pose_stamp_ns = self._last_used_stamp_ns = None
                self._teleported = True
        self._backwards_run = 0
        if self.pose_stamp_ns is not None and not self._teleported:
            dist = math.dist((x, y, z), self.pose)
            dt = (stamp_ns - self.pose_stamp_ns) * 1e-9
            if dist > self.params.teleport_distance_m or dist > self.params.max_tool_speed_m_s * max(dt, 1e-3):
                self._teleported = True
                self._event(TELEPORT, f"tool jumped {dist * 1e3:.1f} mm in {dt * 1e3:.2f} ms: contact restarted")
        self._prev_pose_stamp_ns, self._prev_pose = self.pose_stamp_ns, self.pose
        self.pose_stamp_ns, self.pose = stamp_ns, (x, y, z)
        self.pose_rx_ns = rx_ns if rx_ns is not None else (now_ns if now_ns is not None else stamp_ns)
        self._pending = True
        return None

    def on_twist(self, stamp_ns: int, frame: str, linear) -> str | None:
        vx, vy, vz = (float(c) for c in linear)
        if not (math.isfinite(vx) and math.isfinite(vy) and math.isfinite(vz)):
            return self._event(NON_FINITE, f"rejected tool twist with non-finite velocity ({vx}, {vy}, {vz})")
        if frame != self.params.tissue_frame:
            return self._event(UNKNOWN_FRAME, f"rejected tool twist in frame '{frame}', expected '{self.params.tissue_frame}'")
        self.twist_stamp_ns, self.twist = stamp_ns, (vx, vy, vz)
        return None

    # --- ticks ------------------------------------------------------------------------
    def _velocity(self):
        p = self.params
        if self.twist_stamp_ns is not None and abs(self.twist_stamp_ns - self.pose_stamp_ns) * 1e-9 <= p.twist_max_skew_s:
            v = self.twist
        elif self._prev_pose_stamp_ns is not None and self.pose_stamp_ns > self._prev_pose_stamp_ns:
            dt = (self.pose_stamp_ns - self._prev_pose_stamp_ns) * 1e-9
            v = tuple((a - b) / dt for a, b in zip(self.pose, self._prev_pose))
        else:
            v = (0.0, 0.0, 0.0)
        s = math.sqrt(v[0] * v[0] + v[1] * v[1] + v[2] * v[2])
        if s > p.max_tool_speed_m_s:
            v = tuple(c * p.max_tool_speed_m_s / s for c in v)
        return v

    def tick(self, now_ns: int, elapsed_ns: int) -> float:
        """One haptic tick. ``elapsed_ns``: caller-clock time since the previous tick.

        If a new pose arrived, the model advances by the pose stamps' difference (less
        the time already advanced by pose-less ticks); otherwise by ``elapsed_ns`` with the
        last pose held. Returns the force (N, along +z) and stores it in :attr:`force_n`.
        """
        p = self.params
        model = self.model
        driven_before = model.driven.copy() if self._degenerate.any() else None
        q_before = model.q.copy() if driven_before is not None else None
        stale = self.pose_rx_ns is None or (now_ns - self.pose_rx_ns) * 1e-9 > p.watchdog_s
        if stale and not self.stale:
            self._event(WATCHDOG, f"no valid tool pose for {p.watchdog_s * 1e3:.0f} ms: force set to zero, tissue released")
        self.stale = stale
        if self._pending and not stale:
            self._pending = False
            if self._last_used_stamp_ns is None:
                dt_ns = elapsed_ns
            else:  # from the pose the previous tick used: several poses per tick lose no time
                dt_ns = self.pose_stamp_ns - self._last_used_stamp_ns - self._advanced_since_pose_ns
            self._last_used_stamp_ns = self.pose_stamp_ns
            self._advanced_since_pose_ns = 0
            if self._teleported:
                model.release()
                self._teleported = False
                v = (0.0, 0.0, 0.0)
            else:
                v = self._velocity()
            pos = self.pose
            self.answered_stamp_ns = self.pose_stamp_ns
        else:
            dt_ns = elapsed_ns
            self._advanced_since_pose_ns += elapsed_ns
            v = (0.0, 0.0, 0.0)
            if stale:
                pos = (self.pose[0], self.pose[1], 1.0)  # unknown tool: treat as lifted off
                model.release()
            else:
                pos = self.pose
        dt = max(dt_ns, 0) * 1e-9
        if dt > p.max_dt_s:
            self._event(TICK_CLAMPED, f"tick interval {dt * 1e3:.1f} ms advanced as max_dt_s = {p.max_dt_s * 1e3:.0f} ms")
            dt = p.max_dt_s
        self.velocity = v
        force = model.step(pos, v, dt)
        self._ticks += 1
        self._regime_events(pos)
        if driven_before is not None:
            self._release_degenerate_from_rest(driven_before, q_before)
        if not math.isfinite(force) or (self._ticks % 64 == 0 and not math.isfinite(model.energy())):
            self._event(FORCE_NON_FINITE, f"model state became non-finite (force {force}): published 0, tissue reset to rest")
            model.reset()
            force = 0.0
        if force > p.max_force_n:
            self._event(FORCE_CLAMPED, f"force {force:.2f} N clamped to max_force_n = {p.max_force_n} N")
            force = p.max_force_n
        if p.max_force_rate_n_per_s > 0:
            rate = p.max_force_rate_n_per_s
            elapsed_s = max(elapsed_ns, 0) * 1e-9
            budget = min(self._rate_budget_n + rate * elapsed_s, rate * max(elapsed_s, RATE_ALLOWANCE_S))
            if abs(force - self.force_n) > budget:
                self._event(
                    FORCE_RATE_LIMITED,
                    f"force step {self.force_n:.3f} -> {force:.3f} N after {max(elapsed_ns, 0) * 1e-6:.2f} ms limited "
                    f"to {budget:.3f} N by max_force_rate_n_per_s = {rate:g} N/s",
                )
                force = self.force_n + math.copysign(budget, force - self.force_n)
            self._rate_budget_n = budget - abs(force - self.force_n)
            force = min(force, p.max_force_n)  # the clamp is the hard limit, also right after a live lowering
        if stale:
            force = 0.0  # a safety stop is not rate limited
        self.force_n = force
        return force

    # --- model regime ---------------------------------------------------------------------
    def _regime_events(self, pos) -> None:
        """Log (once each) the model-regime flags of the last step; the kernel already bounded them."""
        f = self.model.flags
        if f & kn.FLAG_BOTTOMED:
            self._event(TOOL_BELOW_TISSUE, f"tool {-pos[2] * 1e3:.2f} mm deep, below the tissue: depth clamped at the bottom")
        if f & kn.FLAG_LAYER_BOUND:
            self._event(REUSS_BOUND, "a layer's Reuss compression left [0, thickness] (fast press or retraction, or a "
                        "saturated layer): held at the bound, the rest of the depth split over the others")  # fmt: skip
        if f & kn.FLAG_SEPARATED:
            self._event(CONTACT_SEPARATED, "tool retracted faster than the tissue follows (Reuss stress <= 0): contact released")
        if f & kn.FLAG_OFF_SHEET and pos[2] < 0.0:
            self._event(TOOL_OFF_SHEET, f"tool at ({pos[0] * 1e3:.1f}, {pos[1] * 1e3:.1f}) mm is off the sheet: no contact")
        if f & kn.FLAG_CONTACT and (abs(pos[0]) > self._patch_free[0] or abs(pos[1]) > self._patch_free[1]):
            self._event(PATCH_CLIPPED, f"contact at ({pos[0] * 1e3:.1f}, {pos[1] * 1e3:.1f}) mm: the deformation patch "
                        "passes the sheet edge and is clipped there (the paper's incomplete deformation)")  # fmt: skip

    def _release_degenerate_from_rest(self, driven_before, q_before) -> None:
        """A degenerate layer released this tick restarts from its last driven shape at rest (eq 9's ``B* = 0``)."""
        m = self.model
        for li in np.flatnonzero(driven_before.astype(bool) & ~m.driven.astype(bool) & self._degenerate):
            prop = m._prop  # this tick's exact modal propagator, filled by the kernel
            m.q[li] = prop[0, li] * q_before[li]
            m.v[li] = prop[2, li] * q_before[li]
