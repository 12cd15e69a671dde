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

from msgs_schema.parameters import SessionParams

from .model import (
    FLAG_BOTTOMED,
    FLAG_CONTACT,
    FLAG_LAYER_BOUND,
    FLAG_OFF_SHEET,
    FLAG_SEPARATED,
    ContactTangent,
    SkinModel,
    normal_tangent,
)

__all__ = ["HapticSession", "SessionParams", "TickResult"]

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

NO_CONTACT = normal_tangent(0.0, 0.0, 0.0, 0.0)
"""The tangent out of contact (no force, no stiffness), shared: :meth:`SkinModel.tangent` builds its arrays
anew on each call (8 us of a 1 ms tick), so it is called only while the tool is in contact."""

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


@dataclass(frozen=True)
class TickResult:
    """What one haptic tick produced: the one output path (node, offline replay and benchmarks read only this).

    :func:`msgs_schema.convert.fill_wrench_from_tick` and :func:`msgs_schema.convert.fill_contact_from_tick`
    turn it into the ``tool/wrench`` and ``tissue/contact`` messages.

    Attributes
    ----------
    seq : int
        Tick sequence number, increasing by one per tick of this session (from 1).
    stamp_ns : int
        Stamp of the pose the model ran at (the last accepted pose; 0 before any).
    answered : bool
        This tick consumed a newly accepted pose (it answers that pose).
    x0_m : tuple of 3 float
        Tool position the model ran at (tissue frame, m); ``z = 1 m`` (lifted off) when stale.
    velocity_m_s : tuple of 3 float
        Tool velocity the model ran at (m/s).
    force_n : tuple of 3 float
        Published reaction force on the tool (N) after the session's clamp, rate bound and watchdog.
    depth_m : float
        Tool depth of the Reuss split (eq 6), 0 out of contact.
    n_affected : int
        Layers engaged by the contact (the deepest reached).
    compression_m, compression_rate_m_s, stress_pa : tuple of float, one per layer
        Reuss compression of each layer, its rate (the normal speed shared in proportion to the
        compression), and the common Reuss stress on the engaged layers (0 on the others).
    flags : int
        Model regime flags of the step (``skin_sim_node.model.FLAG_*``).
    events : tuple of str
        Rejection, safety and regime event kinds raised since the previous tick (each occurrence).
    stale : bool
        The input watchdog fired: the force is zero and the tissue released.
    idle : bool
        The model skipped the kernel (tissue at rest, tool off it).
    tangent : ContactTangent
        The model's local linearisation at ``x0_m`` (:meth:`SkinModel.tangent`), for the local contact model.
    """

    seq: int
    stamp_ns: int
    answered: bool
    x0_m: tuple[float, float, float]
    velocity_m_s: tuple[float, float, float]
    force_n: tuple[float, float, float]
    depth_m: float
    n_affected: int
    compression_m: tuple[float, ...]
    compression_rate_m_s: tuple[float, ...]
    stress_pa: tuple[float, ...]
    flags: int
    events: tuple[str, ...]
    stale: bool
    idle: bool
    tangent: ContactTangent

    @property
    def force_z_n(self) -> float:
        """The force along the tissue normal ``+z`` (N), the model's single force component."""
        return self.force_n[2]


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
        self._seq = 0
        self._tick_events: list[str] = []
        self.last: TickResult | None = None  # the last tick's result
        self.set_model(model)

    # --- events -----------------------------------------------------------------------
    def _event(self, kind: str, message: str) -> str:
        (self.regime_counts if kind in REGIME_EVENTS else self.counts)[kind] += 1
        self._tick_events.append(kind)
        if kind not in self._logged:
            self._logged.add(kind)
            if self._log:
                self._log(kind, message)
        return kind

    def set_model(self, model: SkinModel) -> None:
        """Swap in a new model (a live tissue parameter change); the tissue restarts at rest."""
        self.model = model
        if model.degenerate_layers:  # the model releases them from rest itself
            names = ", ".join(model.degenerate_layers)
            self._event(
                DEGENERATE_WAVE_SPEED,
                f"degenerate wave speed: {names} take {model.slowest_return_s:.3g} s to return (c = "
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

    def tick(self, now_ns: int, elapsed_ns: int) -> TickResult:
        """One haptic tick. ``elapsed_ns``: caller-clock time since the previous tick.

        If a new pose arrived, the model advances by the pose stamps' difference (less
        the time already advanced by pose-less ticks); otherwise by ``elapsed_ns`` with the
        last pose held. Returns the tick's :class:`TickResult` (also kept in :attr:`last`);
        the force (N, along +z) is also stored in :attr:`force_n`.
        """
        p = self.params
        model = self.model
        stale = self.pose_rx_ns is None or (now_ns - self.pose_rx_ns) * 1e-9 > p.watchdog_s
        if stale and not self.stale:
            self._event(WATCHDOG, f"no valid tool pose for {p.watchdog_s * 1e3:.0f} ms: force set to zero, tissue released")
        self.stale = stale
        answered = self._pending and not stale
        if answered:
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
        return self._result(answered, pos, v, force, stale)

    def _result(self, answered: bool, pos, v, force: float, stale: bool) -> TickResult:
        """The frozen record of this tick (the contact message's per-layer rate and stress included)."""
        m = self.model
        n = m.n_affected
        depth = m.depth_m
        comp = tuple(m.compression_m.tolist())
        nl = len(comp)
        k = -v[2] / depth if depth > 0 else 0.0  # the normal speed, shared in proportion to each layer's compression
        rate = tuple([k * c for c in comp])
        stress = (m.stress_pa,) * n + (0.0,) * (nl - n)
        self._seq += 1
        events = tuple(self._tick_events) if self._tick_events else ()
        self._tick_events.clear()
        flags = m.flags
        self.last = TickResult(
            seq=self._seq, stamp_ns=self.answered_stamp_ns, answered=answered, x0_m=tuple(pos), velocity_m_s=tuple(v),
            force_n=(0.0, 0.0, force), depth_m=depth, n_affected=n, compression_m=comp, compression_rate_m_s=rate,
            stress_pa=stress, flags=flags, events=events, stale=stale, idle=m.last_tick_idle,
            tangent=m.tangent() if flags & FLAG_CONTACT else NO_CONTACT,
        )  # fmt: skip
        return self.last

    # --- read-outs for the node's diagnostics, display and logs (no caller reads the model) ---------------------
    @property
    def kernel_calls(self) -> int:
        """Model kernel invocations so far (idle ticks make none)."""
        return self.model.kernel_calls

    @property
    def modes_per_axis(self) -> tuple[int, ...]:
        """Modes per axis each layer uses now (adaptive: its current level; else the fixed count)."""
        return tuple(int(k) for k in self.model.modes_per_axis())

    @property
    def idle_ticks(self) -> int:
        return self.model.idle_ticks

    @property
    def state_key(self) -> tuple[int, int]:
        """Changes whenever the deformation may have changed (a kernel call, a reset or a new model)."""
        return id(self.model), self.model.version

    def display_state(self) -> dict:
        """Live views of the modal state the display rebuilds the grid from (copy them before the next tick)."""
        m = self.model
        return {"q": m.q, "centre": m.centre, "driven": m.driven, "level": m.level, "active": m.active}

    def build_grid(self):
        """The display grid of the current deformation (:meth:`SkinModel.build_grid`)."""
        return self.model.build_grid()

    def state(self) -> dict:
        """A copy of the model's dynamic state (see :meth:`SkinModel.state`), e.g. at peak force."""
        return self.model.state()

    def describe_modes(self) -> str:
        """The mode counts the model really runs: adaptive levels, or the fixed ``modes.m x modes.n``."""
        cfg, b = self.model.cfg, self.model.basis
        if cfg.lod.adaptive_modes:
            top = int(b.level_modes[-1])
            return (
                f"adaptive modes on (tissue.lod.adaptive_modes): each layer uses 1x1 to {top}x{top} modes per axis "
                f"({b.n_modes} odd modes at most) to keep the truncation within tissue.lod.tolerance_m = "
                f"{cfg.lod.tolerance_m:g} m; tissue.modes.m x n = {cfg.modes[0]}x{cfg.modes[1]} applies only with it off"
            )
        return f"fixed modes: {cfg.modes[0]}x{cfg.modes[1]} per axis ({b.n_modes} odd modes), adaptive modes off"

    # --- model regime ---------------------------------------------------------------------
    def _regime_events(self, pos) -> None:
        """Log (once each) the model-regime flags of the last step; the kernel already bounded them."""
        f = self.model.flags
        if f & FLAG_BOTTOMED:
            self._event(TOOL_BELOW_TISSUE, f"tool {-pos[2] * 1e3:.2f} mm deep, below the tissue: depth clamped at the bottom")
        if f & FLAG_LAYER_BOUND:
            self._event(REUSS_BOUND, "a layer's Reuss compression left [0, thickness] (fast press or retraction, or a "
                        "saturated layer): held at the bound, the rest of the depth split over the others")  # fmt: skip
        if f & FLAG_SEPARATED:
            self._event(CONTACT_SEPARATED, "tool retracted faster than the tissue follows (Reuss stress <= 0): contact released")
        if f & FLAG_OFF_SHEET and pos[2] < 0.0:
            self._event(TOOL_OFF_SHEET, f"tool at ({pos[0] * 1e3:.1f}, {pos[1] * 1e3:.1f}) mm is off the sheet: no contact")
        if f & FLAG_CONTACT and (abs(pos[0]) > self._patch_free[0] or abs(pos[1]) > self._patch_free[1]):
            self._event(PATCH_CLIPPED, f"contact at ({pos[0] * 1e3:.1f}, {pos[1] * 1e3:.1f}) mm: the deformation patch "
                        "passes the sheet edge and is clipped there (the paper's incomplete deformation)")  # fmt: skip
