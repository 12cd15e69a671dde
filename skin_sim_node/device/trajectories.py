"""Scripted, deterministic tool trajectories. Pure: no ROS.

The mock tool (:mod:`skin_sim_node.device.mock_tool`) publishes them; the simulated device
uses the same paths as its hand path.

Every trajectory is a chain of cosine ramps ``p(s) = a + (b - a) (1 - cos(pi s)) / 2``
(``s = t / T``) with the exact velocity ``(b - a) pi / (2 T) sin(pi s)``: position and
velocity are continuous, and every segment starts and ends at rest. All positions are
in the tissue frame (sheet centred on the origin, z up, rest surface z = 0; the tool
presses for z < 0). Each starts and ends lifted at ``z = LIFT_Z_M``.
"""

from __future__ import annotations

import bisect
import math
from dataclasses import dataclass, field

from .mapping import Vec3, vec3

LIFT_Z_M = 0.005
"""Lifted tool height (m): 5 mm clears the rest surface by far more than any relaxing bulge."""


@dataclass(frozen=True)
class Trajectory:
    """A piecewise cosine-ramp path.

    Parameters
    ----------
    name : str
    start_m : tuple of float
        Start position (m, tissue frame).
    segments : tuple of (duration_s, target_m)
        Each segment ramps from the previous point to ``target_m`` in ``duration_s``;
        ``target_m`` equal to the previous point is a hold.
    description : str
    orientation : tuple of 4 float
        The tool's orientation ``(x, y, z, w)`` over the whole path (tissue frame; identity: a needle points
        straight down). Only the needle (``tool.shape`` 'needle') uses it.
    """

    name: str
    start_m: Vec3
    segments: tuple[tuple[float, Vec3], ...]
    description: str = ""
    orientation: tuple[float, float, float, float] = (0.0, 0.0, 0.0, 1.0)
    _t0: tuple[float, ...] = field(init=False, repr=False, compare=False)
    _p0: tuple[Vec3, ...] = field(init=False, repr=False, compare=False)

    def __post_init__(self) -> None:
        t0: list[float] = []
        p0: list[Vec3] = []
        t, p = 0.0, vec3(self.start_m)
        for dur, target in self.segments:
            if not dur > 0:
                raise ValueError(f"{self.name}: segment durations must be > 0, got {dur}")
            t0.append(t)
            p0.append(p)
            t += float(dur)
            p = vec3(target)
        object.__setattr__(self, "_t0", tuple(t0))
        object.__setattr__(self, "_p0", tuple(p0))

    @property
    def duration_s(self) -> float:
        """Total duration (s)."""
        return sum(d for d, _ in self.segments)

    @property
    def end_m(self) -> Vec3:
        """End position (m): the last segment's target, or the start without segments."""
        return vec3(self.segments[-1][1]) if self.segments else vec3(self.start_m)

    def sample(self, t: float) -> tuple[Vec3, Vec3]:
        """Position (m) and exact velocity (m/s) at time ``t`` (s); held at the ends outside ``[0, duration_s]``."""
        if t <= 0.0 or not self.segments:
            return vec3(self.start_m), (0.0, 0.0, 0.0)
        if t >= self.duration_s:
            return self.end_m, (0.0, 0.0, 0.0)
        i = bisect.bisect_right(self._t0, t) - 1
        dur, b = self.segments[i]
        a = self._p0[i]
        s = (t - self._t0[i]) / dur
        w = 0.5 * (1.0 - math.cos(math.pi * s))
        dw = 0.5 * math.pi / dur * math.sin(math.pi * s)
        pos = (a[0] + (b[0] - a[0]) * w, a[1] + (b[1] - a[1]) * w, a[2] + (b[2] - a[2]) * w)
        vel = ((b[0] - a[0]) * dw, (b[1] - a[1]) * dw, (b[2] - a[2]) * dw)
        return pos, vel


def _press(name: str, x_m: float, depth_m: float, press_s: float, hold_s: float, release_s: float, lifted_s: float, desc: str):
    up = (x_m, 0.0, LIFT_Z_M)
    down = (x_m, 0.0, -depth_m)
    return Trajectory(name, up, ((press_s, down), (hold_s, down), (release_s, up), (lifted_s, up)), desc)


NEEDLE_DEPTH_M = 5.2e-3
"""Deepest tip of the needle paths below the rest surface (m): past the skin's puncture for 18-30 G, lubricated (1.8-3.9
mm of tip travel) and dry (up to 5.15 mm for 18 G; docs/needle.md), and inside the 5.275 mm stack (the model has no
tissue below it)."""
NEEDLE_START_M = 0.5e-3
"""Tip height above the surface where the needle paths start and end their insertion (m)."""


def needle_orientation(elevation_rad: float) -> tuple[float, float, float, float]:
    """Orientation ``(x, y, z, w)`` of a needle inclined ``elevation_rad`` above the sheet (pi/2: vertical), pointing
    along +x and down: the rotation about y taking ``(0, 0, -1)`` to ``(cos e, 0, -sin e)``."""
    half = -0.5 * (0.5 * math.pi - elevation_rad)
    return (0.0, math.sin(half), 0.0, math.cos(half))


def _needle(name: str, elevation_deg: float, speed_m_s: float, stops: tuple[float, ...], desc: str) -> Trajectory:
    """A needle path along its own axis through the entry at the origin: from ``NEEDLE_START_M`` above the surface to
    each vertical depth in ``stops`` in turn (m, > 0 down) at the mean speed ``speed_m_s`` along the axis, holding
    0.3 s at each, then back out and lifted."""
    e = math.radians(elevation_deg)
    u = (math.cos(e), 0.0, -math.sin(e))

    def at(depth_m: float) -> Vec3:
        s = depth_m / math.sin(e)
        return (s * u[0], 0.0, s * u[2])

    lift = (-LIFT_Z_M * u[0] / math.sin(e), 0.0, LIFT_Z_M)
    start = at(-NEEDLE_START_M)
    segs: list[tuple[float, Vec3]] = [(0.5, start)]
    here = -NEEDLE_START_M
    for depth in (*stops, -NEEDLE_START_M):
        segs.append((abs(depth - here) / math.sin(e) / speed_m_s, at(depth)))
        segs.append((0.3, at(depth)))
        here = depth
    segs.append((0.3, lift))
    return Trajectory(name, lift, tuple(segs), desc, needle_orientation(e))


def _build() -> dict[str, Trajectory]:
    lift = LIFT_Z_M
    trajs = [
        _press(
            "press_hold_release",
            0.0,
            2.5e-3,
            0.5,
            1.0,
            0.3,
            0.5,
            "centre: press to 2.5 mm over 0.5 s, hold 1 s, release over 0.3 s, stay lifted 0.5 s",
        ),
        _press(
            "anchor_hold",
            0.0,
            2e-3,
            0.5,
            3.5,
            0.3,
            0.5,
            "centre: a finger anchoring the skin (two hands, with --offset / --path-offset beside a needle): press to 2 mm "
            "over 0.5 s, hold 3.5 s (through a needle_straight started 0.5 s later), release over 0.3 s, stay lifted 0.5 s",
        ),
        _press(
            "light_touch",
            0.0,
            20e-6,
            0.5,
            1.0,
            0.3,
            0.5,
            "centre: press to 20 um (epidermis only: the epidermis/dermis interface peaks at 35 um), hold 1 s, "
            "release over 0.3 s, stay lifted 0.5 s",
        ),
        _press(
            "press_all_layers",
            0.0,
            4.0e-3,
            0.8,
            1.0,
            0.5,
            0.5,
            "centre: press to 4.0 mm (below the dermis/fat interface, 1.275 +- 0.5 mm: all three layers)",
        ),
        Trajectory(
            "drag",
            (-0.02, 0.0, lift),
            (
                (0.5, (-0.02, 0.0, -1.5e-3)),
                (0.2, (-0.02, 0.0, -1.5e-3)),
                (2.0, (0.02, 0.0, -1.5e-3)),
                (0.2, (0.02, 0.0, -1.5e-3)),
                (0.3, (0.02, 0.0, lift)),
                (0.3, (0.02, 0.0, lift)),
            ),
            "press to 1.5 mm at x = -20 mm, drag along x to +20 mm over 2 s across the egg-carton "
            "peaks (x = 0, +-5 mm, ...) and valleys (x = +-2.5 mm, ...) of the dermis/fat interface, lift",
        ),
        _press(
            "edge_press",
            0.05,
            2.0e-3,
            0.5,
            1.0,
            0.3,
            0.5,
            "press to 2 mm at x = 50 mm, 10 mm from the +x sheet edge",
        ),
        Trajectory(
            "fast_stab",
            (0.0, 0.0, lift),
            (
                (0.3, (0.0, 0.0, 0.0)),
                (0.1, (0.0, 0.0, 0.0)),
                (0.02, (0.0, 0.0, -3.0e-3)),
                (0.02, (0.0, 0.0, 0.0)),
                (0.2, (0.0, 0.0, lift)),
                (0.3, (0.0, 0.0, lift)),
            ),
            "approach the surface, stab from the surface to 3 mm in 20 ms and out in 20 ms, lift",
        ),
        Trajectory(
            "lift_during_relax",
            (0.0, 0.0, lift),
            (
                (0.5, (0.0, 0.0, -3.0e-3)),
                (0.3, (0.0, 0.0, -3.0e-3)),
                (0.015, (0.0, 0.0, 0.5e-3)),
                (0.015, (0.0, 0.0, -1.0e-3)),
                (0.3, (0.0, 0.0, -1.0e-3)),
                (0.3, (0.0, 0.0, lift)),
                (0.3, (0.0, 0.0, lift)),
            ),
            "press 3 mm, release to +0.5 mm in 15 ms, come back down to 1 mm 30 ms after the release "
            "started (the tissue is still relaxing: fat release time constant is tens of ms), hold, lift",
        ),
        _needle(
            "needle_straight",
            90.0,
            5e-3,
            (NEEDLE_DEPTH_M,),
            "needle (tool.shape 'needle'), vertical at the origin (an egg-carton peak): insert at 5 mm/s mean to 5.2 mm "
            "deep, hold 0.3 s, withdraw, lift",
        ),
        _needle(
            "needle_oblique_30",
            30.0,
            5e-3,
            (NEEDLE_DEPTH_M,),
            "needle at 30 deg to the skin surface, pointing along +x, entering at the origin: insert at 5 mm/s mean along "
            "its axis to 5.2 mm below the surface (10.4 mm of track), hold, withdraw, lift",
        ),
        _needle(
            "needle_oblique_15",
            15.0,
            5e-3,
            (NEEDLE_DEPTH_M,),
            "needle at 15 deg to the skin surface (an intravenous angle), along +x, entering at the origin: the tip "
            "skates on the tented skin before it punctures (docs/needle.md, oblique insertion); to 5.2 mm deep at 5 mm/s "
            "mean along its axis (20.1 mm of track), hold, withdraw, lift",
        ),
        _needle(
            "needle_oblique_60",
            60.0,
            5e-3,
            (NEEDLE_DEPTH_M,),
            "needle at 60 deg to the skin surface, along +x, entering at the origin: to 5.2 mm deep at 5 mm/s mean",
        ),
        _needle(
            "needle_reinsert",
            90.0,
            5e-3,
            (NEEDLE_DEPTH_M, 1.5e-3, NEEDLE_DEPTH_M, -NEEDLE_START_M, NEEDLE_DEPTH_M),
            "needle, vertical: insert to 5.2 mm, retract to 1.5 mm (still in the track), re-insert to 5.2 mm (no second "
            "puncture: the track is latched), withdraw out of the skin, insert again (a new track: the peak returns)",
        ),
        _needle(
            "needle_slow",
            90.0,
            1e-3,
            (NEEDLE_DEPTH_M,),
            "needle, vertical: insert at 1 mm/s mean to 5.2 mm, hold, withdraw (with needle_fast: the skin peak's speed "
            "dependence)",
        ),
        _needle(
            "needle_fast",
            90.0,
            20e-3,
            (NEEDLE_DEPTH_M,),
            "needle, vertical: insert at 20 mm/s mean to 5.2 mm, hold, withdraw",
        ),
    ]
    return {t.name: t for t in trajs}


TRAJECTORIES: dict[str, Trajectory] = _build()
"""The scripted trajectories by name."""


class ScriptClock:
    """Maps loop time to trajectory time: start delay, repeats, then a lifted tail.

    Parameters
    ----------
    traj : Trajectory
    start_delay_s : float
        Time holding the start pose before the first run (lets DDS discovery finish).
    repeat : int
        Number of runs; ``<= 0`` loops forever.
    tail_s : float
        Time holding the end pose after the last run before :attr:`done`.
    """

    def __init__(self, traj: Trajectory, start_delay_s: float, repeat: int, tail_s: float):
        self.traj, self.start_delay_s, self.repeat, self.tail_s = traj, start_delay_s, repeat, tail_s

    def trajectory_time(self, t_s: float) -> float:
        """Trajectory time (s) at loop time ``t_s``."""
        t = t_s - self.start_delay_s
        d = self.traj.duration_s
        if t <= 0.0:
            return 0.0
        if self.repeat <= 0:
            return math.fmod(t, d)
        return t - d * (self.repeat - 1) if t >= d * self.repeat else math.fmod(t, d)

    def done(self, t_s: float) -> bool:
        """True at ``t_s`` once every run and the tail are over (never with ``repeat = 0``)."""
        return self.repeat > 0 and t_s >= self.start_delay_s + self.traj.duration_s * self.repeat + self.tail_s
