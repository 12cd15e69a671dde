"""Time-domain passivity observer and controller at the device port (Hannaford & Ryu 2002).

B. Hannaford and J.-H. Ryu, "Time-domain passivity control of haptic interfaces", IEEE Trans.
Robotics and Automation 18(1):1-10, 2002. The observer sums the energy the rendered environment
(node, network delay and zero-order hold together) has absorbed at the device port; when the sum
goes negative the environment has put net energy into the stylus, and the controller adds just the
damping that dissipates that energy on the next device tick.

It runs on the device side, in the device's own servo tick, because only there are the applied
force and the stylus motion between ticks known exactly: with a zero-order hold the work of the
environment over one tick is exactly ``F_applied . (x_end - x_start)``. Pure Python, no ROS.
"""

from __future__ import annotations

import math

from .mapping import Vec3


class PassivityController:
    """Passivity observer (PO) + variable-damping passivity controller (PC).

    Parameters
    ----------
    mass_kg : float
        Apparent stylus mass; bounds the controller's damping at ``mass_kg / dt`` (half the
        ``2 m / dt`` stability limit of a sampled damper on a free mass with a zero-order hold).

    Notes
    -----
    Sign convention: ``F`` is the environment's force on the stylus. The observed energy absorbed by
    the environment is ``W = -sum F_applied . dx``, >= 0 for a passive environment. Per tick, with
    the stylus velocity ``v`` at the start of the tick and ``W < 0``:
    ``alpha = min(-W / (dt v.v), mass / dt)`` and the applied force is ``F - alpha v``.
    """

    def __init__(self, mass_kg: float):
        if not mass_kg > 0:
            raise ValueError(f"mass_kg must be > 0, got {mass_kg}")
        self.mass_kg = float(mass_kg)
        self.reset()

    def reset(self) -> None:
        """Zero the observed energy, the dissipated energy, the damping and the active-tick count."""
        self.energy_j = 0.0  # observed energy absorbed by the environment (J); < 0: it generated energy
        self.dissipated_j = 0.0  # energy the controller dissipated, observed (J)
        self.alpha_n_s_per_m = 0.0  # damping of the current tick (N*s/m)
        self.active_ticks = 0

    def force(self, f_env: Vec3, vel: Vec3, dt: float) -> Vec3:
        """The force to apply over the coming tick: ``f_env`` plus the controller's damping."""
        self.alpha_n_s_per_m = 0.0
        v2 = vel[0] * vel[0] + vel[1] * vel[1] + vel[2] * vel[2]
        if self.energy_j >= 0.0 or dt <= 0.0 or v2 <= 0.0:
            return f_env
        alpha = min(-self.energy_j / (dt * v2), self.mass_kg / dt)
        if not math.isfinite(alpha):
            return f_env
        self.alpha_n_s_per_m = alpha
        self.active_ticks += 1
        return (f_env[0] - alpha * vel[0], f_env[1] - alpha * vel[1], f_env[2] - alpha * vel[2])

    def observe(self, f_applied: Vec3, f_env: Vec3, dx: Vec3) -> None:
        """Account the tick just integrated: ``f_applied`` held over the stylus displacement ``dx``.

        ``f_env`` is the environment's part of ``f_applied`` (both after saturation); the rest is
        the controller's damping, whose work is booked as dissipated.
        """
        work_applied = f_applied[0] * dx[0] + f_applied[1] * dx[1] + f_applied[2] * dx[2]
        work_env = f_env[0] * dx[0] + f_env[1] * dx[1] + f_env[2] * dx[2]
        if math.isfinite(work_applied):
            self.energy_j -= work_applied
            self.dissipated_j += max(0.0, work_env - work_applied)
