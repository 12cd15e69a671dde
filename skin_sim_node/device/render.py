"""Render the node's local contact model at the device's servo rate (issue 12). Pure: no ROS.

The node answers a tool pose with a force and a local model of the contact around that pose
(:class:`msgs_schema.contact_model.LocalModel`). Between models the bridge computes the force from
the device's own pose every servo tick (Mark et al. 1996, "Adding force feedback to graphics
systems": plane-and-probe; sawSensablePhantom ``servo_ci``; SOFA ``LCPForceFeedback``)::

    F(x, v) = f0 + K (x - x0) + D (v - v0)

- one-sided along the contact normal: the tissue pushes, never pulls; the tangential part shrinks
  with the normal force when that drops below the model's (no step at separation);
- ``K`` and ``D`` capped (spectral norm, the largest gain in any direction) at the device's passive limits, the
  tangential part inside the model's friction cone (:data:`FRICTION_CONE_FLOOR`), ``|F|`` at the device's force
  limit by scaling the vector;
- a crossfade from the force being rendered to each new model, over the interval between models;
- once the model is older than its time-to-live, or the tool leaves its validity radius, a linear
  fade of the last force to zero over ``fade_s``: never a step;
- optionally the time-domain passivity controller (:mod:`.passivity`) on the rendered force.

Units: SI, tissue frame (the bridge maps the device pose in and the force out, see
:class:`skin_sim_node.device.bridge.DeviceMapping`). Times are seconds on the device's clock (its pose stamps;
:data:`MAX_TICK_S`).
"""

from __future__ import annotations

import math
from collections import deque
from dataclasses import dataclass

import numpy as np

from msgs_schema.contact_model import LocalModel
from msgs_schema.tissue import FRICTION_COEFFICIENT

from .mapping import TOUCH_MAX_DAMPING_N_S_PER_M, TOUCH_MAX_STIFFNESS_N_PER_M, TOUCH_PEAK_FORCE_N
from .passivity import PassivityController

FADE_S = 0.05
"""Fade to zero when the model is stale or left (s): issue 12 asks ~50 ms, about a hand's reflex latency
(short enough to stop a stale push, long enough that the user feels no step)."""

CROSSFADE_MIN_S = 1e-3
"""Shortest crossfade (s): one servo period of a 1 kHz device; a shorter one is a step at the tick."""

CROSSFADE_MAX_S = 0.02
"""Blend from zero (the first model) or from a fade (s): two periods of the slowest server rate of the rate lever
(100 Hz). Model-to-model switches blend over :data:`CROSSFADE_MIN_S` only (:meth:`ContactRenderer.set_model`)."""

PASSIVITY_DELAY_TICKS = 2
"""Ticks from the bridge rendering a force (at device pose ``k``) to the device applying it: the command reaches
the device before its next tick (DDS on one host: well under 1 ms) and a servo loop applies a command from the
tick after it arrives (zero-order hold, as :class:`skin_sim_node.device.stylus.SimulatedDevice`): it acts over
the displacement from pose ``k + 1`` to ``k + 2``. The passivity observer (Hannaford & Ryu 2002) must book that
displacement against that force, or it misses the energy the delayed loop generates."""

MAX_TICK_S = 0.004
"""Most device time one tick advances the crossfade and the fade (s). The clock of both is the device's (its pose
stamps), so a tick that reaches the bridge late, or a burst of queued poses, does not jump; a gap in the stamps
themselves (the driver's servo loop was late) advances them by at most 4 ms, four periods of a 1 kHz Touch: over
the gap the device held its last command anyway, and on the 50 ms fade 4 ms is an 8 % step, under the 10 % the
kill aim of issue 19 allows. The time-to-live is measured on the unclamped stamps: a model is as old as it is."""

FRICTION_CONE_FLOOR = FRICTION_COEFFICIENT
"""Least tangential-to-normal force ratio the renderer allows (1): the tissue's default friction coefficient, 0.5
(``msgs_schema.tissue.FRICTION_COEFFICIENT``, Derler and Gerhardt 2012). The tissue model's tangential force is
``mu F_n g`` with ``|g| <= 1`` (:meth:`skin_sim_node.model.SkinModel.tangent`), so a model's ``K`` and ``D`` cannot
mean more friction than ``mu`` times the normal force; the cone of a model is the larger of its own ratio at
``f0`` (``mu |g|`` while sliding, whatever ``mu`` is configured) and this floor (a stroke that starts from rest,
until the next model says how fast it slides)."""

STATES = ("none", "model", "crossfade", "fade")


def _finite(v) -> bool:
    return bool(np.isfinite(v).all())


@dataclass
class _Slot:
    """A model ready to evaluate: bounded matrices, the normal force at x0 and the friction cone.

    ``rx_s``: arrival on the device clock (pose stamps, s); None until the first device tick.
    """

    m: LocalModel
    rx_s: float | None
    K: np.ndarray
    D: np.ndarray
    fn0: float
    cone: float

    def force(self, x: np.ndarray, v: np.ndarray | None) -> np.ndarray:
        """``f0 + K (x - x0) + D (v - v0)``, one-sided along the normal and inside the model's friction cone."""
        m = self.m
        f = m.f0_n + self.K @ (x - m.x0_m)
        if v is not None:
            f = f + self.D @ (v - m.v0_m_s)
        n = m.normal
        fn = float(n @ f)
        if fn <= 0.0 or self.fn0 <= 0.0:
            return np.zeros(3) if fn <= 0.0 else fn * n
        t = f - fn * n
        if fn < self.fn0:
            t = t * (fn / self.fn0)
        t_n = float(np.linalg.norm(t))
        if t_n > self.cone * fn:  # K or D asked for more friction than the tissue model can give: not amplified
            t = t * (self.cone * fn / t_n)
        return fn * n + t


def cap_spectral_norm(A: np.ndarray, limit: float) -> np.ndarray:
    """``A`` scaled down as a whole so that its spectral norm (its largest gain, in any direction) is at most
    ``limit``; its direction structure is kept."""
    s = float(np.linalg.norm(A, 2))
    return A * (limit / s) if s > limit else A.copy()


def clamp_vec(f: np.ndarray, max_n: float) -> np.ndarray:
    """``f`` scaled down as a vector to magnitude ``max_n`` if longer (direction kept, never per axis)."""
    mag = float(np.linalg.norm(f))
    return f * (max_n / mag) if mag > max_n else f


class ContactRenderer:
    """Servo-rate force from local contact models (see the module docstring).

    Parameters
    ----------
    max_force_n : float
        Force magnitude limit (N), tissue units: the vector is scaled, never clipped per axis.
    max_stiffness_n_per_m, max_damping_n_s_per_m : float
        Spectral-norm caps of ``K`` and ``D`` (N/m, N s/m), tissue units; ``inf``: uncapped. Defaults: a Touch's
        (:data:`skin_sim_node.device.mapping.TOUCH_MAX_STIFFNESS_N_PER_M`, ``TOUCH_MAX_DAMPING_N_S_PER_M``).
    fade_s : float
        Fade time to zero after the model goes stale or the tool leaves it (s, device clock).
    crossfade_min_s, crossfade_max_s : float
        Bounds of the crossfade to a new model (its length is the interval since the previous model).
    passivity_mass_kg : float or None
        Apparent device mass for the passivity controller (tissue units); None: no controller.
    passivity_delay_ticks : int
        Device ticks from rendering a force to the start of the tick over which the device applies it
        (:data:`PASSIVITY_DELAY_TICKS`); the passivity observer books each displacement against that force.
    use_damping : bool
        Render ``D (v - v0)`` when a velocity is given.
    friction_cone_floor : float
        :data:`FRICTION_CONE_FLOOR`.
    max_tick_s : float
        :data:`MAX_TICK_S`.

    Attributes
    ----------
    state : str
        ``none`` (no model yet), ``model``, ``crossfade`` or ``fade`` (stale/left model, or fading after it).
    counts : dict
        ``models`` accepted, ``rejected_non_finite``, ``rejected_out_of_order``, ``fades_ttl``, ``fades_radius``.

    Notes
    -----
    The clock is the device's: :meth:`render` takes the pose's stamp (s), and :meth:`set_model` without a time
    books the model at the latest device tick (the one it will first be rendered after).
    """

    def __init__(
        self,
        max_force_n: float = TOUCH_PEAK_FORCE_N,
        max_stiffness_n_per_m: float = TOUCH_MAX_STIFFNESS_N_PER_M,
        max_damping_n_s_per_m: float = TOUCH_MAX_DAMPING_N_S_PER_M,
        fade_s: float = FADE_S,
        crossfade_min_s: float = CROSSFADE_MIN_S,
        crossfade_max_s: float = CROSSFADE_MAX_S,
        passivity_mass_kg: float | None = None,
        passivity_delay_ticks: int = PASSIVITY_DELAY_TICKS,
        use_damping: bool = True,
        friction_cone_floor: float = FRICTION_CONE_FLOOR,
        max_tick_s: float = MAX_TICK_S,
    ):
        for name, val in (
            ("max_force_n", max_force_n),
            ("max_stiffness_n_per_m", max_stiffness_n_per_m),
            ("max_damping_n_s_per_m", max_damping_n_s_per_m),
            ("friction_cone_floor", friction_cone_floor),
        ):
            if math.isnan(val) or val < 0:
                raise ValueError(f"{name} must be >= 0, got {val}")
        if not (fade_s > 0 and 0 < crossfade_min_s <= crossfade_max_s and max_tick_s > 0):
            raise ValueError("need fade_s > 0, 0 < crossfade_min_s <= crossfade_max_s and max_tick_s > 0")
        self.max_force_n = float(max_force_n)
        self.max_k = float(max_stiffness_n_per_m)
        self.max_d = float(max_damping_n_s_per_m)
        self.cone_floor = float(friction_cone_floor)
        self.max_tick_s = float(max_tick_s)
        self.fade_s = float(fade_s)
        self.cf_min, self.cf_max = float(crossfade_min_s), float(crossfade_max_s)
        self.use_damping = use_damping
        # the controller's damping acts delay_ticks late: a damper b delayed by tau on a mass m is stable for
        # b tau / m < pi / 2; the controller's bound m / dt becomes m / ((delay + 1) dt), b tau / m <= 0.83 at delay 2
        d = max(int(passivity_delay_ticks), 1)
        self.passivity = PassivityController(passivity_mass_kg / (d + 1)) if passivity_mass_kg else None
        self.counts = {"models": 0, "rejected_non_finite": 0, "rejected_out_of_order": 0, "fades_ttl": 0, "fades_radius": 0}
        self._model: _Slot | None = None
        self._from: _Slot | None = None
        self._offset = np.zeros(3)
        self._blend_t0: float | None = 0.0
        self._blend_T = 0.0
        self._fade_t0: float | None = 0.0  # start faded (from zero): the first model crossfades in
        self._fade_from = np.zeros(3)
        self._last_out = np.zeros(3)
        self._last_x: np.ndarray | None = None
        self._last_v: np.ndarray | None = None
        self._last_t: float | None = None  # stamp of the last tick with a finite pose (passivity's dt)
        self._stamp_last: float | None = None  # the last tick's stamp (s)
        self._s_last: float | None = None  # device time at the last tick: the stamps' forward steps summed (s)
        self._d_last: float | None = None  # the smooth clock of the crossfade and fade at the last tick (s)
        self._sent: deque = deque(
            [(np.zeros(3), np.zeros(3))] * max(int(passivity_delay_ticks), 1), maxlen=max(int(passivity_delay_ticks), 1)
        )
        self.state = "none"
        self.outside_reason: str | None = None  # why the last tick had no valid model: "ttl", "radius" or None

    # --- the device clock -------------------------------------------------------------------
    def _clocks(self, now_s: float) -> tuple[float, float]:
        """Device time and smooth clock at stamp ``now_s``: the last tick's plus the stamp's step, a step back
        counting 0 (a restarted driver: time goes on from its new stamps), the smooth one at most ``max_tick_s``."""
        if self._stamp_last is None:
            return now_s, now_s
        assert self._s_last is not None and self._d_last is not None  # set with _stamp_last, at every tick
        step = max(now_s - self._stamp_last, 0.0)
        return self._s_last + step, self._d_last + min(step, self.max_tick_s)

    # --- models -------------------------------------------------------------------------
    def model_age_s(self, now_s: float | None = None) -> float:
        """Age of the current model on the device clock at stamp ``now_s`` (default: the last tick), s; inf without one."""
        slot = self._model
        now = self._s_last if now_s is None else now_s
        if slot is None:
            return math.inf
        return 0.0 if slot.rx_s is None or now is None else now - slot.rx_s

    @property
    def model(self) -> LocalModel | None:
        """The current local contact model, or None before the first."""
        return self._model.m if self._model else None

    def bounded(self, m: LocalModel) -> tuple[np.ndarray, np.ndarray]:
        """The ``K`` and ``D`` this renderer evaluates for model ``m``: spectral norms capped at the device limits."""
        return cap_spectral_norm(m.stiffness_n_per_m, self.max_k), cap_spectral_norm(m.damping_n_s_per_m, self.max_d)

    def set_model(self, m: LocalModel, now_s: float | None = None) -> str | None:
        """Take a new model that arrived at device time ``now_s`` (default: the latest device tick).

        Returns None, or why it was dropped. A sequence number not above the current one is dropped (late or
        duplicate) unless the current model has expired, so a restarted node (sequence from 0 again) is followed.
        """
        if not m.finite:
            self.counts["rejected_non_finite"] += 1
            return "non-finite model"
        rx, smooth_now = (self._s_last, self._d_last) if now_s is None else self._clocks(float(now_s))
        cur = self._model
        age = rx - cur.rx_s if cur is not None and cur.rx_s is not None and rx is not None else 0.0
        if cur is not None and m.sequence <= cur.m.sequence and age <= cur.m.time_to_live_s:
            self.counts["rejected_out_of_order"] += 1
            return f"sequence {m.sequence} not after {cur.m.sequence}"
        n = np.asarray(m.normal, dtype=float)
        nn = float(np.linalg.norm(n))
        if nn <= 0:
            self.counts["rejected_non_finite"] += 1
            return "zero normal"
        if abs(nn - 1.0) > 1e-9:
            m = LocalModel(**{**m.__dict__, "normal": n / nn})
        fn0 = float(m.normal @ m.f0_n)
        ratio0 = float(np.linalg.norm(m.f0_n - fn0 * m.normal)) / fn0 if fn0 > 0 else 0.0
        K, D = self.bounded(m)
        slot = _Slot(m, rx, K, D, fn0, max(ratio0, self.cone_floor))
        # model to model: one servo tick (the models are linearisations of one force; a longer blend lags the new
        # one by half its length: at 250 Hz it made the rendered force worse than hold-last's, p99 7.6 against 4.8 %
        # of peak, at friction reversals the capped D cannot predict); from zero or a fade: cf_max
        blend = self.cf_min if cur is not None and self._fade_t0 is None else self.cf_max
        self._begin_blend(smooth_now, blend, keep_from=self._fade_t0 is None)
        self._model = slot
        self.counts["models"] += 1
        return None

    def _begin_blend(self, now_d: float | None, duration_s: float, keep_from: bool) -> None:
        """Crossfade from what is rendered now: the current model (plus the residue of any blend in progress)."""
        self._from = self._model if keep_from else None
        base = np.zeros(3)
        if self._from is not None and self._last_x is not None:
            base = self._from.force(self._last_x, self._last_v if self.use_damping else None)
        self._offset = self._last_out - base
        # the blend starts where that force was rendered, so the next tick already moves towards the new model
        d = self._d_last
        self._blend_t0 = d if d is not None and (now_d is None or d <= now_d) else now_d
        self._blend_T = duration_s
        self._fade_t0 = None

    # --- the servo tick -------------------------------------------------------------------
    def render(self, now_s: float, x, v=None, applied_over_dx=None) -> np.ndarray:
        """The force (N, tissue frame) to command for the coming servo tick at tool position ``x`` (m).

        ``now_s``: the device pose's stamp (s): the renderer's clock. ``v`` (m/s): the device's measured velocity;
        None differentiates the positions for the passivity controller and renders no ``D`` term. A non-finite
        ``x`` fades out like a stale model. ``applied_over_dx`` (N, tissue frame): the force the device reports it
        applied while moving from the previous ``x`` to this one (CRTK ``measured_cf``); the passivity observer
        books it exactly, else it assumes the force rendered ``passivity_delay_ticks`` ago.
        """
        now_s = float(now_s)
        if not math.isfinite(now_s):
            now_s = self._stamp_last if self._stamp_last is not None else 0.0
        raw, d = self._clocks(now_s)  # stamps going back do not turn time back
        x = np.asarray(x, dtype=float)
        v = None if v is None else np.asarray(v, dtype=float)
        finite_x = _finite(x) and (v is None or _finite(v))
        slot = self._model
        if slot is not None and slot.rx_s is None:  # arrived before the first device tick
            slot.rx_s = raw
        if self._blend_t0 is None:
            self._blend_t0 = d
        valid = False
        self.outside_reason = None
        if slot is not None and finite_x:
            assert slot.rx_s is not None  # set just above
            fresh = raw - slot.rx_s <= slot.m.time_to_live_s
            inside = float(np.linalg.norm(x - slot.m.x0_m)) <= slot.m.validity_radius_m
            valid = fresh and inside
            self.outside_reason = None if valid else ("ttl" if not fresh else "radius")
            if not valid and self._fade_t0 is None:
                self.counts["fades_ttl" if not fresh else "fades_radius"] += 1
        vd = v if self.use_damping else None
        pc_gain = 1.0  # the passivity controller acts on a rendered model only
        if valid:
            assert slot is not None  # valid: a fresh model under the tool
            if self._fade_t0 is not None:  # back inside / model fresh again after a fade: blend from the faded force
                self._begin_blend(d, self.cf_min if self._blend_T <= 0 else self._blend_T, keep_from=False)
            f = slot.force(x, vd)
            w = (d - self._blend_t0) / self._blend_T if self._blend_T > 0 else 1.0
            if w < 1.0:
                f_from = self._offset + (self._from.force(x, vd) if self._from is not None else 0.0)
                f = f_from + max(w, 0.0) * (f - f_from)
                self.state = "crossfade"
            else:
                self.state = "model"
        else:
            if self._fade_t0 is None:
                self._fade_t0, self._fade_from = d, self._last_out.copy()
            g = max(0.0, 1.0 - (d - self._fade_t0) / self.fade_s)
            f = g * self._fade_from
            pc_gain = 0.0  # the environment is being removed: the controller stands aside, the fade stays a ramp
            self.state = "fade" if slot is not None else "none"
        f = clamp_vec(f, self.max_force_n)
        if not _finite(f):  # cannot happen with finite models and x; never send it
            f = np.zeros(3)
        self._last_out = f
        applied = f
        if self.passivity is not None and finite_x:
            dt = raw - self._last_t if self._last_t is not None else 0.0
            if self._last_x is not None:
                dx = x - self._last_x
                if applied_over_dx is not None and _finite(applied_over_dx):  # the device said what it applied
                    applied_then = env_then = np.asarray(applied_over_dx, dtype=float)
                else:
                    applied_then, env_then = self._sent[0]  # the force that acted over dx (rendered delay ticks ago)
                self.passivity.observe(tuple(applied_then), tuple(env_then), tuple(dx))
                vel = v if v is not None else (dx / dt if dt > 0 else np.zeros(3))
            else:
                vel = np.zeros(3)
            damped = np.array(self.passivity.force(tuple(f), tuple(vel), dt))
            applied = clamp_vec(f + pc_gain * (damped - f), self.max_force_n)
            if slot is not None:  # the controller's damping may not pull the tool into the tissue either
                an = float(slot.m.normal @ applied)
                if an < 0.0:
                    applied = applied - an * slot.m.normal
            if pc_gain == 0.0:  # fading or nothing rendered: the energy account of that environment is closed
                self.passivity.reset()
        if finite_x:
            self._sent.append((applied, f))
            self._last_x, self._last_v, self._last_t = x, v, raw
        self._stamp_last, self._s_last, self._d_last = now_s, raw, d
        return applied


class HoldLastRenderer:
    """The baseline bridge: the last model's ``f0`` held until the next (what ``tool/wrench`` forwarding does).

    Same interface as :class:`ContactRenderer`; zero once the model is older than its time-to-live.
    """

    def __init__(self, max_force_n: float = math.inf):
        self.max_force_n = max_force_n
        self._m: LocalModel | None = None
        self._rx: float | None = None
        self._t: float | None = None  # the last tick's stamp
        self.state = "none"

    def set_model(self, m: LocalModel, now_s: float | None = None) -> str | None:
        """Hold ``m`` from ``now_s`` (default: the last tick's stamp); never drops one (returns None)."""
        self._m, self._rx = m, self._t if now_s is None else now_s
        return None

    def render(self, now_s: float, x, v=None, applied_over_dx=None) -> np.ndarray:
        """The held model's ``f0`` (clamped) while it is younger than its time-to-live, else zero; ``x``, ``v`` unused."""
        self._t = now_s
        if self._m is None:
            self.state = "none"
            return np.zeros(3)
        if self._rx is None:
            self._rx = now_s
        if now_s - self._rx > self._m.time_to_live_s:
            self.state = "fade"
            return np.zeros(3)
        self.state = "model"
        return clamp_vec(self._m.f0_n.copy(), self.max_force_n)
