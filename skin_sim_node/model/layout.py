"""The kernels' argument layout: what each slot of the grouped arrays holds, and their packing.

A tick kernel takes a few arrays instead of some forty scalars and vectors (the numba dispatcher
pays about 0.1 us per argument). Their row and slot indices are defined here once, as
compile-time constants of the kernels; :func:`pack` builds every array for one
:class:`~skin_sim_node.model.config.TissueConfig` and its :class:`~skin_sim_node.model.modal.ModalBasis`.
Units are SI; depths and displacements are positive downward (into the tissue). ``L`` is the
number of layers, ``K`` of modes in the basis, ``V`` of its levels, ``M`` the largest mode index.

numba compiles these constants into every kernel that reads them, and its cache is checked against the
kernel's own file only: after changing one here, clear the ``__pycache__`` folders of ``model/``.

=========  ===================  ==================================================================
array      shape                holds
=========  ===================  ==================================================================
``lp``     (LP_SIZE, L)         per-layer properties and the interfaces (``LP_*``)
``sp``     (SP_SIZE,)           scalars of the tissue, the tool and the level of detail (``SP_*``)
``bmodes`` (V + L, K)           rows [0, V): ``beta`` of each level; rows [V, V + L): ``lambda``
``bvec``   (V + L,)             [0, V): truncation bound per level; [V, V + L): damping rate gamma
``blev``   (2, V) int64         modes in each level's prefix, largest m or n of each level
``bk``     (2, K) int64         ``mode_m``, ``mode_n`` (1-based)
``mstate`` (6, L, K)            modal amplitudes q, velocities v, cached propagator P11, P12, P21, P22
``lstate`` (LS_SIZE, L)         per-layer float state (``LS_*``)
``istate`` (IS_SIZE, L) int64   per-layer int state (``IS_*``)
``aux``    (AUX_SIZE, L + 1)    per-layer scratch of a tick (``AUX_*``)
``sbuf``   (2, M + 1)           sine tables in x and y
``out``    (OUT_SIZE,)          results of a tick (``OUT_*``), also the contact state the layered form carries
=========  ===================  ==================================================================

The needle (issue 22, :mod:`.needle_kernels`) reads ``lp`` and has its own arrays, in the last section below:

==========  ===================  =================================================================
array       shape                holds
==========  ===================  =================================================================
``npar``    (NP_SIZE,)           the needle's scalar parameters (``NP_*``)
``nlp``     (NL_SIZE, L)         its per-layer parameters: thresholds, thicknesses, moduli (``NL_*``)
``nstate``  (NS_SIZE,)           the track: entry, axis, ruptured layers, front, law cache (``NS_*``)
``ntrack``  (NT_SIZE, L + 1)     crossings along the axis and Dahl states (``NT_*``)
``nbuf``    (NB_SIZE, L + 1)     scratch of the chain and the interfaces (``NB_*``)
``nout``    (NO_SIZE,)           one tick's force and its parts (``NO_*``)
``nlaw``    (NW_SIZE,)           the axial law at the tip (``NW_*``)
==========  ===================  =================================================================
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from .calibration import WALL_STRAIN
from .config import TissueConfig
from .contact import Indenter
from .modal import ModalBasis

FLAG_CONTACT = 1
"""Step flag: the tool is in contact with the tissue."""
FLAG_BOTTOMED = 2
"""Step flag: the tool is below the tissue bottom (paper form: its depth is clamped there)."""
FLAG_LAYER_BOUND = 4
"""Step flag: a layer's compression left ``[0, thickness]`` (paper form) or passed the wall strain (layered form)."""
FLAG_SEPARATED = 8
"""Step flag: the tool retracted faster than the tissue follows; the unilateral contact is released."""
FLAG_OFF_SHEET = 16
"""Step flag: the tool tip is outside the sheet's x-y extent (layered form: its contact disk does not reach the sheet)."""

OUT_FORCE_N = 0
OUT_STRESS_PA = 1
OUT_DEPTH_M = 2
OUT_N_AFFECTED = 3
OUT_SURFACE_M = 4
OUT_SETTLED = 5
OUT_FX = 6
OUT_FY = 7
OUT_FZ = 8
OUT_NX = 9
OUT_NY = 10
OUT_NZ = 11
OUT_RADIUS_M = 12
OUT_DFN_DX = 13
OUT_DFN_DY = 14
OUT_DFN_DZ = 15
OUT_T = 16
OUT_ZX = 17
OUT_ZY = 18
OUT_ZZ = 19
OUT_ANCHORED = 20
OUT_SLIP_M = 21
OUT_HOLD = 22
OUT_SIZE = 23
"""Slots of ``out``, shape (OUT_SIZE,), float64: what a tick kernel writes.

==================  ======  ===================================================================
slot                unit    holds
==================  ======  ===================================================================
OUT_FORCE_N         N       normal reaction force magnitude (what ``SkinModel.step`` returns)
OUT_STRESS_PA       Pa      Reuss stress (paper form, eq 6); normal force over the contact area (layered)
OUT_DEPTH_M         m       tool depth of the force law (paper form: clamped at the bottom); 0 out of contact
OUT_N_AFFECTED      -       layers engaged (Fig 3 in the paper form; all in the layered form), 0 out of contact
OUT_SURFACE_M       m       surface displacement under the tool before this tick
OUT_SETTLED         -       1.0: no layer driven and every layer's displacement bound below ``settle_tol``
OUT_FX .. OUT_FZ    N       reaction force vector on the tool, tissue frame
OUT_NX .. OUT_NZ    -       unit contact normal (``+z`` out of contact); the layered form keeps it over a contact
OUT_RADIUS_M        m       contact radius, 0 out of contact
OUT_DFN_DX .. _DZ   N/m     gradient of the normal force magnitude w.r.t. the tool position (layered form)
OUT_T               N       layered form: chain force per unit load scale, the Newton warm start of the next tick
OUT_ZX .. OUT_ZZ    m       layered form: the friction's anchor (adhesion point, :mod:`.friction`), tissue frame
OUT_ANCHORED        -       1.0: the anchor holds (in contact, or kept through a release); 0.0: none
OUT_SLIP_M          m       how far the anchor slipped at the last tick (0 while the skin sticks)
OUT_HOLD            -       2.0 after :meth:`SkinModel.release` (a stall's tick or a teleport), 1.0 after a tick out
                            of contact that followed one: the next contact keeps the anchor if it lands within the
                            contact radius of it; a tick out of contact without a release (a true lift-off) clears it
==================  ======  ===================================================================

The anchor slots are tissue state, not a tick's result: the idle path of ``SkinModel.step`` leaves them.
"""

LP_K = 0
LP_B = 1
LP_AREA = 2
LP_EA = 3
LP_N = 4
LP_IF_MEAN = 5
LP_IF_AMP = 6
LP_IF_KX = 7
LP_IF_KY = 8
LP_G1 = 9
LP_TAU1 = 10
LP_G2 = 11
LP_TAU2 = 12
LP_SIZE = 13
"""Rows of ``lp``, shape (LP_SIZE, L), float64: per-layer properties; the ``LP_IF_*`` rows hold interface ``j``
(the top of layer ``j + 1``, section II.C) in column ``j``, and column ``L - 1`` is unused there.

============  ======  =====================================================================
row           unit    holds
============  ======  =====================================================================
LP_K          N/m     Kelvin-Voigt spring ``k`` (eq 6)
LP_B          N s/m   Kelvin-Voigt damper ``b`` (eq 6)
LP_AREA       m^2     loaded area ``A`` (eq 6, paper form)
LP_EA         N       ``k`` times the layer's mean thickness: its modulus times the tool area (layered form)
LP_N          -       stiffening exponent ``n`` of the compression law (layered form)
LP_IF_MEAN    m       interface mean depth ``D_j``
LP_IF_AMP     m       interface egg-carton amplitude ``A_j``
LP_IF_KX      1/m     ``2 pi / wavelength_x`` of the interface
LP_IF_KY      1/m     ``2 pi / wavelength_y`` of the interface
============  ======  =====================================================================
"""

SP_BOTTOM = 0
SP_HALF_X = 1
SP_HALF_Y = 2
SP_PATCH_A = 3
SP_PATCH_B = 4
SP_MODE_TOL = 5
SP_SETTLE_TOL = 6
SP_SKIP_SETTLED = 7
SP_TOOL_R = 8
SP_SPHERE = 9
SP_MU = 10
SP_K_T = 11
SP_WALL = 12
SP_COS = 13
SP_SIN = 14
SP_SIZE = 15
"""Slots of ``sp``, shape (SP_SIZE,), float64: scalars of the tissue, the tool and the level of detail.

===============  ======  ==================================================================
slot             unit    holds
===============  ======  ==================================================================
SP_BOTTOM        m       depth of the tissue bottom (the sum of the layer thicknesses)
SP_HALF_X        m       half the sheet's extent in x
SP_HALF_Y        m       half the sheet's extent in y
SP_PATCH_A       m       modal patch side ``a`` in x (eq 2)
SP_PATCH_B       m       modal patch side ``b`` in y
SP_MODE_TOL      m       ``lod.tolerance_m``: truncation allowed when choosing or shedding modes
SP_SETTLE_TOL    m       displacement bound below which a free layer is settled; 0: not tracked
SP_SKIP_SETTLED  -       1.0: settled layers are set to rest and skipped (``lod.affected_layers``)
SP_TOOL_R        m       tool radius: flat punch radius or sphere radius
SP_SPHERE        -       1.0: spherical tip, 0.0: flat punch
SP_MU            -       Coulomb friction coefficient
SP_K_T           N/m     tangential (presliding) stiffness of the skin under the tool (:mod:`.friction`)
SP_WALL          -       strain beyond which the compression law continues along its tangent (the wall)
SP_COS, SP_SIN   -       cosine and sine of ``anisotropy.angle_rad``: the patch's first side along the tension lines
===============  ======  ==================================================================
"""

LS_COMP = 0
LS_DROPPED = 1
LS_AMP = 2
LS_PROP_DT = 3
LS_CX = 4
LS_CY = 5
LS_FE = 6
LS_H1 = 7
LS_H2 = 8
LS_THICK = 9
LS_SIZE = 10
"""Rows of ``lstate``, shape (LS_SIZE, L), float64: per-layer float state carried between ticks.

===========  ======  ========================================================================
row          unit    holds
===========  ======  ========================================================================
LS_COMP      m       compression of the layer under the tool (0 when free)
LS_DROPPED   m       displacement bound shed with outer modes since the layer was last driven
LS_AMP       m       bound on a free layer's future displacement; inf while driven
LS_PROP_DT   s       ``dt`` of the cached propagator (NaN: none yet)
LS_CX        m       patch centre x (where the layer was last driven)
LS_CY        m       patch centre y
LS_FE        N       layered form: the layer's elastic (equilibrium) force ``EA phi(c / h)`` at the last tick
LS_H1        N       layered form: force of the first Prony arm (quasi-linear viscoelasticity)
LS_H2        N       layered form: force of the second Prony arm
LS_THICK     m       layered form: the layer's thickness under the tool at the last contact (its recovery uses it)
===========  ======  ========================================================================
"""

IS_DRIVEN = 0
IS_LEVEL = 1
IS_ACTIVE = 2
IS_PROP_K = 3
IS_SIZE = 4
"""Rows of ``istate``, shape (IS_SIZE, L), int64: per-layer integer state carried between ticks.

==========  =====================================================================================
row         holds
==========  =====================================================================================
IS_DRIVEN   1: the layer is driven by the tool this tick (quasi-static, eq 3); 0: it relaxes freely
IS_LEVEL    index into the basis levels: the layer uses the first ``blev[0, level]`` modes
IS_ACTIVE   1: the layer is evolved; 0: at rest and skipped (``lod.affected_layers``)
IS_PROP_K   modes the cached propagator covers
==========  =====================================================================================
"""

AUX_BOUNDS = 0
AUX_THICK = 1
AUX_SPLIT = 2
AUX_C_OLD = 3
AUX_C = 4
AUX_G = 5
AUX_DBX = 6
AUX_DBY = 7
AUX_DBD = 8
AUX_EA = 9
AUX_OFF = 10
AUX_SIZE = 11
"""Rows of ``aux``, shape (AUX_SIZE, L + 1), float64: scratch of one tick (only ``AUX_BOUNDS`` uses column L).

==========  =====  ===========================================================================
row         unit   holds
==========  =====  ===========================================================================
AUX_BOUNDS  m      depths of the layer tops under the tool, then the bottom (L + 1 values)
AUX_THICK   m      layer thicknesses under the tool
AUX_SPLIT   m      Reuss compressions (paper form, eq 6)
AUX_C_OLD   m      chain compressions at the previous tick (layered form)
AUX_C       m      chain compressions now (layered form)
AUX_G       N/m    slope ``dT/dc_i`` of each layer's backward-Euler residual (layered form)
AUX_DBX     -      d(interface depth)/dx of the disk-averaged interfaces (layered form)
AUX_DBY     -      d(interface depth)/dy
AUX_DBD     -      d(interface depth)/d(tool depth) through the contact radius (sphere)
AUX_EA      N      the layer's instantaneous ``EA (1 + a_1 g_1 + a_2 g_2)`` of this tick's backward-Euler step
AUX_OFF     N      the Prony arms' force carried into this tick, ``sum_j a_j (H_j - g_j f_e,old)``
==========  =====  ===========================================================================
"""


# --- the needle (issue 22; kernels in needle_kernels.py, packing in needle.py) ----------------------------------------
# The needle's arrays sit beside the tissue's: its kernels also read ``lp`` (LP_EA, LP_N, LP_IF_*) for the chain and
# the interfaces, so the layer properties stay in one place.

NP_SCALE = 0
NP_FRICTION = 1
NP_CUT_RATIO = 2
NP_DAHL_M = 3
NP_CUT_M = 4
NP_WALL = 5
NP_LATERAL = 6
NP_BOTTOM = 7
NP_MIN_SIN = 8
NP_MU = 9
NP_KAPPA = 10
NP_SIZE = 11
"""Slots of ``npar``, shape (NP_SIZE,), float64: the needle's scalar parameters (constant over a run).

=================  ======  ======================================================================================
slot               unit    holds
=================  ======  ======================================================================================
NP_SCALE           -       dimple force scale: the needle's radius over the calibrated punch's (Sneddon)
NP_FRICTION        N/m     Dahl friction level per inserted length, ``lambda tau pi d``
NP_CUT_RATIO       -       ``beta``: cutting force over the puncture threshold
NP_DAHL_M          m       Dahl presliding length ``x_0``
NP_CUT_M           m       longest cutting fade ``x_c,max`` (each layer's own ``x_c,j`` is ``NL_CUT_M``)
NP_WALL            -       the compression law's wall strain (the chain of the dimple)
NP_LATERAL         -       ``k_l``: Winkler modulus per length over the layer's Young's modulus
NP_BOTTOM          m       depth of the tissue bottom (the last crossing's surface)
NP_MIN_SIN         -       sine of the shallowest angle below the surface that starts a track
NP_MU              -       ``mu``: Coulomb friction coefficient of the tip on the tented skin (before a rupture)
NP_KAPPA           -       ``kappa``: the tent's tangential over normal stiffness (Mindlin's ratio, stick)
=================  ======  ======================================================================================
"""

NL_FP = 0
NL_H = 1
NL_MODULUS = 2
NL_ZERO = 3
NL_CUT_M = 4
NL_TENT_K = 5
NL_SIZE = 6
"""Rows of ``nlp``, shape (NL_SIZE, L), float64: the needle's per-layer parameters.

==========  =====  ===========================================================================================
row         unit   holds
==========  =====  ===========================================================================================
NL_FP       N      puncture threshold ``F_p = lambda Gamma d`` of each layer
NL_H        m      mean thickness of each layer (the dimple's chain)
NL_MODULUS  Pa     Young's modulus of each layer (the lateral bed)
NL_ZERO     -      zeros: the dimple chain's dampers, old compressions and Prony offsets (its equilibrium law)
NL_CUT_M    m      ``x_c,j``: the layer's cutting force fades over this distance behind the crack front
NL_TENT_K   N/m    ``k_t,j = kappa F_p,j / w*_j``: the tangential (stick) stiffness of layer ``j``'s tent
==========  =====  ===========================================================================================
"""

NS_INSERTED = 0
NS_EX = 1
NS_EY = 2
NS_EZ = 3
NS_UX = 4
NS_UY = 5
NS_UZ = 6
NS_RUPTURED = 7
NS_FRONT = 8
NS_LAST = 9
NS_T = 10
NS_LAW_K = 11
NS_LAW_FRONT = 12
NS_LAW_RUPTURE = 13
NS_LAW_POST = 14
NS_LAW_POST_GRADIENT = 15
NS_AX = 16
NS_AY = 17
NS_TENT = 18
NS_DEVZ = 19
NS_LAW_DEV = 20
NS_SIZE = 21
"""Slots of ``nstate``, shape (NS_SIZE,), float64: the needle's track, carried between ticks.

======================  ======  ===========================================================================================
slot                    unit    holds
======================  ======  ===========================================================================================
NS_INSERTED             -       1.0: a track exists (the tip passed the surface); 0.0: out of the tissue
NS_EX .. NS_EZ          m       entry point ``e`` of the track (on the rest surface)
NS_UX .. NS_UZ          -       unit axis ``u_e`` of the track (toward the tip); (0, 0, -1) out of the tissue
NS_RUPTURED             -       layers ruptured along the track (an integer, stored as float)
NS_FRONT                m       crack front: the deepest insertion cut so far
NS_LAST                 m       insertion at the last tick (the Dahl states' step)
NS_T                    N       chain force ``T`` of the current dimple (before ``NP_SCALE``): the next tick's Newton start
NS_LAW_K                -       the law's cache of the rupture ahead: valid for ``k + 1`` ruptured layers ``k`` (0: empty)
NS_LAW_FRONT            m       ... and this crack front (the line past the rupture depends on track, ``k`` and front)
NS_LAW_RUPTURE          m       cached insertion of the next rupture (inf: none)
NS_LAW_POST             N       cached ``R_e`` just past it
NS_LAW_POST_GRADIENT    N/m     cached slope there
NS_AX, NS_AY            m       the tent's stuck point (anchor) on the surface plane: the tip's friction is ``-k_t (p - a)``
NS_TENT                 -       1.0: the anchor holds a tent (a dimple is pressed); 0.0: none (the next contact sets it)
NS_DEVZ                 m       the tip's height off the axis at the last tick, ``delta_z`` (the normal depth's offset)
NS_LAW_DEV              m       ... and this ``delta_z`` (the rupture ahead depends on it)
======================  ======  ===========================================================================================
"""

NT_CROSS = 0
NT_DAHL = 1
NT_SIZE = 2
"""Rows of ``ntrack``, shape (NT_SIZE, L + 1), float64: the needle's per-layer state.

=========  =====  ============================================================================================
row        unit   holds
=========  =====  ============================================================================================
NT_CROSS   m      axis length from the entry to the top of layer ``j`` (column ``L``: to the bottom)
NT_DAHL    -      Dahl state ``s_i`` in ``[-1, 1]`` of each ruptured layer's shaft friction (column ``L`` unused)
=========  =====  ============================================================================================
"""

NB_C = 0
NB_G = 1
NB_BOUNDS = 2
NB_SIZE = 3
"""Rows of ``nbuf``, shape (NB_SIZE, L + 1), float64: the needle kernels' scratch (no state).

==========  =====  ===========================================================================================
row         unit   holds
==========  =====  ===========================================================================================
NB_C        m      compressions of the dimple's chain (columns ``k..L-1``)
NB_G        N/m    their slopes
NB_BOUNDS   m      depths of the layer tops at a point of the axis, then the bottom (``paper.layer_bounds``)
==========  =====  ===========================================================================================
"""

NO_FX = 0
NO_FY = 1
NO_FZ = 2
NO_AXIAL = 3
NO_DIMPLE = 4
NO_CUT = 5
NO_FRICTION = 6
NO_LX = 7
NO_LY = 8
NO_LZ = 9
NO_DIMPLE_M = 10
NO_INSERTION_M = 11
NO_RUPTURED = 12
NO_FIRST = 13
NO_BED = 14
NO_LATERAL_K = 15
NO_NORMAL = 16
NO_TANGENTIAL = 17
NO_TX = 18
NO_TY = 19
NO_TZ = 20
NO_SIZE = 21
"""Slots of ``nout``, shape (NO_SIZE,), float64: what the needle's step kernel writes (``NeedleTick``).

==================  ====  =========================================================================================
slot                unit  holds
==================  ====  =========================================================================================
NO_FX .. NO_FZ      N     force on the needle, ``-R u_e`` plus the lateral force, tissue frame
NO_AXIAL            N     axial resistance ``R`` (> 0 resists insertion)
NO_DIMPLE           N     its dimple part
NO_CUT              N     its cutting part
NO_FRICTION         N     its shaft friction part (signed)
NO_LX .. NO_LZ      N     lateral force of the bed along the shaft
NO_DIMPLE_M         m     axial dimple of the next intact layer
NO_INSERTION_M      m     insertion ``L`` along the track (0 out of the tissue)
NO_RUPTURED         -     layers ruptured after the tick
NO_FIRST            -     layers ruptured before it: layers ``NO_FIRST .. NO_RUPTURED - 1`` ruptured this tick
NO_BED              N     the bed's axial part ``k'(L) |delta|^2 / 4`` (the lateral bed is the gradient of a potential)
NO_LATERAL_K        N/m   the bed's ``k = sum_i k_l E_i l_i`` (its sideways stiffness at the tip is ``k / 2``)
NO_NORMAL           N     the tent's normal reaction ``N`` (along the surface normal +z; 0 with no dimple)
NO_TANGENTIAL       N     its tangential reaction along the surface, ``c N`` (> 0 against the tip's advance)
NO_TX .. NO_TZ      N     the tent's reaction off the axis, ``F_tent - (F_tent . u) u`` (in the force, not the bed)
==================  ====  =========================================================================================
"""

NW_FORCE = 0
NW_GRADIENT = 1
NW_RUPTURE_M = 2
NW_POST = 3
NW_POST_GRADIENT = 4
NW_CAPACITY = 5
NW_CAPACITY_GRADIENT = 6
NW_STATE = 7
NW_GRADIENT_BEHIND = 8
NW_SIZE = 9
"""Slots of ``nlaw``, shape (NW_SIZE,), float64: the needle's axial law at the tip (``msgs_schema`` ``NeedleLaw``).

=====================  =====  =====================================================================================
slot                   unit   holds
=====================  =====  =====================================================================================
NW_FORCE               N      ``R_e``: dimple plus cutting at the tip
NW_GRADIENT            N/m    its slope along the axis (0 when a step ahead ruptures)
NW_RUPTURE_M           m      distance along the axis to the next rupture (0: none ahead)
NW_POST                N      ``R_e`` just past that rupture
NW_POST_GRADIENT       N/m    its slope there
NW_CAPACITY            N      Dahl friction's Coulomb level ``F_c`` over the inserted length
NW_CAPACITY_GRADIENT   N/m    its growth per inserted length
NW_STATE               -      Dahl state ``z = F_f / F_c`` in ``[-1, 1]``
NW_GRADIENT_BEHIND     N/m    ``R_e``'s slope behind the tip (the cutting force's fade behind the crack front)
=====================  =====  =====================================================================================
"""


def settle_tolerance_m(cfg: TissueConfig) -> float:
    """``SP_SETTLE_TOL``: ``lod.tolerance_m`` when a lever needs the settled state (affected layers, idle), else 0."""
    lod = cfg.lod
    return lod.tolerance_m if (lod.affected_layers or lod.idle) else 0.0


def pack_layers(cfg: TissueConfig) -> np.ndarray:
    """``lp`` (see :data:`LP_SIZE`) of ``cfg``."""
    layers = cfg.layers
    lp = np.zeros((LP_SIZE, len(layers)))
    lp[LP_K] = [la.stiffness_n_per_m for la in layers]
    lp[LP_B] = [la.damping_n_s_per_m for la in layers]
    lp[LP_AREA] = [la.area_m2 for la in layers]
    lp[LP_EA] = [la.stiffness_n_per_m * la.thickness_m for la in layers]
    lp[LP_N] = [la.stiffening for la in layers]
    n_i = len(cfg.interfaces)
    lp[LP_IF_MEAN, :n_i] = [i.mean_depth_m for i in cfg.interfaces]
    lp[LP_IF_AMP, :n_i] = [i.amplitude_m for i in cfg.interfaces]
    lp[LP_IF_KX, :n_i] = [2 * math.pi / i.wavelength_x_m for i in cfg.interfaces]
    lp[LP_IF_KY, :n_i] = [2 * math.pi / i.wavelength_y_m for i in cfg.interfaces]
    ve = cfg.viscoelastic
    lp[LP_G1], lp[LP_TAU1], lp[LP_G2], lp[LP_TAU2] = ve.g1, ve.tau1_s, ve.g2, ve.tau2_s
    return lp


def pack_scalars(cfg: TissueConfig, indenter: Indenter | None = None) -> np.ndarray:
    """``sp`` (see :data:`SP_SIZE`) of ``cfg`` pressed by ``indenter`` (default: the configuration's punch)."""
    indenter = Indenter.of(cfg) if indenter is None else indenter
    sp = np.zeros(SP_SIZE)
    sx, sy = cfg.sheet_size_m
    sp[SP_BOTTOM] = cfg.total_thickness_m
    sp[SP_HALF_X], sp[SP_HALF_Y] = 0.5 * sx, 0.5 * sy
    sp[SP_PATCH_A], sp[SP_PATCH_B] = cfg.patch_size_m
    sp[SP_MODE_TOL] = cfg.lod.tolerance_m
    sp[SP_SETTLE_TOL] = settle_tolerance_m(cfg)
    sp[SP_SKIP_SETTLED] = 1.0 if cfg.lod.affected_layers else 0.0
    sp[SP_TOOL_R] = indenter.radius_m
    sp[SP_SPHERE] = 1.0 if indenter.sphere else 0.0
    sp[SP_MU] = cfg.friction_coefficient
    sp[SP_K_T] = cfg.tangential_stiffness_n_per_m
    sp[SP_WALL] = WALL_STRAIN
    sp[SP_COS] = math.cos(cfg.anisotropy_angle_rad)
    sp[SP_SIN] = math.sin(cfg.anisotropy_angle_rad)
    return sp


@dataclass(frozen=True)
class KernelArrays:
    """Every array a tick kernel takes, for one configuration (module docstring for shapes and contents).

    The state arrays (``mstate``, ``lstate``, ``istate``, ``out``) are the model's state; :class:`SkinModel`
    keeps named views of their rows. :attr:`args` is the tail of a tick kernel's arguments, in order.
    """

    lp: np.ndarray
    sp: np.ndarray
    bmodes: np.ndarray
    bvec: np.ndarray
    blev: np.ndarray
    bk: np.ndarray
    mstate: np.ndarray
    lstate: np.ndarray
    istate: np.ndarray
    aux: np.ndarray
    sbuf: np.ndarray
    out: np.ndarray

    @property
    def args(self) -> tuple:
        """``(lp, sp, bmodes, bvec, blev, bk, mstate, lstate, istate, aux, sbuf, out)``."""
        return (
            self.lp,
            self.sp,
            self.bmodes,
            self.bvec,
            self.blev,
            self.bk,
            self.mstate,
            self.lstate,
            self.istate,
            self.aux,
            self.sbuf,
            self.out,
        )


class Form:
    """A tissue form bound to one model's kernel arrays: :class:`SkinModel` chooses its form once, at construction.

    Subclasses (:class:`~.paper.PaperForm`, :class:`~.layered.LayeredForm`) give :meth:`tick` and :meth:`tangent`.

    Parameters
    ----------
    arrays : KernelArrays
        The model's arrays (:func:`pack`).
    cfg : TissueConfig
        Its configuration.
    """

    name = ""

    def __init__(self, arrays: KernelArrays, cfg: TissueConfig):
        self._args = arrays.args
        self._out = arrays.out

    def tick(self, x, y, z, vx, vy, vz, dt, restart=False) -> int:
        """The form's tick kernel at the tool position ``(x, y, z)`` (m) and velocity (m/s); returns the flags.
        ``restart``: contact restarts after an unknown time (the layered form's viscoelastic arms are relaxed)."""
        raise NotImplementedError

    def tangent(self, flags: int):
        """The :class:`~.contact.ContactTangent` of the last tick (``flags``: its flags)."""
        raise NotImplementedError


def pack(cfg: TissueConfig, basis: ModalBasis, indenter: Indenter | None = None) -> KernelArrays:
    """The kernel arrays of ``cfg`` with its modal ``basis``, pressed by ``indenter`` (default: the configuration's
    punch); the state is zero (no cached propagator)."""
    n_l = len(cfg.layers)
    nv = basis.level_modes.size
    bmodes = np.ascontiguousarray(np.vstack([basis.beta_table, basis.lam]))
    assert bmodes.shape[0] == nv + n_l
    lstate = np.zeros((LS_SIZE, n_l))
    lstate[LS_PROP_DT] = np.nan
    return KernelArrays(
        lp=pack_layers(cfg),
        sp=pack_scalars(cfg, indenter),
        bmodes=bmodes,
        bvec=np.concatenate([basis.trunc_err, basis.gamma]),
        blev=np.ascontiguousarray(np.vstack([basis.k_prefix, basis.m_lim]).astype(np.int64)),
        bk=np.ascontiguousarray(np.vstack([basis.mode_m, basis.mode_n]).astype(np.int64)),
        mstate=np.zeros((6, n_l, basis.n_modes)),
        lstate=lstate,
        istate=np.zeros((IS_SIZE, n_l), dtype=np.int64),
        aux=np.zeros((AUX_SIZE, n_l + 1)),
        sbuf=np.zeros((2, int(basis.m_lim.max()) + 1)),
        out=np.zeros(OUT_SIZE),
    )
