"""A simulated Phantom / Geomagic Touch, so the haptic loop closes headless.

The stylus is a point mass pulled by a hand impedance (spring + damper) towards a
scripted hand path (a :data:`skin_sim_node.device.trajectories.TRAJECTORIES` entry), pushed by the
commanded device force (zero-order hold, applied one tick late, saturated at the
Touch's peak force) and slowed by a small device damping.

Device frame: the same axes as the tissue frame, origin at tissue ``(0, 0, +0.05)`` m,
i.e. ``p_tissue = p_device + (0, 0, 0.05)``; this is the default
:class:`skin_sim_node.device.bridge.DeviceMapping`, so the default bridge needs no options.
Positions are reported in the device frame (frame_id ``device_base``).

Pure: no ROS. The node that publishes it like a device driver is :mod:`skin_sim_node.device.sim_device`;
there the bridge renders the force (and runs the passivity controller) and the device just applies it.
The ``stabiliser`` option here serves the in-process loop sweep (:mod:`skin_sim_lab.stability.haptic_loop`).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

from .mapping import TOUCH_PEAK_FORCE_N, DeviceMapping, Vec3, clamp_magnitude
from .passivity import PassivityController
from .trajectories import TRAJECTORIES, ScriptClock, Trajectory

STABILISERS = ("none", "passivity")


@dataclass(frozen=True)
class DeviceParams:
    """Stylus and hand parameters (SI units).

    Attributes
    ----------
    mass_kg : float
        Apparent stylus mass at the tip: ~45 g on the Touch / Phantom Omni spec sheet
        ("inertia (apparent mass at tip) ~45 g").
    damping_n_s_per_m : float
        Device viscous damping. Small: 0.05 N*s/m resists a brisk 0.1 m/s hand with 5 mN,
        well under the Touch's specified backdrive friction (< 0.26 N), so it models only
        the viscous part of the gimbal and cable losses.
    hand_stiffness_n_per_m : float
        Hand impedance spring K_h. A pen grip is a few hundred N/m (fingertip impedance
        measurements, e.g. Hajian & Howe 1997, J Biomech Eng 119:109, report hundreds of N/m
        and a few N*s/m); 300 N/m stays below the Touch's own ~1 N/mm rendering stiffness.
    hand_damping_n_s_per_m : float
        Hand damper B_h. 3 N*s/m gives the stylus on the hand spring a damping ratio
        ``B_h / (2 sqrt(K_h m)) = 0.41`` at the defaults: a settled but not sluggish grip.
    max_force_n : float
        Saturation of the commanded force magnitude: the Touch's 3.3 N peak force.
    delay_ticks : int
        Ticks between a force command handed to :meth:`SimulatedDevice.step` and its first
        application (0 or 1; a real servo loop applies a command from its next tick).
    substep_s : float
        Longest integration step inside one tick (s); 0 integrates each tick in one step. The
        stability sweep (:mod:`skin_sim_lab.stability.haptic_loop`) sets 50 us so that the stylus
        and hand behave as continuous-time physics and only the loop is sampled.
    stabiliser : str
        ``"none"`` or ``"passivity"``: the device-side passivity observer and controller of
        :class:`skin_sim_node.device.passivity.PassivityController`, run in the device tick.
    """

    mass_kg: float = 0.045
    damping_n_s_per_m: float = 0.05
    hand_stiffness_n_per_m: float = 300.0
    hand_damping_n_s_per_m: float = 3.0
    max_force_n: float = TOUCH_PEAK_FORCE_N
    delay_ticks: int = 1
    substep_s: float = 0.0
    stabiliser: str = "none"

    def __post_init__(self):
        if not self.mass_kg > 0:
            raise ValueError(f"mass_kg must be > 0, got {self.mass_kg}")
        for name in ("damping_n_s_per_m", "hand_stiffness_n_per_m", "hand_damping_n_s_per_m", "max_force_n"):
            v = getattr(self, name)
            if not (math.isfinite(v) and v >= 0):
                raise ValueError(f"{name} must be finite and >= 0, got {v}")
        if self.delay_ticks not in (0, 1):
            raise ValueError(f"delay_ticks must be 0 or 1, got {self.delay_ticks}")
        if not (math.isfinite(self.substep_s) and self.substep_s >= 0):
            raise ValueError(f"substep_s must be finite and >= 0, got {self.substep_s}")
        if self.stabiliser not in STABILISERS:
            raise ValueError(f"stabiliser must be one of {', '.join(STABILISERS)}, got {self.stabiliser!r}")

    def max_stable_dt_s(self, contact_stiffness_n_per_m: float = 0.0) -> float:
        """Largest step for which semi-implicit Euler stays stable on the linearised stylus.

        Semi-implicit (symplectic) Euler on ``m x'' = -K x - B x'`` is stable for
        ``dt < 2 / omega`` (``omega = sqrt(K / m)``) and ``dt < 2 m / B``; a one-tick force
        delay roughly halves the first bound, so ``dt < 1 / omega`` is required with
        ``K = K_h + contact stiffness``. At the defaults and 1 kHz, ``omega dt = 0.08`` on the
        hand spring and 0.47 against the stiffest default layer (epidermis, ~9.7 kN/m).
        """
        k = self.hand_stiffness_n_per_m + contact_stiffness_n_per_m
        b = self.hand_damping_n_s_per_m + self.damping_n_s_per_m
        limits = [1.0 / math.sqrt(k / self.mass_kg) if k > 0 else math.inf, 2.0 * self.mass_kg / b if b > 0 else math.inf]
        return min(limits)


class SimulatedDevice:
    """A Touch stylus held by a scripted hand, in the device frame.

    Parameters
    ----------
    hand_path : Trajectory or str
        The hand's path in the tissue frame (a trajectory or its name).
    params : DeviceParams
    mapping : DeviceMapping
        Device <-> tissue frame; the hand path is mapped into the device frame with it.
    start_delay_s, repeat, tail_s : float, int, float
        As :class:`skin_sim_node.device.trajectories.ScriptClock`: hold the start pose first, run
        ``repeat`` times (``<= 0``: forever), hold the end pose ``tail_s`` before :attr:`done`.
    path_offset_m : tuple of 3 float
        The hand path shifted in the tissue frame (m): a second hand beside the first (issue 32).

    Notes
    -----
    Per :meth:`step`: ``F = K_h (x_h - x) + B_h (v_h - v) - b v + F_ext``, ``v += F dt / m``,
    ``x += v dt`` (semi-implicit Euler; see :meth:`DeviceParams.max_stable_dt_s`), in substeps of
    at most ``substep_s``. ``F_ext`` is the last force command, held, saturated to ``max_force_n``
    (direction kept; a non-finite command counts as zero), and applied ``delay_ticks`` late; with
    ``stabiliser="passivity"`` the device-side passivity controller adds its damping to it.
    """

    def __init__(
        self,
        hand_path: Trajectory | str = "press_hold_release",
        params: DeviceParams | None = None,
        mapping: DeviceMapping | None = None,
        start_delay_s: float = 0.0,
        repeat: int = 1,
        tail_s: float = 0.0,
        path_offset_m: tuple[float, float, float] = (0.0, 0.0, 0.0),
    ):
        self.hand_path = TRAJECTORIES[hand_path] if isinstance(hand_path, str) else hand_path
        self.path_offset_m = tuple(float(c) for c in path_offset_m)
        self.params = params or DeviceParams()
        self.mapping = mapping or DeviceMapping()
        self.script = ScriptClock(self.hand_path, start_delay_s, repeat, tail_s)
        self.reset()

    def reset(self) -> None:
        """Stylus at rest in the hand at the path's start; no force held; time 0."""
        self.t_s = 0.0
        self.pos, _ = self.hand()
        self.vel = (0.0, 0.0, 0.0)
        self._held = (0.0, 0.0, 0.0)
        self.applied_force_n = (0.0, 0.0, 0.0)
        self.passivity = PassivityController(self.params.mass_kg) if self.params.stabiliser == "passivity" else None

    def hand(self, t_s: float | None = None) -> tuple[Vec3, Vec3]:
        """Hand position (m) and velocity (m/s) in the device frame at ``t_s`` (default: now)."""
        p, v = self.hand_path.sample(self.script.trajectory_time(self.t_s if t_s is None else t_s))
        o = self.path_offset_m
        return self.mapping.to_device((p[0] + o[0], p[1] + o[1], p[2] + o[2])), self.mapping.velocity_to_device(v)

    @property
    def orientation(self) -> tuple[float, float, float, float]:
        """The stylus orientation ``(x, y, z, w)`` in the device frame: the hand path's (the hand holds the tool's
        angle; only its position is simulated)."""
        return self.mapping.orientation_to_device(self.hand_path.orientation)

    @property
    def done(self) -> bool:
        """True once the hand path's last run and tail are over."""
        return self.script.done(self.t_s)

    def step(self, force_xyz_n, dt: float) -> tuple[Vec3, Vec3]:
        """Advance by ``dt`` (s) with the force command ``force_xyz_n`` (N, device frame).

        Returns the new stylus position (m) and velocity (m/s) in the device frame.
        """
        p = self.params
        cmd = clamp_magnitude(tuple(float(c) for c in force_xyz_n), p.max_force_n)
        if p.delay_ticks == 0:
            self._held = cmd
        f_env = f_ext = self._held
        if self.passivity is not None:
            f_ext = clamp_magnitude(self.passivity.force(f_env, self.vel, dt), p.max_force_n)
        self.applied_force_n = f_ext
        x0 = x = self.pos
        v = self.vel
        k, b, bd, m = p.hand_stiffness_n_per_m, p.hand_damping_n_s_per_m, p.damping_n_s_per_m, p.mass_kg
        n_sub = max(1, math.ceil(dt / p.substep_s - 1e-9)) if p.substep_s > 0 else 1
        h = dt / n_sub
        for j in range(n_sub):
            xh, vh = self.hand(self.t_s + j * h)
            a = [k * (xh[i] - x[i]) + b * (vh[i] - v[i]) - bd * v[i] + f_ext[i] for i in range(3)]  # m * acceleration
            v = (v[0] + h / m * a[0], v[1] + h / m * a[1], v[2] + h / m * a[2])
            x = (x[0] + h * v[0], x[1] + h * v[1], x[2] + h * v[2])
        if self.passivity is not None:
            self.passivity.observe(f_ext, f_env, (x[0] - x0[0], x[1] - x0[1], x[2] - x0[2]))
        self.pos, self.vel = x, v
        self.t_s += dt
        self._held = cmd
        return x, v

    @property
    def pos_tissue(self) -> Vec3:
        """Stylus position in the tissue frame (m)."""
        return self.mapping.to_tissue(self.pos)

    @property
    def vel_tissue(self) -> Vec3:
        """Stylus velocity in the tissue frame (m/s)."""
        return self.mapping.velocity_to_tissue(self.vel)
