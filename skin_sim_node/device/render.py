"""Render the node's local contact model at the device's servo rate (issue 12). Pure: no ROS.

The node answers a tool pose with a force and a local model of the contact around that pose
(:class:`msgs_schema.contact_model.LocalModel`). Between models the bridge computes the force from
the device's own pose every servo tick (Mark et al. 1996, "Adding force feedback to graphics
systems": plane-and-probe; sawSensablePhantom ``servo_ci``; SOFA ``LCPForceFeedback``)::

    F(x, v) = f0 + K (x - x0) + D (v - v0)

or, when the model carries the tissue's friction law (``friction_coefficient > 0``; issue 19), that law itself at the
device's own velocity (:func:`friction_law_force`)::

    F(x, v) = F_n(x) (n - mu v_t / sqrt(|v_t|^2 + v_r^2)) + (f0 - F_law(x0, v0)),   F_n(x) = F_n0 + grad(F_n) . (x - x0)

The linear form cannot follow the friction's reversal: the regularised Coulomb law flips sign over ``+-v_s`` (1 mm/s),
a slope ``mu F_n / v_s`` (hundreds of N s/m) that no damping cap passes; the law renders the flip at the device tick
where the device's velocity crosses zero, whatever the server's rate.

- one-sided along the contact normal: the tissue pushes, never pulls; the tangential part shrinks
  with the normal force when that drops below the model's (no step at separation);
- ``K`` and ``D`` capped (spectral norm, the largest gain in any direction) at the device's passive limits (the law's
  normal-force gradient so that its ``K`` meets the same cap), the tangential part inside the model's friction cone
  (:data:`FRICTION_CONE_FLOOR`), ``|F|`` at the device's force limit by scaling the vector;
- a crossfade from the force being rendered to each new model, over the interval between models;
- once the model is older than its time-to-live, or the tool leaves its validity radius, a linear
  fade of the last force to zero over ``fade_s``: never a step;
- optionally the time-domain passivity controller (:mod:`.passivity`) on the rendered force;
- with a needle law (:class:`msgs_schema.contact_model.NeedleLaw`, issue 22) the axial part follows the needle's
  piecewise law (:class:`NeedleRender`: the rupture ahead latched at the first tick that reaches it, the Dahl shaft
  friction integrated over the device's own moves) and the rest ``f0 + (I - u u^T) K (x - x0)``; the safety chain
  applies as :class:`NeedleRender` states;
- optionally the chatter guard (:data:`CHATTER_WINDOW_S`): while the device's tangential velocity keeps reversing
  (stick on a light stylus, or velocity noise), the velocity law's slope is capped at the stylus' stable damping; it
  acts on the legacy velocity law only (the presliding law has no slope in velocity).

Units: SI, tissue frame (the bridge maps the device pose in and the force out, see
:class:`skin_sim_node.device.bridge.DeviceMapping`). Times are seconds on the device's clock (its pose stamps;
:data:`MAX_TICK_S`).

Size (issue 28: over 500 lines, with a reason): one state machine (crossfade, TTL and radius fades, caps, passivity,
chatter guard) whose parts share its slots; the laws it evaluates are in :mod:`.laws`.
"""

from __future__ import annotations

import math
from collections import deque
from dataclasses import dataclass

import numpy as np

from msgs_schema.contact_model import STALE_RADIUS_M, LocalModel
from msgs_schema.tissue import FRICTION_COEFFICIENT

from .laws import NeedleRender, PreslidingRender, friction_law_force, presliding_update  # noqa: F401 (re-exported)
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

TOUCH_POSITION_RESOLUTION_M = 0.055e-3
"""Nominal position resolution of a Touch (m): 3D Systems' specification, > 450 dpi (about 0.055 mm)."""

VELOCITY_ESTIMATE_WINDOW_S = 0.0
"""Window of the renderer's own velocity estimate for the friction law (s); 0 (the default): none. The law needs the
device's velocity (CRTK ``measured_cv``); without it the renderer renders the linear form ``f0 + K dx`` (the friction
the server computed at ``v0``, as before issue 19's law). Why no estimate by default: the law flips over ``+-v_s``
(1 mm/s), a slope ``mu F_n / v_s`` of hundreds of N s/m, so it needs a velocity that is both fresh and quiet, and a
pose difference is neither. A one-tick difference of a Touch's encoder counts moves by
:data:`TOUCH_POSITION_RESOLUTION_M` / 1 ms = 55 mm/s per count (the law would flip its full ``mu F_n`` on every
count: a chatter); a longer window lags by half its length. Offline, on the bench-device drag at 250 Hz with exact
positions (no counts), a 2/5/10 ms window gave p99 1.4/4.2/9.2 % of peak against hold-last's 4.8 %; regularised at
one count per window (``slip_speed_floor_m_s``, as a Touch would need) 37/31/26 % (``skin-sim force-path
--device-drag``, issue 19 closing note). A device that reports no velocity is better served by the linear form."""

SERVO_PERIOD_S = 1e-3
"""The device's servo period the bridge's chatter guard and passivity controller assume (s): a Touch's OpenHaptics
servo loop runs at 1 kHz. The controller's tick is never shorter (stamps closer than it are a driver's publish
jitter, not a shorter tick)."""

CHATTER_WINDOW_S = 0.01
"""The chatter guard's window (s): :data:`CHATTER_FLIPS` reversals of the device's tangential velocity within 10 ms
is not a stroke (a hand reverses a few times a second; the bench drag once a second) but the stick limit cycle of a
steep friction law on a light stylus, a tick or two late (a period of 4-6 ms, measured closed-loop in ``skin-sim
force-path --device-drag``), or velocity noise near rest. Either way the law's sign is not the motion's."""

CHATTER_FLIPS = 2
"""Reversals within :data:`CHATTER_WINDOW_S` that engage the guard (a stroke's own reversal is one)."""

CHATTER_HOLD_S = 0.1
"""How long the guard holds after the last reversal (s): it stays on through a stick (where the velocity keeps
crossing zero) and lets go once the device slides one way for 100 ms. Closed-loop drag (``skin-sim force-path
--device-drag``, with :data:`CHATTER_RELEASE_S`): 2 reversals and 100 ms left 4 friction sign flips over the slide,
2 and 50 ms 8, 3 and 50 ms 12, 2 and 200 ms 4 (with less friction), none of them changing the offline bench drag's
render error."""


CHATTER_RELEASE_S = 0.02
"""After the hold the guard lets go over this long (s): the regularisation ``mu F_n / cap`` falls linearly to the
model's ``v_s``, so the friction returns to the law's without a step (at once it rose by up to a third of ``mu F_n``
in one tick at a 10 mm/s slide)."""


def stable_damping_n_s_per_m(mass_kg: float, period_s: float, delay_ticks: int = 2) -> float:
    """The largest damping ``B`` a sampled device of mass ``mass_kg`` renders stably when the force acts
    ``delay_ticks`` periods late: ``v_{k+1} = v_k - (B T / m) v_{k-d}`` is stable for ``B T / m < 2 sin(pi / (2 (2d + 1)))``
    (2 without delay, 1 for one tick, 0.618 for two: the bridge's :data:`PASSIVITY_DELAY_TICKS`). 27.8 N s/m for a
    45 g Touch stylus at 1 kHz, two ticks late."""
    d = max(int(delay_ticks), 0)
    return 2.0 * math.sin(math.pi / (2 * (2 * d + 1))) * mass_kg / period_s


STATES = ("none", "model", "crossfade", "fade")


def _finite(v) -> bool:
    if len(v) == 3:  # the servo tick's vectors: plain floats, no NumPy call (a few microseconds each, issue 27)
        return math.isfinite(v[0]) and math.isfinite(v[1]) and math.isfinite(v[2])
    return bool(np.isfinite(v).all())


def _norm3(v) -> float:
    """|v| of a 3-vector without a NumPy call (``np.linalg.norm`` costs microseconds per servo tick)."""
    return math.sqrt(v[0] * v[0] + v[1] * v[1] + v[2] * v[2])


@dataclass
class _Slot:
    """A model ready to evaluate: bounded matrices, the normal force at x0 and the friction cone.

    ``rx_s``: arrival on the device clock (pose stamps, s); None until the first device tick. With a friction law
    (``law``): ``grad`` is the normal force's gradient capped as ``K`` is, ``residual`` what ``f0`` holds beyond the
    law at ``x0``, ``v0`` (zero from skin_sim_node's session, float rounding aside) and ``slip`` the regularisation
    speed the renderer evaluates the law with.
    """

    m: LocalModel
    rx_s: float | None
    K: np.ndarray
    D: np.ndarray
    fn0: float
    cone: float
    law: bool = False
    grad: np.ndarray | None = None
    residual: np.ndarray | None = None
    slip: float = 0.0
    needle: NeedleRender | None = None
    presliding: PreslidingRender | None = None

    def force(
        self, x: np.ndarray, v: np.ndarray | None, v_law: np.ndarray | None = None, stick_slope: float = math.inf
    ) -> np.ndarray:
        """The model's force at ``x``, ``v``, one-sided along the normal and inside the model's friction cone.

        The friction law at velocity ``v_law`` (default ``v``; :func:`friction_law_force`, regularised at ``slip``, and
        at least at ``mu F_n0 / stick_slope``: the chatter guard's slope cap) when the model carries one and a velocity
        is known, else
        ``f0 + K (x - x0) + D (v - v0)`` (without ``v``: no ``D`` term).
        """
        m = self.m
        n = m.normal
        if self.needle is not None:
            return self.needle.force(m, self.K, self.D, x, v)
        if self.presliding is not None:  # a law of positions: neither v nor the chatter guard's cap enters
            f = self.presliding.force(m, x)
            fn = float(n @ f)
            if fn <= 0.0:
                return np.zeros(3)
            t = f - fn * n
            t_n = _norm3(t)
            if t_n > self.cone * fn:
                t = t * (self.cone * fn / t_n)
            return fn * n + t
        if v_law is None:
            v_law = v
        if self.law and v_law is not None:
            assert self.grad is not None and self.residual is not None  # set with law
            fn = m.normal_force_n + float(self.grad @ (x - m.x0_m))
            if fn <= 0.0:
                return np.zeros(3)
            slip = self.slip
            if stick_slope < math.inf:
                slip = max(slip, m.friction_coefficient * max(m.normal_force_n, 0.0) / stick_slope)
            f = friction_law_force(n, fn, m.friction_coefficient, slip, v_law)
            if m.normal_force_n > 0.0:  # f0's part beyond the law, shrinking with the normal force as friction does
                f = f + self.residual * min(fn / m.normal_force_n, 1.0)
            fn = float(n @ f)
            if fn <= 0.0:
                return np.zeros(3)
            t = f - fn * n
            t_n = _norm3(t)
            if t_n > self.cone * fn:
                t = t * (self.cone * fn / t_n)
            return fn * n + t
        f = m.f0_n + self.K @ (x - m.x0_m)
        if v is not None:
            f = f + self.D @ (v - m.v0_m_s)
        fn = float(n @ f)
        if fn <= 0.0 or self.fn0 <= 0.0:
            return np.zeros(3) if fn <= 0.0 else fn * n
        t = f - fn * n
        if fn < self.fn0:
            t = t * (fn / self.fn0)
        t_n = _norm3(t)
        if t_n > self.cone * fn:  # K or D asked for more friction than the tissue model can give: not amplified
            t = t * (self.cone * fn / t_n)
        return fn * n + t


COUPLING_MIN_AGE_S = 1e-3
"""The coupling rate is rendered for at least this long (s) when the node answers every pose (``answer_period_s`` 0):
one servo period of a 1 kHz device, about the age of a model answering the device's last pose."""


def coupled(slot: _Slot, f: np.ndarray, now_s: float) -> np.ndarray:
    """``f`` plus the other hands' first-order change of this force since the model answered (issue 32): its
    ``coupling_rate_n_per_s`` times the model's age on the stamps, at most one announced server period
    (``answer_period_s``, at least :data:`COUPLING_MIN_AGE_S`: the node's next model carries the real change), one-sided
    along the normal for a punch.

    Parameters
    ----------
    slot : _Slot
        The model rendered.
    f : ndarray, shape (3,)
        Its force at the device's pose (N).
    now_s : float
        The device pose's stamp (s), on the clock of the model's stamp.

    Returns
    -------
    ndarray, shape (3,)
    """
    m = slot.m
    c = m.coupling_rate_n_per_s
    if not (c[0] or c[1] or c[2]):
        return f
    age = min(max(now_s - m.stamp_ns * 1e-9, 0.0), max(m.answer_period_s, COUPLING_MIN_AGE_S))
    g = f + age * c
    if slot.needle is None and float(m.normal @ g) <= 0.0:  # a punch's tissue never pulls
        return np.zeros(3)
    return g


def cap_spectral_norm(A: np.ndarray, limit: float) -> np.ndarray:
    """``A`` scaled down as a whole so that its spectral norm (its largest gain, in any direction) is at most
    ``limit``; its direction structure is kept."""
    if float(np.sqrt(np.sum(A * A))) <= limit:  # the Frobenius norm bounds the spectral one: no SVD needed
        return A.copy()
    s = float(np.linalg.norm(A, 2))
    return A * (limit / s) if s > limit else A.copy()


def clamp_vec(f: np.ndarray, max_n: float) -> np.ndarray:
    """``f`` scaled down as a vector to magnitude ``max_n`` if longer (direction kept, never per axis)."""
    mag = _norm3(f)
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
    friction_law : bool
        Evaluate a model's friction law (``friction_coefficient > 0``): the presliding law at the device's positions,
        the legacy velocity law at its velocity; False: render every model's linear form ``f0 + K dx + D dv``
        (``D`` capped).
    slip_speed_floor_m_s : float
        Least regularisation speed of the rendered friction law (m/s): raise it above the model's ``v_s`` for a
        device whose measured velocity is noisier than that near rest (the law's sign would follow the noise). 0: the
        model's own ``v_s``.
    max_friction_slope_n_s_per_m : float
        Cap of the rendered friction law's steepest slope ``mu F_n / v_r`` (N s/m, at ``v_t = 0``): the law is
        regularised at ``v_r >= mu F_n0 / cap``. ``inf`` (default): the model's own law (see ``docs/devices.md``, "The
        friction law at the device", for the closed-loop stick chatter this trades against the render error).
    stick_slope_n_s_per_m : float
        The chatter guard (:data:`CHATTER_WINDOW_S`): while the device's tangential velocity keeps reversing, the law's
        slope at zero slip is capped at this (N s/m); ``inf``: no guard. The bridge sets
        :func:`stable_damping_n_s_per_m` of the device's mass at 1 kHz.
    velocity_estimate_window_s : float
        The friction law's velocity when :meth:`render` gets none: the pose difference over this window (s); 0: no
        estimate, the linear form (:data:`VELOCITY_ESTIMATE_WINDOW_S`).

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
        friction_law: bool = True,
        slip_speed_floor_m_s: float = 0.0,
        max_friction_slope_n_s_per_m: float = math.inf,
        stick_slope_n_s_per_m: float = math.inf,
        velocity_estimate_window_s: float = VELOCITY_ESTIMATE_WINDOW_S,
    ):
        for name, val in (
            ("max_force_n", max_force_n),
            ("max_stiffness_n_per_m", max_stiffness_n_per_m),
            ("max_damping_n_s_per_m", max_damping_n_s_per_m),
            ("friction_cone_floor", friction_cone_floor),
            ("slip_speed_floor_m_s", slip_speed_floor_m_s),
            ("max_friction_slope_n_s_per_m", max_friction_slope_n_s_per_m),
            ("stick_slope_n_s_per_m", stick_slope_n_s_per_m),
            ("velocity_estimate_window_s", velocity_estimate_window_s),
        ):
            if math.isnan(val) or val < 0:
                raise ValueError(f"{name} must be >= 0, got {val}")
        if not (fade_s > 0 and 0 < crossfade_min_s <= crossfade_max_s and max_tick_s > 0):
            raise ValueError("need fade_s > 0, 0 < crossfade_min_s <= crossfade_max_s and max_tick_s > 0")
        self.friction_law = bool(friction_law)
        self.slip_floor = float(slip_speed_floor_m_s)
        self.max_slope = float(max_friction_slope_n_s_per_m)
        self.stick_slope = float(stick_slope_n_s_per_m)
        self._flips: deque = deque(maxlen=CHATTER_FLIPS)  # device times of the last tangential reversals
        self._vt_last: np.ndarray | None = None
        self._guard_until = -math.inf  # device time until which the chatter guard holds
        self.counts_chatter = 0  # times the guard engaged
        self.counts_clamped = 0  # ticks whose force was scaled down to max_force_n (the peak flattened)
        self.velocity_window_s = float(velocity_estimate_window_s)
        self._poses: deque = deque(maxlen=256)  # (device time, x) of the recent finite poses: the velocity estimate
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
        self._last_law_v: np.ndarray | None = None  # the friction law's velocity at the last tick
        self._last_stick = math.inf  # the chatter guard's slope cap at the last tick
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
    def presliding(self) -> PreslidingRender | None:
        """The current model's presliding friction and its anchor, or None."""
        return self._model.presliding if self._model else None

    @property
    def needle(self) -> NeedleRender | None:
        """The current model's needle law and its state (latch, Dahl ``z``), or None."""
        return self._model.needle if self._model else None

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
        if m.needle is not None:  # the needle law: its own state per model (Dahl from friction_state, no latch)
            slot = _Slot(m, rx, K, D, fn0, 0.0, needle=NeedleRender(m.needle, self.max_k, m.validity_radius_m))
        elif self.friction_law and m.friction_coefficient > 0.0 and m.tangential_stiffness_n_per_m > 0.0:
            # the presliding law (issue 30): its own anchor per model, from the model's; |F_t| <= mu F_n by the law
            slot = _Slot(m, rx, K, D, fn0, max(ratio0, m.friction_coefficient), presliding=PreslidingRender(m, self.max_k))
        elif self.friction_law and m.friction_coefficient > 0.0:
            mu = m.friction_coefficient
            # the law's K at any velocity is (n - mu g) grad^T, of spectral norm <= sqrt(1 + mu^2) |grad|: capped so
            g = m.normal_force_gradient_n_per_m
            gain = float(np.linalg.norm(g)) * math.sqrt(1.0 + mu * mu)
            grad = g * (self.max_k / gain) if gain > self.max_k else g.copy()
            residual = m.f0_n - friction_law_force(m.normal, m.normal_force_n, mu, m.slip_speed_m_s, m.v0_m_s)
            # the law's steepest slope, mu F_n / v_r at v_t = 0, at most max_slope: v_r >= mu F_n0 / max_slope
            slip = max(m.slip_speed_m_s, self.slip_floor, mu * max(m.normal_force_n, 0.0) / self.max_slope)
            slot = _Slot(m, rx, K, D, fn0, max(ratio0, mu), True, grad, residual, slip)
        else:
            slot = _Slot(m, rx, K, D, fn0, max(ratio0, self.cone_floor))
        # model to model: one servo tick (the models are linearisations of one force; a longer blend lags the new
        # one by half its length: at 250 Hz it made the rendered force worse than hold-last's, p99 7.6 against 4.8 %
        # of peak, at friction reversals the capped D cannot predict); from zero or a fade: cf_max; into and out of the
        # node's stale zero model too (issue 31: the node's watchdog fired, or poses resumed after a stall): the force
        # fades out and back in over cf_max, never a step at the hand
        stale_edge = m.validity_radius_m >= STALE_RADIUS_M or (cur is not None and cur.m.validity_radius_m >= STALE_RADIUS_M)
        blend = self.cf_min if cur is not None and self._fade_t0 is None and not stale_edge else self.cf_max
        self._begin_blend(smooth_now, blend, keep_from=self._fade_t0 is None)
        self._model = slot
        self.counts["models"] += 1
        return None

    def _begin_blend(self, now_d: float | None, duration_s: float, keep_from: bool) -> None:
        """Crossfade from what is rendered now: the current model (plus the residue of any blend in progress)."""
        self._from = self._model if keep_from else None
        base = np.zeros(3)
        if self._from is not None and self._last_x is not None:
            base = self._from.force(self._last_x, self._last_v if self.use_damping else None, self._last_law_v, self._last_stick)
        self._offset = self._last_out - base
        # the blend starts where that force was rendered, so the next tick already moves towards the new model
        d = self._d_last
        self._blend_t0 = d if d is not None and (now_d is None or d <= now_d) else now_d
        self._blend_T = duration_s
        self._fade_t0 = None

    def _chatter_guard(self, now: float, v: np.ndarray | None, slot: _Slot | None) -> float:
        """The slope cap of this tick: :attr:`stick_slope` while the guard holds (:data:`CHATTER_WINDOW_S`), else inf."""
        if v is not None and slot is not None and slot.law:
            n = slot.m.normal
            vt = v - float(n @ v) * n
            if self._vt_last is not None and float(vt @ self._vt_last) < 0.0:
                self._flips.append(now)
                if len(self._flips) == CHATTER_FLIPS and now - self._flips[0] <= CHATTER_WINDOW_S:
                    if now > self._guard_until:
                        self.counts_chatter += 1
                    self._guard_until = now + CHATTER_HOLD_S
                elif now <= self._guard_until:  # a reversal while held (stick): hold on
                    self._guard_until = now + CHATTER_HOLD_S
            self._vt_last = vt
        if now <= self._guard_until:
            return self.stick_slope
        u = (now - self._guard_until) / CHATTER_RELEASE_S  # let go gradually: v_r falls linearly to the model's
        return self.stick_slope / (1.0 - u) if u < 1.0 else math.inf

    def _estimate_velocity(self, now: float, x: np.ndarray) -> np.ndarray | None:
        """Pose difference over the oldest recent pose within :attr:`velocity_window_s` of device time (m/s); None
        without an earlier pose. A pose gap longer than the window: the difference over the gap (the last pose)."""
        ref = None
        for t, xp in reversed(self._poses):
            if now - t > self.velocity_window_s and ref is not None:
                break
            ref = (t, xp)
        if ref is None or not now > ref[0]:
            return None
        return (x - ref[1]) / (now - ref[0])

    # --- the servo tick -------------------------------------------------------------------
    def render(self, now_s: float, x, v=None, applied_over_dx=None) -> np.ndarray:
        """The force (N, tissue frame) to command for the coming servo tick at tool position ``x`` (m).

        ``now_s``: the device pose's stamp (s): the renderer's clock. ``v`` (m/s): the device's measured velocity;
        None differentiates the positions for the passivity controller and the friction law (over
        ``velocity_window_s``) and renders no ``D`` term. A non-finite
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
            x0 = slot.m.x0_m
            inside = _norm3((x[0] - x0[0], x[1] - x0[1], x[2] - x0[2])) <= slot.m.validity_radius_m
            valid = fresh and inside
            self.outside_reason = None if valid else ("ttl" if not fresh else "radius")
            if not valid and self._fade_t0 is None:
                self.counts["fades_ttl" if not fresh else "fades_radius"] += 1
        vd = v if self.use_damping else None
        # the friction law's velocity: the device's, else (opt-in) the renderer's estimate from the poses; None: the
        # linear form (VELOCITY_ESTIMATE_WINDOW_S); use_damping False renders no velocity term at all
        vl = vd
        if v is None and finite_x and self.use_damping and self.velocity_window_s > 0:
            vl = self._estimate_velocity(raw, x)
        if finite_x and self.velocity_window_s > 0:  # kept only for the estimate: no per-tick allocation otherwise
            self._poses.append((raw, x))
        stick = self._chatter_guard(raw, vl, slot) if self.stick_slope < math.inf else math.inf
        pc_gain = 1.0  # the passivity controller acts on a rendered model only
        if valid:
            assert slot is not None  # valid: a fresh model under the tool
            if self._fade_t0 is not None:  # back inside / model fresh again after a fade: blend from the faded force
                self._begin_blend(d, self.cf_min if self._blend_T <= 0 else self._blend_T, keep_from=False)
            f = coupled(slot, slot.force(x, vd, vl, stick), now_s)
            w = (d - self._blend_t0) / self._blend_T if self._blend_T > 0 else 1.0
            if w < 1.0:
                f_from = self._offset + (self._from.force(x, vd, vl, stick) if self._from is not None else 0.0)
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
        if _norm3(f) > self.max_force_n:
            self.counts_clamped += 1
        f = clamp_vec(f, self.max_force_n)
        if not _finite(f):  # cannot happen with finite models and x; never send it
            f = np.zeros(3)
        self._last_out = f
        applied = f
        if self.passivity is not None and finite_x:
            dt = raw - self._last_t if self._last_t is not None else 0.0
            # the controller's tick is the device's servo period, not the stamps' difference (Hannaford & Ryu's
            # sampling period): a driver's stamp is its publish time, and after a late slot the next pose came 0.14 ms
            # after it while its position had moved a whole period's worth (13 um at 13 mm/s); dx / 0.14 ms and the
            # bound mass / 0.14 ms rendered a 9.4 N damping spike, the device's 3.3 N for one tick (bench-device,
            # 2026-12-06). A longer interval (a gap) is kept: it only lowers the bound
            dt = max(dt, SERVO_PERIOD_S) if dt > 0.0 else 0.0
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
            if slot is not None and slot.needle is None:  # its damping may not pull the tool into the tissue either
                an = float(slot.m.normal @ applied)
                if an < 0.0:
                    applied = applied - an * slot.m.normal
            if pc_gain == 0.0:  # fading or nothing rendered: the energy account of that environment is closed
                self.passivity.reset()
        if finite_x:
            self._sent.append((applied, f))
            self._last_x, self._last_v, self._last_t = x, v, raw
            self._last_law_v, self._last_stick = vl, stick
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
