"""A needle through the layered skin (issue 22, first cut): dimple, per-layer puncture, cutting, shaft friction.

Pure Python (NumPy), the physics reference for the haptic kernel still to come; it is not wired into the
node, the bridge or the view yet (docs/needle.md, "Status"). Tissue frame, SI units, z up, rest surface z = 0.

The needle is a rigid shaft of outer diameter ``d`` whose tip is at ``p`` and which points along the unit axis
``u`` (tip direction). Once the tip passes the rest surface the *track* is fixed: the entry point ``e`` where the
axis met the surface, and the axis ``u_e``. Along it, the insertion length is ``L = (p - e) . u_e`` and the
layers' tops are crossed at the axis lengths ``t_j`` where the axis meets the egg-carton interfaces (section II.C,
point values: the needle is thin), so the crossing depth varies with the entry point and the angle.

Per tick the axial resistance ``R`` (N, along ``u_e``, positive against insertion) is the sum of:

- **dimple** (before the next layer ``k`` ruptures): the tip presses layer ``k``'s top ``w = L - t_k`` ahead of
  it; the stack below, layers ``k..L-1``, answers with the layered form's equilibrium series chain (its fitted
  law, :func:`~.layered.chain_solve`) at the normal compression ``w |u_z|``, acting along the axis (the column along
  the needle, strained as the normal compression strains the stack), scaled from the calibrated 2.5 mm
  punch to the *tent's* radius ``a + l_f`` as a half-space is (Sneddon: force proportional to the contact radius),
  and projected on the axis. ``a`` is the needle's radius and ``l_f`` the layers' own spread length
  (``patch.foundation_length_m``, 1.63 mm, fitted to the 3D reference's dent: how far a load spreads from the tool):
  the stiff skin carries the tip's load over a tent wider than the needle. For 18-25 G the tent's radius (1.9-2.3 mm)
  is within 25 % of the punch the law was fitted with, so the law is used near its calibrated regime. (Scaling to
  ``a`` alone left the skin unruptured until the 5.3 mm stack was pressed onto its bottom.)
- **puncture**: layer ``k`` ruptures when the axial dimple force reaches ``F_p,k = lambda Gamma_k d``
  (``Gamma_k`` an effective toughness, ``lambda`` 1 lubricated / 2 dry): a force threshold whose value is a
  toughness times the diameter, rate- and angle-independent (Schneider 1978). The track is latched: no second
  puncture of a layer until the needle leaves the tissue. A rupture releases the dimple at once; if the tip is then
  past the next layer's top, that layer's dimple is tested in the same tick (a cascade);
- **cutting**: while the tip advances into new material of a ruptured layer ``j`` (at the crack front, the
  deepest ``L`` so far), ``beta F_p,j``; it fades over ``x_c`` behind the front when the tip backs off (a
  position law: nothing toggles at zero speed) and is zero in an already cut track;
- **shaft friction**, Dahl's model per ruptured layer ``i`` with inserted length ``l_i``:
  ``F_f,i = lambda tau pi d l_i s_i``, ``s_i <- sigma + (s_i - sigma) exp(-|dL| / x_0)``, ``sigma = sign(dL)``
  (integrated exactly over a step: rate-independent, hysteresis on retraction, no velocity threshold).

Sideways, the shaft's deviation from its track, ``delta = (p - e) - L u_e`` at the tip, is resisted by a Winkler
bed along the inserted shaft, ``-0.5 sum_i k_l E_i l_i delta`` (a shaft pivoting at the entry: the mean deviation is
half the tip's). The force on the needle is ``-R u_e`` plus that lateral force.

Sources and the data each default meets: docs/needle.md and docs/data/needle/ (sources.md, data.yaml).
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np

from msgs_schema.contact_model import NeedleLaw
from msgs_schema.tissue import LAYER_DEFAULTS, LAYER_NAMES, TOOL_RADIUS_M

from .config import WALL_STRAIN, TissueConfig
from .interfaces import interface_depths_m
from .layered import chain_solve
from .layout import LP_EA, LP_N, pack_layers
from .physics import equilibrium

GAUGE_OUTER_DIAMETER_M = {18: 1.270e-3, 21: 0.819e-3, 25: 0.514e-3, 27: 0.413e-3, 30: 0.311e-3}
"""Nominal outer diameters of normal-wall hypodermic tubing (ISO 9626:2016, table 1, nominal OD)."""
TOUGHNESS_J_PER_M2 = {"epidermis": 1.1e3, "dermis": 2.2e3, "fat": 0.33e3}
"""Effective puncture toughness ``Gamma`` per layer (N/m): dermis 2.2 kJ/m^2 from the cadaver skin peak 2.75-2.80 N
(J Endourol, doi 10.1089/end.2016.0342) over an 18 G diameter (gauge assumed: not in the abstract), bracketed by
Mohammadi et al. 2021's cohesive 1.6 kJ/m^2 and Roemgens et al. 2014's F/d of 4.5 kJ/m^2; epidermis half of it and
fat 15 % of it: design choices (the issue's fat peak < 20 % of skin's, with a margin; no measured fat peak found).
docs/data/needle/model_notes.md section 1."""
DRY_FACTOR = 2.0
"""``lambda`` for a dry (unlubricated) needle: Schneider 1978, dry needles need 1.5-3 x the force of lubricated
ones (applied to puncture, cutting and friction alike: the report does not say which)."""
CUTTING_RATIO = 0.6
"""``beta``: steady cutting force over the puncture threshold (design: Mohammadi's G_c over the calibrated Gamma
is 0.73; Barnett et al. 2015: cutting dominates the steady force)."""
SHAFT_SHEAR_PA = 6.0e3
"""``tau``: friction per shaft area (Pa), between Barnett's 21 % friction share (4.3 kPa at full depth) and the
cadaver overall slope 0.035-0.059 N/mm over an 18 G perimeter (8.8-14.8 kPa, an upper bound)."""
DAHL_LENGTH_M = 1.0e-3
"""Dahl presliding length ``x_0`` (design: stick stiffness at full 18 G depth 130 N/m, under the Touch's 1.02 N/mm;
Kim & Lee 2016 fit a Dahl law to needle friction in porcine tissue, number not read)."""
CUT_PRESLIDING_M = 0.1e-3
"""``x_c``: the cutting force fades over this distance when the tip backs off the crack front (design: a tenth of
``x_0``; a position law instead of a switch at zero speed)."""
LATERAL_FACTOR = 2.0
"""``k_l``: Winkler modulus of a shaft in an elastic medium per unit length over the medium's Young's modulus
(order 2 for a rigid cylinder; stated choice)."""
MIN_ANGLE_RAD = math.radians(10.0)
"""Shallowest insertion below the surface that starts a track (steeper than 10 degrees; a shallower needle
slides: no track)."""


@dataclass(frozen=True)
class NeedleParams:
    """The needle: outer diameter or gauge, lubrication, bevel (kept for the tip's lateral force, not in the
    threshold: Mohammadi et al. 2021 find the diameter dominates the cutting angle)."""

    outer_diameter_m: float = GAUGE_OUTER_DIAMETER_M[21]
    lubricated: bool = True
    bevel_angle_deg: float = 17.0
    toughness_j_per_m2: tuple[float, ...] = field(default=tuple(TOUGHNESS_J_PER_M2[n] for n in LAYER_NAMES))
    cutting_ratio: float = CUTTING_RATIO
    shaft_shear_pa: float = SHAFT_SHEAR_PA
    dahl_length_m: float = DAHL_LENGTH_M
    cut_presliding_m: float = CUT_PRESLIDING_M

    @classmethod
    def gauge(cls, g: int, **kw) -> NeedleParams:
        """A needle of gauge ``g`` (:data:`GAUGE_OUTER_DIAMETER_M`)."""
        if g not in GAUGE_OUTER_DIAMETER_M:
            raise ValueError(f"gauge {g} not tabulated: one of {sorted(GAUGE_OUTER_DIAMETER_M)}")
        return cls(outer_diameter_m=GAUGE_OUTER_DIAMETER_M[g], **kw)

    @property
    def lubrication_factor(self) -> float:
        """``lambda``: 1 lubricated, :data:`DRY_FACTOR` dry."""
        return 1.0 if self.lubricated else DRY_FACTOR

    def puncture_force_n(self, layer: int) -> float:
        """``F_p = lambda Gamma d`` of ``layer`` (N)."""
        return self.lubrication_factor * self.toughness_j_per_m2[layer] * self.outer_diameter_m


@dataclass
class NeedleTick:
    """One tick's answer: the force on the needle and its parts (N), the layers ruptured, the events."""

    force_n: np.ndarray
    axial_n: float = 0.0
    dimple_n: float = 0.0
    cutting_n: float = 0.0
    friction_n: float = 0.0
    lateral_n: np.ndarray = field(default_factory=lambda: np.zeros(3))
    dimple_m: float = 0.0
    insertion_m: float = 0.0
    ruptured: int = 0
    punctured: tuple[int, ...] = ()


class NeedleModel:
    """A needle in the layered stack of ``cfg`` (module docstring); :meth:`step` per tick."""

    def __init__(self, cfg: TissueConfig, params: NeedleParams | None = None):
        self.cfg = equilibrium(cfg)
        self.params = params or NeedleParams()
        lp = pack_layers(self.cfg)
        self._ea = lp[LP_EA].copy()
        self._n = lp[LP_N].copy()
        self._h = np.array([la.thickness_m for la in self.cfg.layers])
        self._moduli = np.array([LAYER_DEFAULTS[name][1] for name in LAYER_NAMES])
        # the tent: a punch of radius a + l_f (TENT_SPREAD), scaled from the calibrated punch as Sneddon's F ~ radius
        self._scale = (0.5 * self.params.outer_diameter_m + self.cfg.foundation_length_m) / TOOL_RADIUS_M
        self.reset()

    def reset(self) -> None:
        """Needle out of the tissue: no track."""
        nl = len(self._h)
        self.inserted = False
        self.entry = np.zeros(3)
        self.axis = np.array([0.0, 0.0, -1.0])
        self.crossings = np.zeros(nl + 1)
        self.ruptured = 0
        self.front_m = 0.0
        self.last_m = 0.0
        self.dahl = np.zeros(nl)

    # --- geometry -----------------------------------------------------------------------------
    def _interface_depth(self, j: int, x: float, y: float) -> float:
        """Depth (m, down) of the top of layer ``j`` at ``(x, y)``: 0 for the surface, the egg-carton below."""
        if j == 0:
            return 0.0
        if j >= len(self._h):
            return self.cfg.total_thickness_m
        return float(interface_depths_m(self.cfg, x, y)[j - 1])

    def _crossing(self, j: int) -> float:
        """Axis length from the entry to the first point where the axis meets layer ``j``'s top (m): the first sign
        change of ``depth(s) - D_j(x(s), y(s))`` on a 2 um scan, then bisection."""
        e, u = self.entry, self.axis
        down = -u[2]
        if j == 0:
            return 0.0
        s_max = (self.cfg.total_thickness_m + 1e-3) / down

        def g(s: float) -> float:
            q = e + s * u
            return -q[2] - self._interface_depth(j, q[0], q[1])

        ds = 2e-6 / down
        s = 0.0
        while s < s_max and g(s + ds) < 0.0:
            s += ds
        lo, hi = s, s + ds
        for _ in range(60):
            mid = 0.5 * (lo + hi)
            lo, hi = (mid, hi) if g(mid) < 0.0 else (lo, mid)
        return 0.5 * (lo + hi)

    def _start_track(self, tip: np.ndarray, axis: np.ndarray) -> bool:
        if axis[2] > -math.sin(MIN_ANGLE_RAD) or tip[2] >= 0.0:
            return False
        self.reset()
        self.inserted = True
        self.axis = axis.copy()
        self.entry = tip - (tip[2] / axis[2]) * axis
        for j in range(len(self._h) + 1):
            self.crossings[j] = self._crossing(j)
        return True

    # --- laws ---------------------------------------------------------------------------------
    def dimple_force_n(self, layer: int, w_m: float) -> float:
        """Axial force (N) of the stack below ``layer``'s top pressed ``w_m`` along the axis by the needle's tip: the
        column along the needle, its layers ``h / |u_z|`` long, strained as the normal compression ``w |u_z|`` strains
        the stack, so the force at puncture does not depend on the angle (Schneider 1978: "relatively insensitive to
        penetration velocity or angle")."""
        if w_m <= 0.0:
            return 0.0
        down = -self.axis[2]
        sub = slice(layer, len(self._h))
        n = self._h[sub].size
        c, g = np.zeros(n), np.zeros(n)
        t = chain_solve(w_m * down, 0.0, self._ea[sub].copy(), self._n[sub].copy(), np.zeros(n), 1.0,
                        np.zeros(n), self._h[sub].copy(), WALL_STRAIN, np.zeros(n), c, g)  # fmt: skip
        return self._scale * max(t, 0.0)

    def rupture_insertion_m(self) -> float:
        """Insertion ``L`` (m) at which the next intact layer ruptures: its dimple force reaches ``F_p`` (bisection
        on the monotone dimple law); inf when every layer is ruptured or the dimple never reaches it."""
        k = self.ruptured
        if not self.inserted or k >= len(self._h):
            return math.inf
        fp = self.params.puncture_force_n(k)
        hi = 1e-4
        while self.dimple_force_n(k, hi) < fp:
            hi *= 2.0
            if hi > 1.0:
                return math.inf
        lo = 0.0
        for _ in range(48):
            mid = 0.5 * (lo + hi)
            lo, hi = (mid, hi) if self.dimple_force_n(k, mid) < fp else (lo, mid)
        return float(self.crossings[k] + hi)

    def copy(self) -> NeedleModel:
        """An independent copy (state arrays included) for look-ahead."""
        c = object.__new__(NeedleModel)
        c.__dict__.update(self.__dict__)
        for name in ("entry", "axis", "crossings", "dahl"):
            setattr(c, name, getattr(self, name).copy())
        return c

    def law(self, tick: NeedleTick, tip_m) -> NeedleLaw | None:
        """The axial law at the tip ``tip_m`` after ``tick`` (the last :meth:`step`), for the local contact model:
        ``R_e`` and its slope, the rupture ahead and the line past it, and the Dahl friction's level, slope and state
        (``ContactModel.msg``). None out of the tissue."""
        if not self.inserted:
            return None
        pr = self.params
        ins = tick.insertion_m
        h = 1e-6
        re0 = tick.dimple_n + tick.cutting_n
        ahead = self.copy()
        t1 = ahead.step(np.asarray(tip_m) + h * self.axis, self.axis)
        slope = (t1.dimple_n + t1.cutting_n - re0) / h if t1.ruptured == tick.ruptured else 0.0
        lr = self.rupture_insertion_m()
        dist = post = post_slope = 0.0
        if math.isfinite(lr):
            dist = max(lr - ins, 0.0) + 1e-9
            after = self.copy()
            base = np.asarray(tip_m) + (dist + 1e-7) * self.axis
            a1 = after.step(base, self.axis)
            a2 = after.step(base + h * self.axis, self.axis)
            post = a1.dimple_n + a1.cutting_n
            post_slope = (a2.dimple_n + a2.cutting_n - post) / h
        lam = pr.lubrication_factor
        per_length = lam * pr.shaft_shear_pa * math.pi * pr.outer_diameter_m
        cap, grows = 0.0, 0.0
        for i in range(self.ruptured):
            length = min(max(ins, self.crossings[i]), self.crossings[i + 1]) - self.crossings[i]
            cap += per_length * length
            grows += per_length if self.crossings[i] < ins < self.crossings[i + 1] else 0.0
        if self.ruptured == len(self._h) and ins >= self.crossings[-1]:
            grows = 0.0
        z = min(max(tick.friction_n / cap, -1.0), 1.0) if cap > 0.0 else 0.0
        return NeedleLaw(
            axis=tuple(float(c) for c in self.axis),  # type: ignore[arg-type]
            axial_force_n=re0,
            axial_gradient_n_per_m=slope,
            rupture_distance_m=dist,
            post_rupture_force_n=post,
            post_rupture_gradient_n_per_m=post_slope,
            friction_capacity_n=cap,
            friction_capacity_gradient_n_per_m=grows,
            friction_state=z,
            dahl_length_m=pr.dahl_length_m,
        )

    def step(self, tip_m, axis) -> NeedleTick:
        """Advance to the tip position ``tip_m`` (m) with the needle along ``axis`` (unit vector toward the tip)."""
        p = np.asarray(tip_m, dtype=float)
        u = np.asarray(axis, dtype=float)
        u = u / np.linalg.norm(u)
        pr = self.params
        if not self.inserted and not self._start_track(p, u):
            return NeedleTick(np.zeros(3))
        ins = float((p - self.entry) @ self.axis)
        if ins <= 0.0:  # withdrawn: the track is forgotten
            self.reset()
            return NeedleTick(np.zeros(3))
        nl = len(self._h)
        punctured = []
        dimple = 0.0
        while self.ruptured < nl:
            w = ins - self.crossings[self.ruptured]
            dimple = self.dimple_force_n(self.ruptured, w)
            if dimple < pr.puncture_force_n(self.ruptured):
                break
            punctured.append(self.ruptured)
            self.ruptured += 1
            dimple = 0.0
        w_dimple = max(ins - self.crossings[self.ruptured], 0.0) if self.ruptured < nl else 0.0
        lam = pr.lubrication_factor
        # cutting at the crack front, inside the ruptured part of the track
        cut = 0.0
        inside = self.ruptured > 0 and (self.ruptured == nl or ins < self.crossings[self.ruptured])
        if inside:
            j = int(np.searchsorted(self.crossings[: self.ruptured + 1], ins, side="right")) - 1
            j = min(max(j, 0), self.ruptured - 1)
            ramp = min(max((ins - self.front_m + pr.cut_presliding_m) / pr.cut_presliding_m, 0.0), 1.0)
            cut = pr.cutting_ratio * pr.puncture_force_n(j) * ramp
        if inside:
            self.front_m = max(self.front_m, ins)
        elif self.ruptured > 0:  # dimpling the next layer: the ruptured ones are cut through
            self.front_m = max(self.front_m, self.crossings[self.ruptured])
        # Dahl shaft friction in each ruptured layer
        step = ins - self.last_m
        self.last_m = ins
        fric = 0.0
        lateral_k = 0.0
        for i in range(self.ruptured):
            length = min(max(ins, self.crossings[i]), self.crossings[i + 1]) - self.crossings[i]
            if step != 0.0:
                sigma = math.copysign(1.0, step)
                self.dahl[i] = sigma + (self.dahl[i] - sigma) * math.exp(-abs(step) / pr.dahl_length_m)
            fric += lam * pr.shaft_shear_pa * math.pi * pr.outer_diameter_m * length * self.dahl[i]
            lateral_k += LATERAL_FACTOR * self._moduli[i] * length
        axial = dimple + cut + fric
        deviation = (p - self.entry) - ins * self.axis
        lateral = -0.5 * lateral_k * deviation
        force = -axial * self.axis + lateral
        return NeedleTick(force, axial, dimple, cut, fric, lateral, w_dimple, ins, self.ruptured, tuple(punctured))
