"""Render the node's local contact model at the device's servo rate (issue 12). Pure: no ROS.

The node answers a tool pose with a force and a local model of the contact around that pose
(:class:`msgs_schema.contact_model.LocalModel`). Between models the bridge computes the force from
the device's own pose every servo tick (Mark et al. 1996, "Adding force feedback to graphics
systems": plane-and-probe; sawSensablePhantom ``servo_ci``; SOFA ``LCPForceFeedback``)::

    F(x, v) = f0 + K (x - x0) + D (v - v0)

- one-sided along the contact normal: the tissue pushes, never pulls; the tangential part shrinks
  with the normal force when that drops below the model's (no step at separation);
- ``K`` and ``D`` capped (spectral norm) at the device's passive limits, ``|F|`` at its force limit;
- a crossfade from the force being rendered to each new model, over the interval between models;
- once the model is older than its time-to-live, or the tool leaves its validity radius, a linear
  fade of the last force to zero over ``fade_s``: never a step;
- optionally the time-domain passivity controller (:mod:`.passivity`) on the rendered force.

Units: SI, tissue frame (the bridge maps the device pose in and the force out, see
:class:`skin_sim_node.device.bridge.DeviceMapping`). Times are seconds on the renderer's clock.
"""

from __future__ import annotations

import math
from collections import deque
from dataclasses import dataclass

import numpy as np

from msgs_schema.contact_model import LocalModel

from .mapping import TOUCH_MAX_STIFFNESS_N_PER_M, TOUCH_PEAK_FORCE_N
from .passivity import PassivityController

FADE_S = 0.05
"""Fade to zero when the model is stale or left (s): issue 12 asks ~50 ms, about a hand's reflex latency
(short enough to stop a stale push, long enough that the user feels no step)."""

CROSSFADE_MIN_S = 1e-3
"""Shortest crossfade (s): one servo period of a 1 kHz device; a shorter one is a step at the tick."""

CROSSFADE_MAX_S = 0.02
"""Longest crossfade (s): two periods of the slowest server rate of the rate lever (100 Hz); models further
apart than that are not spread out further (the crossfade lags the model by half its length)."""

PASSIVITY_DELAY_TICKS = 2
"""Ticks from the bridge rendering a force (at device pose ``k``) to the device applying it: the command reaches
the device before its next tick (DDS on one host: well under 1 ms) and a servo loop applies a command from the
tick after it arrives (zero-order hold, as :class:`skin_sim_node.device.stylus.SimulatedDevice`): it acts over
the displacement from pose ``k + 1`` to ``k + 2``. The passivity observer (Hannaford & Ryu 2002) must book that
displacement against that force, or it misses the energy the delayed loop generates."""

STATES = ("none", "model", "crossfade", "fade")


@dataclass
class _Slot:
    """A model ready to evaluate: capped matrices and the normal force at x0."""

    m: LocalModel
    rx_s: float
    K: np.ndarray
    D: np.ndarray
    fn0: float

    def force(self, x: np.ndarray, v: np.ndarray | None) -> np.ndarray:
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
        return fn * n + t


def _cap_norm(A: np.ndarray, limit: float) -> np.ndarray:
    """``A`` scaled down so that its spectral norm is at most ``limit`` (direction structure kept)."""
    s = float(np.linalg.norm(A, 2))
    return A * (limit / s) if s > limit else A.copy()


def clamp_vec(f: np.ndarray, max_n: float) -> np.ndarray:
    mag = float(np.linalg.norm(f))
    return f * (max_n / mag) if mag > max_n else f


class ContactRenderer:
    """Servo-rate force from local contact models (see the module docstring).

    Parameters
    ----------
    max_force_n : float
        Force magnitude limit (N), tissue units.
    max_stiffness_n_per_m, max_damping_n_s_per_m : float
        Spectral-norm caps of ``K`` and ``D`` (N/m, N s/m), tissue units; ``inf``: uncapped.
    fade_s : float
        Fade time to zero after the model goes stale or the tool leaves it (s).
    crossfade_min_s, crossfade_max_s : float
        Bounds of the crossfade to a new model (its length is the interval since the previous model).
    passivity_mass_kg : float or None
        Apparent device mass for the passivity controller (tissue units); None: no controller.
    passivity_delay_ticks : int
        Device ticks from rendering a force to the start of the tick over which the device applies it
        (:data:`PASSIVITY_DELAY_TICKS`); the passivity observer books each displacement against that force.
    use_damping : bool
        Render ``D (v - v0)`` when a velocity is given.

    Attributes
    ----------
    state : str
        ``none`` (no model yet), ``model``, ``crossfade`` or ``fade`` (stale/left model, or fading after it).
    counts : dict
        ``models`` accepted, ``rejected_non_finite``, ``rejected_out_of_order``, ``fades_ttl``, ``fades_radius``.
    """

    def __init__(
        self,
        max_force_n: float = TOUCH_PEAK_FORCE_N,
        max_stiffness_n_per_m: float = TOUCH_MAX_STIFFNESS_N_PER_M,
        max_damping_n_s_per_m: float = math.inf,
        fade_s: float = FADE_S,
        crossfade_min_s: float = CROSSFADE_MIN_S,
        crossfade_max_s: float = CROSSFADE_MAX_S,
        passivity_mass_kg: float | None = None,
        passivity_delay_ticks: int = PASSIVITY_DELAY_TICKS,
        use_damping: bool = True,
    ):
        for name, val in (("max_force_n", max_force_n), ("max_stiffness_n_per_m", max_stiffness_n_per_m),
                          ("max_damping_n_s_per_m", max_damping_n_s_per_m)):  # fmt: skip
            if math.isnan(val) or val < 0:
                raise ValueError(f"{name} must be >= 0, got {val}")
        if not (fade_s > 0 and 0 < crossfade_min_s <= crossfade_max_s):
            raise ValueError("need fade_s > 0 and 0 < crossfade_min_s <= crossfade_max_s")
        self.max_force_n = float(max_force_n)
        self.max_k = float(max_stiffness_n_per_m)
        self.max_d = float(max_damping_n_s_per_m)
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
        self._blend_t0 = 0.0
        self._blend_T = 0.0
        self._fade_t0: float | None = 0.0  # start faded (from zero): the first model crossfades in
        self._fade_from = np.zeros(3)
        self._last_out = np.zeros(3)
        self._last_x: np.ndarray | None = None
        self._last_v: np.ndarray | None = None
        self._last_t: float | None = None
        self._sent: deque = deque(
            [(np.zeros(3), np.zeros(3))] * max(int(passivity_delay_ticks), 1), maxlen=max(int(passivity_delay_ticks), 1)
        )
        self.state = "none"
        self.outside_reason: str | None = None  # why the last tick had no valid model: "ttl", "radius" or None

    # --- models -------------------------------------------------------------------------
    def model_age_s(self, now_s: float) -> float:
        """Age of the current model on this clock (s); inf without one."""
        return now_s - self._model.rx_s if self._model else math.inf

    @property
    def model(self) -> LocalModel | None:
        return self._model.m if self._model else None

    def set_model(self, m: LocalModel, now_s: float) -> str | None:
        """Take a new model that arrived at ``now_s``. Returns None, or why it was dropped.

        A sequence number not above the current one is dropped (late or duplicate) unless the
        current model has expired, so a restarted node (sequence from 0 again) is followed.
        """
        if not m.finite:
            self.counts["rejected_non_finite"] += 1
            return "non-finite model"
        cur = self._model
        if cur is not None and m.sequence <= cur.m.sequence and now_s - cur.rx_s <= cur.m.time_to_live_s:
            self.counts["rejected_out_of_order"] += 1
            return f"sequence {m.sequence} not after {cur.m.sequence}"
        n = np.asarray(m.normal, dtype=float)
        nn = float(np.linalg.norm(n))
        if nn <= 0:
            self.counts["rejected_non_finite"] += 1
            return "zero normal"
        if abs(nn - 1.0) > 1e-9:
            m = LocalModel(**{**m.__dict__, "normal": n / nn})
        slot = _Slot(m, now_s, _cap_norm(m.stiffness_n_per_m, self.max_k), _cap_norm(m.damping_n_s_per_m, self.max_d),
                     float(m.normal @ m.f0_n))  # fmt: skip
        interval = now_s - cur.rx_s if cur is not None else self.cf_max
        self._begin_blend(now_s, min(max(interval, self.cf_min), self.cf_max), keep_from=self._fade_t0 is None)
        self._model = slot
        self.counts["models"] += 1
        return None

    def _begin_blend(self, now_s: float, duration_s: float, keep_from: bool) -> None:
        """Crossfade from what is rendered now: the current model (plus the residue of any blend in progress)."""
        self._from = self._model if keep_from else None
        base = np.zeros(3)
        if self._from is not None and self._last_x is not None:
            base = self._from.force(self._last_x, self._last_v if self.use_damping else None)
        self._offset = self._last_out - base
        # the blend starts where that force was rendered, so the next tick already moves towards the new model
        t0 = self._last_t if self._last_t is not None and self._last_t <= now_s else now_s
        self._blend_t0, self._blend_T = t0, duration_s
        self._fade_t0 = None

    # --- the servo tick -------------------------------------------------------------------
    def render(self, now_s: float, x, v=None, applied_over_dx=None) -> np.ndarray:
        """The force (N, tissue frame) to command for the coming servo tick at tool position ``x`` (m).

        ``v`` (m/s): the device's measured velocity; None differentiates the positions for the
        passivity controller and renders no ``D`` term. A non-finite ``x`` fades out like a stale model.
        ``applied_over_dx`` (N, tissue frame): the force the device reports it applied while moving from the
        previous ``x`` to this one (CRTK ``measured_cf``); the passivity observer books it exactly, else it
        assumes the force rendered ``passivity_delay_ticks`` ago.
        """
        x = np.asarray(x, dtype=float)
        v = None if v is None else np.asarray(v, dtype=float)
        finite_x = bool(np.isfinite(x).all()) and (v is None or bool(np.isfinite(v).all()))
        slot = self._model
        valid = False
        self.outside_reason = None
        if slot is not None and finite_x:
            fresh = now_s - slot.rx_s <= slot.m.time_to_live_s
            inside = float(np.linalg.norm(x - slot.m.x0_m)) <= slot.m.validity_radius_m
            valid = fresh and inside
            self.outside_reason = None if valid else ("ttl" if not fresh else "radius")
            if not valid and self._fade_t0 is None:
                self.counts["fades_ttl" if not fresh else "fades_radius"] += 1
        vd = v if self.use_damping else None
        pc_gain = 1.0  # the passivity controller acts on a rendered model only
        if valid:
            if self._fade_t0 is not None:  # back inside / model fresh again after a fade: blend from the faded force
                self._begin_blend(now_s, self.cf_min if self._blend_T <= 0 else self._blend_T, keep_from=False)
            f = slot.force(x, vd)
            w = (now_s - self._blend_t0) / self._blend_T if self._blend_T > 0 else 1.0
            if w < 1.0:
                f_from = self._offset + (self._from.force(x, vd) if self._from is not None else 0.0)
                f = f_from + max(w, 0.0) * (f - f_from)
                self.state = "crossfade"
            else:
                self.state = "model"
        else:
            if self._fade_t0 is None:
                self._fade_t0, self._fade_from = now_s, self._last_out.copy()
            g = max(0.0, 1.0 - (now_s - self._fade_t0) / self.fade_s)
            f = g * self._fade_from
            pc_gain = 0.0  # the environment is being removed: the controller stands aside, the fade stays a ramp
            self.state = "fade" if slot is not None else "none"
        f = clamp_vec(f, self.max_force_n)
        if not np.isfinite(f).all():  # cannot happen with finite models and x; never send it
            f = np.zeros(3)
        self._last_out = f
        applied = f
        if self.passivity is not None and finite_x:
            dt = now_s - self._last_t if self._last_t is not None else 0.0
            if self._last_x is not None:
                dx = x - self._last_x
                if applied_over_dx is not None and np.isfinite(applied_over_dx).all():  # the device said what it applied
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
        if finite_x:
            self._last_x, self._last_v, self._last_t = x, v, now_s
        return applied


class HoldLastRenderer:
    """The baseline bridge: the last model's ``f0`` held until the next (what ``tool/wrench`` forwarding does).

    Same interface as :class:`ContactRenderer`; zero once the model is older than its time-to-live.
    """

    def __init__(self, max_force_n: float = math.inf):
        self.max_force_n = max_force_n
        self._m: LocalModel | None = None
        self._rx = 0.0
        self.state = "none"

    def set_model(self, m: LocalModel, now_s: float) -> str | None:
        self._m, self._rx = m, now_s
        return None

    def render(self, now_s: float, x, v=None, applied_over_dx=None) -> np.ndarray:
        if self._m is None or now_s - self._rx > self._m.time_to_live_s:
            self.state = "none" if self._m is None else "fade"
            return np.zeros(3)
        self.state = "model"
        return clamp_vec(self._m.f0_n.copy(), self.max_force_n)
