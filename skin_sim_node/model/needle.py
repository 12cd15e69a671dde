"""A needle through the layered skin (issue 22, first cut): dimple, per-layer puncture, cutting, shaft friction.

:class:`NeedleModel` runs the numba kernels of :mod:`.needle_kernels` on the arrays of :mod:`.layout`'s needle
section (a step and the law together take microseconds: the haptic rate); :class:`.needle_reference.NumpyNeedleModel`
is the pure-NumPy first cut, kept as the slow reference the kernels are tested against. Tissue frame, SI units, z up,
rest surface z = 0.

The needle is a rigid shaft of outer diameter ``d`` whose tip is at ``p`` and which points along the unit axis
``u`` (tip direction). Once the tip passes the rest surface the *track* is fixed: the entry point ``e`` where the
axis met the surface, and the axis ``u_e``. Along it, the insertion length is ``L = (p - e) . u_e`` and the
layers' tops are crossed at the axis lengths ``t_j`` where the axis meets the egg-carton interfaces (section II.C,
point values: the needle is thin), so the crossing depth varies with the entry point and the angle.

Per tick the axial resistance ``R`` (N, along ``u_e``, positive against insertion) is the sum of:

- **dimple** (before the next layer ``k`` ruptures): the tip presses layer ``k``'s top, ``w_n`` deep normal to it
  (on the axis ``w_n = (L - t_k) |u_z|``); the stack below, layers ``k..L-1``, answers with its normal reaction
  ``N``, the layered form's equilibrium series chain (its fitted law, :func:`~.layered_law.chain_solve`) at ``w_n``
  (a function of the tip's depth: a potential's gradient), and with the tip's friction on it, the presliding law of
  :mod:`.friction` (a spring ``k_t`` from a stuck anchor on the surface plane, capped at ``mu N``, the anchor dragged
  beyond: passive; the anchor is kept across the tool's track restarts); the dimple is their axial part. ``N`` is
  scaled from the calibrated 2.5 mm
  punch to the *tent's* radius ``a + l_f`` as a half-space is (Sneddon: force proportional to the contact radius),
  and projected on the axis. ``a`` is the needle's radius and ``l_f`` the layers' own spread length
  (``patch.foundation_length_m``, 1.63 mm, fitted to the 3D reference's dent: how far a load spreads from the tool):
  the stiff skin carries the tip's load over a tent wider than the needle. For 18-25 G the tent's radius (1.9-2.3 mm)
  is within 25 % of the punch the law was fitted with, so the law is used near its calibrated regime. (Scaling to
  ``a`` alone left the skin unruptured until the 5.3 mm stack was pressed onto its bottom.)
- **puncture**: layer ``k`` ruptures when the tent's normal reaction ``N`` reaches ``F_p,k = lambda Gamma_k d``
  (docs/needle.md, "Oblique insertion": the friction is carried or dissipated at the interface, not counted as
  driving the crack; at 90 degrees ``N`` is the axial force)
  (``Gamma_k`` an effective toughness, ``lambda`` 1 lubricated / 2 dry): a force threshold whose value is a
  toughness times the diameter, rate-independent (Schneider 1978). The track is latched: no second
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
from typing import Any

import numpy as np

from msgs_schema.contact_model import NeedleLaw
from msgs_schema.tissue import LAYER_NAMES

from .calibration import CALIBRATED_TOOL_RADIUS_M, WALL_STRAIN, youngs_moduli_pa
from .config import TissueConfig, equilibrium
from .layout import (
    LP_EA,
    LP_N,
    NB_SIZE,
    NL_CUT_M,
    NL_FP,
    NL_H,
    NL_MODULUS,
    NL_SIZE,
    NL_TENT_K,
    NO_AXIAL,
    NO_BED,
    NO_CUT,
    NO_DIMPLE,
    NO_DIMPLE_M,
    NO_FIRST,
    NO_FRICTION,
    NO_FX,
    NO_FZ,
    NO_INSERTION_M,
    NO_LATERAL_K,
    NO_LX,
    NO_LZ,
    NO_NORMAL,
    NO_RUPTURED,
    NO_SIZE,
    NO_TANGENTIAL,
    NO_TX,
    NO_TZ,
    NP_BOTTOM,
    NP_CUT_M,
    NP_CUT_RATIO,
    NP_DAHL_M,
    NP_FRICTION,
    NP_KAPPA,
    NP_LATERAL,
    NP_MIN_SIN,
    NP_MU,
    NP_SCALE,
    NP_SIZE,
    NP_WALL,
    NS_AX,
    NS_AY,
    NS_EX,
    NS_FRONT,
    NS_INSERTED,
    NS_LAST,
    NS_LAW_K,
    NS_RUPTURED,
    NS_SIZE,
    NS_TENT,
    NS_UX,
    NS_UZ,
    NT_CROSS,
    NT_DAHL,
    NT_SIZE,
    NW_CAPACITY,
    NW_CAPACITY_GRADIENT,
    NW_FORCE,
    NW_GRADIENT,
    NW_GRADIENT_BEHIND,
    NW_POST,
    NW_POST_GRADIENT,
    NW_RUPTURE_M,
    NW_SIZE,
    NW_STATE,
    pack_layers,
)
from .needle_kernels import (
    _chain_dimple,
    dimple_force,
    needle_law_kernel,
    needle_step_kernel,
    reset_track,
    rupture_insertion,
    start_track,
)

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
RENDER_STIFFNESS_N_PER_M = 1020.0
"""Stiffest slope (N/m) a Touch renders stably: its Z-axis figure (3D Systems' spec sheet, "stiffness ... Z > 1.02 N/mm",
the device side's ``TOUCH_MAX_STIFFNESS_N_PER_M``; repeated here because the model core imports nothing of the device
side, and tests/test_needle.py checks they agree). The withdrawal's fades are as short as this allows (below)."""
DAHL_LENGTH_M = 0.25e-3
"""Dahl presliding length ``x_0`` (issue 31; 1 mm before). Design bounded by the device: a reversal's stick stiffness
``2 F_c / x_0`` is 1.04 N/mm at 18 G lubricated and full depth (``F_c`` 0.13 N), the Touch's cap (a longer ``x_0``
only prolongs the outward push at a withdrawal's start; a shorter one the renderer would lengthen to its cap anyway).
Kim & Lee 2016 fit a Dahl law to needle friction in porcine tissue ("increases gradually ... due to deformation of
surrounding tissue"): a presliding length exists; their number was not read."""
CUT_PRESLIDING_M = 0.5e-3
"""``x_c,max``: the longest fade of the cutting force when the tip backs off the crack front (a position law instead
of a switch at zero speed). Each layer's own fade is ``x_c,j = min(x_c,max, beta F_p,j / K_render)``
(:data:`RENDER_STIFFNESS_N_PER_M`): the steepest the device renders without lagging the truth (``skin-sim needle-device``
counted commands above the true force after a reversal with a 0.1 mm fade). Physically the fade is far shorter: the
cutting force is carried by the crack front's cohesive zone, whose opening at peak traction is 2 MPa over
5000 MPa/mm = 0.4 um (Mohammadi et al. 2021's fitted cohesive law for human skin); no measured fade was found. 21 G
lubricated in fat: 0.16 mm (0.5 mm before)."""
TIP_FRICTION_COEFFICIENT = 0.5
"""``mu``: Coulomb friction of the needle's tip on the tented skin before a rupture. Derler & Gerhardt 2012 (Tribol
Lett 45:1-27, review of human skin friction): dry skin "relatively low and pressure-independent friction coefficients
(greater than 0.2 and typically around 0.5)"; moist or wet skin "typically >1". The typical dry value."""
POISSON_RATIO = 0.5
"""Tissue taken incompressible (the layered form's and the 3D reference's assumption)."""
TENT_SHEAR_RATIO = 2.0 * (1.0 - POISSON_RATIO) / (2.0 - POISSON_RATIO)
"""``kappa``: tangential over normal stiffness of an elastic contact, ``2 (1 - nu) / (2 - nu)`` (Mindlin 1949; Johnson,
Contact Mechanics, 1985, section 7.2): 2/3 for incompressible tissue. A stuck tip shears the tent sideways by what it
travels along the surface. The tent's stick stiffness is ``kappa`` times its normal secant stiffness at the rupture,
``k_t = kappa F_p / w_n*`` (a stated choice: a constant keeps the stuck tent a spring with a potential)."""
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
    tip_friction: float = TIP_FRICTION_COEFFICIENT
    tent_shear_ratio: float = TENT_SHEAR_RATIO
    render_stiffness_n_per_m: float = RENDER_STIFFNESS_N_PER_M

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

    def cut_fade_m(self, layer: int) -> float:
        """``x_c,j = min(x_c,max, beta F_p,j / K_render)`` (m): the cutting force's fade behind the front
        (:data:`CUT_PRESLIDING_M`)."""
        return min(self.cut_presliding_m, self.cutting_ratio * self.puncture_force_n(layer) / self.render_stiffness_n_per_m)

    def skate_angle_rad(self) -> float:
        """``atan(kappa / mu)``: the steepest axis angle at which an advancing tip skates on a *linear* tent (the stuck
        friction ``kappa N cot(theta)``); the layered tent stiffens, so the tip slips earlier and may stick again."""
        return math.atan2(self.tent_shear_ratio, self.tip_friction)


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
    bed_n: float = 0.0
    lateral_k_n_per_m: float = 0.0  # the bed's k = sum_i k_l E_i l_i (sideways stiffness at the tip: k / 2)
    normal_n: float = 0.0  # the tent's normal reaction N (along +z)
    tangential_n: float = 0.0  # the size of the tip's friction on the tent along the surface, |f_t| <= mu N
    tent_lateral_n: np.ndarray = field(default_factory=lambda: np.zeros(3))  # the tent's reaction off the axis


def pack_needle(cfg: TissueConfig, params: NeedleParams) -> tuple[np.ndarray, np.ndarray]:
    """``npar`` and ``nlp`` (:data:`~.layout.NP_SIZE`, :data:`~.layout.NL_SIZE`) of the needle ``params`` in ``cfg``."""
    nl = len(cfg.layers)
    npar = np.zeros(NP_SIZE)
    # the tent: a punch of radius a + l_f (module docstring), scaled from the calibrated punch as Sneddon's F ~ radius
    npar[NP_SCALE] = (0.5 * params.outer_diameter_m + cfg.foundation_length_m) / CALIBRATED_TOOL_RADIUS_M
    npar[NP_FRICTION] = params.lubrication_factor * params.shaft_shear_pa * math.pi * params.outer_diameter_m
    npar[NP_CUT_RATIO] = params.cutting_ratio
    npar[NP_DAHL_M] = params.dahl_length_m
    npar[NP_CUT_M] = params.cut_presliding_m
    npar[NP_MU] = params.tip_friction
    npar[NP_KAPPA] = params.tent_shear_ratio
    npar[NP_WALL] = WALL_STRAIN
    npar[NP_LATERAL] = LATERAL_FACTOR
    npar[NP_BOTTOM] = cfg.total_thickness_m
    npar[NP_MIN_SIN] = math.sin(MIN_ANGLE_RAD)
    nlp = np.zeros((NL_SIZE, nl))
    nlp[NL_FP] = [params.puncture_force_n(i) for i in range(nl)]
    nlp[NL_H] = [la.thickness_m for la in cfg.layers]
    nlp[NL_MODULUS] = youngs_moduli_pa(cfg)  # the live layers' (a stiffness change moves the bed with the dimple)
    nlp[NL_CUT_M] = [params.cut_fade_m(i) for i in range(nl)]
    # the tent's stick stiffness along the surface: kappa times the normal secant stiffness at the layer's rupture
    lp = pack_layers(cfg)
    nbuf = np.zeros((NB_SIZE, nl + 1))
    for i in range(nl):
        wn = _chain_dimple(nlp[NL_FP, i] / npar[NP_SCALE], i, lp, npar, nlp, nbuf)
        nlp[NL_TENT_K, i] = params.tent_shear_ratio * nlp[NL_FP, i] / wn if wn > 0.0 else 0.0
    return npar, nlp


def _vec3(v, what: str) -> tuple[float, float, float]:
    x, y, z = float(v[0]), float(v[1]), float(v[2])
    if not (math.isfinite(x) and math.isfinite(y) and math.isfinite(z)):
        raise ValueError(f"needle {what} must be finite, got ({x}, {y}, {z})")
    return x, y, z


class _Slot:
    """A scalar of a :class:`NeedleModel`'s ``nstate``, read as ``cast`` (an attribute of the reference)."""

    def __init__(self, slot: int, cast: type, doc: str):
        self.slot, self.cast, self.__doc__ = slot, cast, doc

    def __get__(self, obj, owner=None) -> Any:
        return self if obj is None else self.cast(obj.nstate[self.slot])

    def __set__(self, obj, value) -> None:
        obj.nstate[self.slot] = float(value)


class _View:
    """A vector of a :class:`NeedleModel`'s state arrays: a view (it changes with the state; assigning writes into it).
    ``track``: the law's cache of the rupture ahead depends on it, and is emptied when it is assigned."""

    def __init__(self, name: str, doc: str, track: bool = False):
        self.name, self.track, self.__doc__ = name, track, doc

    def __get__(self, obj, owner=None) -> Any:
        return self if obj is None else getattr(obj, self.name)

    def __set__(self, obj, value) -> None:
        getattr(obj, self.name)[:] = value
        if self.track:
            obj.nstate[NS_LAW_K] = 0.0


class NeedleModel:
    """A needle in the layered stack of ``cfg`` (module docstring); :meth:`step` per tick, :meth:`law` after it.

    The state lives in the arrays ``nstate`` and ``ntrack`` (:mod:`.layout`); the attributes ``inserted``,
    ``entry``, ``axis``, ``crossings``, ``ruptured``, ``front_m``, ``last_m`` and ``dahl`` read them (the vectors
    are views: they change with the state).
    """

    def __init__(self, cfg: TissueConfig, params: NeedleParams | None = None):
        self.cfg = equilibrium(cfg)
        self.params = params or NeedleParams()
        nl = len(self.cfg.layers)
        if nl != len(LAYER_NAMES):
            raise ValueError(f"the needle needs the {len(LAYER_NAMES)} layers {LAYER_NAMES}, got {nl}")
        self.lp = pack_layers(self.cfg)
        self.npar, self.nlp = pack_needle(self.cfg, self.params)
        self.nstate = np.zeros(NS_SIZE)
        self.ntrack = np.zeros((NT_SIZE, nl + 1))
        self.nbuf = np.zeros((NB_SIZE, nl + 1))
        self.nout = np.zeros(NO_SIZE)
        self.nlaw = np.zeros(NW_SIZE)
        self._bind()
        self.reset()

    def _bind(self) -> None:
        nl = self.nlp.shape[1]
        self._h = self.nlp[NL_H]
        self._ea = self.lp[LP_EA]
        self._n = self.lp[LP_N]
        self._moduli = self.nlp[NL_MODULUS]
        self._scale = float(self.npar[NP_SCALE])
        self._args = (self.lp, self.npar, self.nlp, self.nstate, self.ntrack, self.nbuf)
        self._entry = self.nstate[NS_EX : NS_EX + 3]
        self._axis = self.nstate[NS_UX : NS_UZ + 1]
        self._crossings = self.ntrack[NT_CROSS]
        self._dahl = self.ntrack[NT_DAHL, :nl]

    def reset(self, keep_tent: bool = False) -> None:
        """Needle out of the tissue: no track. ``keep_tent``: the tent's anchor is kept for the next track's start (a
        track restarted under a tip that still presses the same tent: its friction's stuck point is the skin's, not
        the track's)."""
        a = self.nstate[NS_AX : NS_TENT + 1].copy()
        reset_track(self.nstate, self.ntrack)
        if keep_tent:
            self.nstate[NS_AX : NS_TENT + 1] = a

    # --- the state, as the reference's attributes (read and write the state arrays) ---------------
    inserted = _Slot(NS_INSERTED, bool, "A track exists (the tip passed the surface).")
    ruptured = _Slot(NS_RUPTURED, int, "Layers ruptured along the track.")
    front_m = _Slot(NS_FRONT, float, "Crack front: the deepest insertion cut so far (m).")
    last_m = _Slot(NS_LAST, float, "Insertion at the last tick (m).")
    entry = _View("_entry", "Entry point of the track (m).", track=True)
    axis = _View("_axis", "Unit axis of the track toward the tip; (0, 0, -1) out of the tissue.", track=True)
    crossings = _View("_crossings", "Axis lengths ``t_j`` (m) from the entry to each layer's top, then the bottom.", track=True)
    dahl = _View("_dahl", "Dahl state of each layer's shaft friction.")

    # --- laws ---------------------------------------------------------------------------------
    def _start_track(self, tip: np.ndarray, axis: np.ndarray) -> bool:
        """Start a track at ``tip`` along the unit ``axis`` (:func:`~.needle_kernels.start_track`)."""
        x, y, z = _vec3(tip, "tip")
        return bool(start_track(x, y, z, *_vec3(axis, "axis"), self.lp, self.npar, self.nstate, self.ntrack, self.nbuf))

    def dimple_force_n(self, layer: int, w_m: float) -> float:
        """Normal reaction ``N`` (N) of the tented stack below ``layer``'s top pressed ``w_m`` along the axis by a tip
        on it (eq T1): the chain at the normal depth ``w sin(theta)``; the puncture criterion is ``N = F_p``."""
        return float(
            dimple_force(layer, float(w_m) * -float(self.nstate[NS_UZ]), 0.0, self.lp, self.npar, self.nlp, self.nbuf)[0]
        )

    @property
    def anchor(self) -> np.ndarray | None:
        """The tent's stuck point on the surface plane ``(x, y)`` (m), or None with no tent."""
        return self.nstate[NS_AX : NS_AY + 1].copy() if self.nstate[NS_TENT] else None

    def rupture_insertion_m(self) -> float:
        """Insertion ``L`` (m) at which the next intact layer ruptures: its dimple force reaches ``F_p`` (the series
        chain's law inverted at the threshold); inf when every layer is ruptured or the dimple never reaches it."""
        return float(rupture_insertion(*self._args))

    def copy(self) -> NeedleModel:
        """An independent copy (state arrays included; the parameter arrays are shared, read-only)."""
        c = object.__new__(NeedleModel)
        c.__dict__.update(self.__dict__)
        for name in ("nstate", "ntrack", "nbuf", "nout", "nlaw"):
            setattr(c, name, getattr(self, name).copy())
        c._bind()
        return c

    def law(self, tick: NeedleTick, tip_m) -> NeedleLaw | None:
        """The axial law at the tip ``tip_m`` after ``tick`` (the last :meth:`step`), for the local contact model:
        ``R_e`` and its slope, the rupture ahead and the line past it, and the Dahl friction's level, slope and state
        (``ContactModel.msg``; :func:`~.needle_kernels.needle_law_kernel`). None out of the tissue."""
        if not self.nstate[NS_INSERTED]:
            return None
        px, py, pz = _vec3(tip_m, "tip")
        re0 = tick.dimple_n + tick.cutting_n  # the slopes are of dimple and cutting; the bed's axial part added at x0
        needle_law_kernel(px, py, pz, tick.insertion_m, re0, tick.friction_n, tick.ruptured, *self._args, self.nlaw)
        v = self.nlaw.tolist()
        ux, uy, uz = self._axis.tolist()
        return NeedleLaw(
            axis=(ux, uy, uz),
            axial_force_n=v[NW_FORCE] + tick.bed_n,
            axial_gradient_n_per_m=v[NW_GRADIENT],
            axial_gradient_behind_n_per_m=v[NW_GRADIENT_BEHIND],
            rupture_distance_m=v[NW_RUPTURE_M],
            post_rupture_force_n=v[NW_POST],
            post_rupture_gradient_n_per_m=v[NW_POST_GRADIENT],
            friction_capacity_n=v[NW_CAPACITY],
            friction_capacity_gradient_n_per_m=v[NW_CAPACITY_GRADIENT],
            friction_state=v[NW_STATE],
            dahl_length_m=self.params.dahl_length_m,
        )

    def step(self, tip_m, axis) -> NeedleTick:
        """Advance to the tip position ``tip_m`` (m) with the needle along ``axis`` (vector toward the tip; its
        direction matters only when a track starts). A non-finite tip or axis is a ``ValueError``."""
        px, py, pz = _vec3(tip_m, "tip")
        ux, uy, uz = _vec3(axis, "axis")
        if not needle_step_kernel(px, py, pz, ux, uy, uz, *self._args, self.nout):
            return NeedleTick(np.zeros(3))
        o = self.nout.tolist()
        k, k0 = int(o[NO_RUPTURED]), int(o[NO_FIRST])
        return NeedleTick(
            force_n=np.array(o[NO_FX : NO_FZ + 1]),
            axial_n=o[NO_AXIAL],
            dimple_n=o[NO_DIMPLE],
            cutting_n=o[NO_CUT],
            friction_n=o[NO_FRICTION],
            lateral_n=np.array(o[NO_LX : NO_LZ + 1]),
            dimple_m=o[NO_DIMPLE_M],
            insertion_m=o[NO_INSERTION_M],
            ruptured=k,
            punctured=tuple(range(k0, k)),
            bed_n=o[NO_BED],
            lateral_k_n_per_m=o[NO_LATERAL_K],
            normal_n=o[NO_NORMAL],
            tangential_n=o[NO_TANGENTIAL],
            tent_lateral_n=np.array(o[NO_TX : NO_TZ + 1]),
        )


def warm_up(cfg: TissueConfig) -> None:
    """Compile (or load from numba's cache) every needle kernel and touch each path once: a track start, the dimple,
    the ruptures, cutting and friction, the law, a withdrawal. Loading the kernels from the cache at the first tick
    otherwise stalls it for milliseconds (:func:`~.skin_model.warm_up` does the same for the tissue)."""
    m = NeedleModel(cfg)
    for z in np.linspace(1e-4, -6e-3, 40).tolist() + [-5e-3, 1e-4]:
        tip = (0.0, 0.0, z)
        m.law(m.step(tip, (0.0, 0.0, -1.0)), tip)
    m.rupture_insertion_m()
    m.dimple_force_n(0, 1e-3)
    m.copy().reset()
