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

from .model import SkinModel

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


class HapticSession:
    """Owns a :class:`SkinModel` and turns input samples into force ticks.

    Parameters
    ----------
    model : SkinModel
    params : SessionParams
    log : callable(kind, message), optional
        Called once per event kind (the first occurrence); every occurrence is counted
        in :attr:`counts`.
    """

    def __init__(self, model: SkinModel, params: SessionParams, log: Callable[[str, str], None] | None = None):
        self.model = model
        self.params = params
        self._log = log
        self.counts: Counter[str] = Counter()
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
        self.answered_stamp_ns = 0
        self.velocity = (0.0, 0.0, 0.0)

    # --- events -----------------------------------------------------------------------
    def _event(self, kind: str, message: str) -> str:
        self.counts[kind] += 1
        if kind not in self._logged:
            self._logged.add(kind)
            if self._log:
                self._log(kind, message)
        return kind

    def set_model(self, model: SkinModel) -> None:
        """Swap in a new model (a live tissue parameter change); the tissue restarts at rest."""
        self.model = model

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
        dt = min(max(dt_ns, 0) * 1e-9, p.max_dt_s)
        self.velocity = v
        force = model.step(pos, v, dt)
        self._ticks += 1
        if not math.isfinite(force) or (self._ticks % 64 == 0 and not math.isfinite(model.energy())):
            self._event(FORCE_NON_FINITE, f"model state became non-finite (force {force}): published 0, tissue reset to rest")
            model.reset()
            force = 0.0
        if force > p.max_force_n:
            self._event(FORCE_CLAMPED, f"force {force:.2f} N clamped to max_force_n = {p.max_force_n} N")
            force = p.max_force_n
        if stale:
            force = 0.0
        self.force_n = force
        return force
