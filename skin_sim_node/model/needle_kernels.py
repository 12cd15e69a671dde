"""The needle's kernels (issue 22): track start, one tick of the axial and lateral force, and the law at the tip.

The physics is :mod:`.needle`'s (its module docstring and docs/needle.md): a dimple of the next intact layer by the
layered form's equilibrium series chain (:func:`~.layered_law.chain_solve`), puncture at ``F_p = lambda Gamma d`` with a
cascade and a latched track, a cutting ramp behind the crack front, Dahl shaft friction per ruptured layer and a
Winkler bed sideways. The crossings of the axis with the egg-carton interfaces (section II.C) use the point depths of
:func:`~.paper.layer_bounds`.

Kernel style of :mod:`.modal_kernels`: ``@njit(**JIT_OPTIONS)`` (``cache=True, nogil=True``, defined once here), plain
arrays and scalars, outputs
preallocated by the caller (a tick allocates nothing). The arrays (``lp`` of the tissue, ``npar``, ``nlp``,
``nstate``, ``ntrack``, ``nbuf``, ``nout``, ``nlaw``) are described in :mod:`.layout`; :class:`.needle.NeedleModel`
packs and binds them. Each kernel is tested compiled and as ``.py_func`` against the pure-NumPy reference
:class:`.needle_reference.NumpyNeedleModel` (tests/test_needle_kernels.py).

Every kernel that evaluates the axial law at an insertion (:func:`axial_at`) is a pure function of the state: the
law's look-ahead (a step ahead for the slope, the two steps past the next rupture) runs it on the state as it is,
instead of stepping copies of the model.
"""

from __future__ import annotations

import math
from typing import Any

from numba import njit

from .layered_law import chain_solve, layer_compression
from .layout import (
    LP_EA,
    LP_IF_AMP,
    LP_IF_KX,
    LP_IF_KY,
    LP_IF_MEAN,
    LP_N,
    NB_BOUNDS,
    NB_C,
    NB_G,
    NL_CUT_M,
    NL_FP,
    NL_H,
    NL_MODULUS,
    NL_ZERO,
    NO_AXIAL,
    NO_BED,
    NO_CUT,
    NO_DIMPLE,
    NO_DIMPLE_M,
    NO_FIRST,
    NO_FRICTION,
    NO_FX,
    NO_FY,
    NO_FZ,
    NO_INSERTION_M,
    NO_LATERAL_K,
    NO_LX,
    NO_LY,
    NO_LZ,
    NO_NORMAL,
    NO_RUPTURED,
    NO_TANGENTIAL,
    NO_TX,
    NO_TY,
    NO_TZ,
    NP_BOTTOM,
    NP_CUT_RATIO,
    NP_DAHL_M,
    NP_FRICTION,
    NP_KAPPA,
    NP_LATERAL,
    NP_MIN_SIN,
    NP_MU,
    NP_SCALE,
    NP_WALL,
    NS_EX,
    NS_EY,
    NS_EZ,
    NS_FRONT,
    NS_INSERTED,
    NS_LAST,
    NS_LAW_FRONT,
    NS_LAW_K,
    NS_LAW_POST,
    NS_LAW_POST_GRADIENT,
    NS_LAW_RUPTURE,
    NS_LAW_SLIP,
    NS_RUPTURED,
    NS_SLIP,
    NS_T,
    NS_UX,
    NS_UY,
    NS_UZ,
    NT_CROSS,
    NT_DAHL,
    NW_CAPACITY,
    NW_CAPACITY_GRADIENT,
    NW_FORCE,
    NW_GRADIENT,
    NW_GRADIENT_BEHIND,
    NW_POST,
    NW_POST_GRADIENT,
    NW_RUPTURE_M,
    NW_STATE,
)
from .paper import layer_bounds

JIT_OPTIONS: dict[str, Any] = {"cache": True, "nogil": True}
"""The numba options of every needle kernel (one place: cached compilation, the GIL released)."""

SCAN_STEP_M = 2e-6
"""Smallest depth step (m) of the march along the axis to an interface: two crossings closer than this may be taken
as none (the reference's scan grid; a hundredth of the epidermis-dermis interface's 200 um wavelength)."""
LAW_STEP_M = 1e-6
"""Axial step (m) of the law's finite differences (slope at the tip, slope past the rupture)."""
RUPTURE_MARGIN_M = 1e-9
"""Added to the distance to the rupture (m): the rupture is reached, not approached, at that distance."""
POST_MARGIN_M = 1e-7
"""Past the rupture distance (m), where the post-rupture line is evaluated (the step there does rupture)."""
MAX_DIMPLE_M = 1.0
"""Largest axial dimple (m) searched for a rupture: beyond it the layer is taken never to rupture (inf)."""


@njit(**JIT_OPTIONS)
def reset_track(nstate, ntrack):
    """Clear the track: the needle is out of the tissue (``nstate``, ``ntrack`` as after packing).

    Parameters
    ----------
    nstate : ndarray, shape (NS_SIZE,)
        Written: not inserted, entry 0, axis (0, 0, -1), nothing ruptured, front, last insertion and warm start 0.
    ntrack : ndarray, shape (NT_SIZE, L + 1)
        Written: zeros (crossings and Dahl states).
    """
    nstate[:] = 0.0
    nstate[NS_UZ] = -1.0
    ntrack[:, :] = 0.0


@njit(**JIT_OPTIONS)
def axis_gap(s, j, lp, npar, nstate, nbuf):
    """Depth below layer ``j``'s top of the axis point at length ``s`` from the entry (m; < 0 above it).

    ``g(s) = depth(e + s u) - d_j(x(s), y(s))`` with ``d_0 = 0`` (the rest surface), ``d_j`` the egg-carton interface
    ``j - 1`` (section II.C, point values by :func:`~.paper.layer_bounds`) and ``d_L`` the bottom.

    Parameters
    ----------
    s : float
        Axis length from the entry (m).
    j : int
        Layer whose top is met, ``0..L`` (``L``: the bottom).
    lp : ndarray, shape (LP_SIZE, L)
        The tissue's per-layer properties (``LP_IF_*`` rows).
    npar : ndarray, shape (NP_SIZE,)
        The needle's parameters (``NP_BOTTOM``).
    nstate : ndarray, shape (NS_SIZE,)
        The track (entry and axis).
    nbuf : ndarray, shape (NB_SIZE, L + 1)
        Scratch (``NB_BOUNDS`` written).

    Returns
    -------
    float
        ``g(s)`` (m).
    """
    ni = lp.shape[1] - 1
    x = nstate[NS_EX] + s * nstate[NS_UX]
    y = nstate[NS_EY] + s * nstate[NS_UY]
    z = nstate[NS_EZ] + s * nstate[NS_UZ]
    bounds = nbuf[NB_BOUNDS]
    layer_bounds(x, y, lp[LP_IF_MEAN, :ni], lp[LP_IF_AMP, :ni], lp[LP_IF_KX, :ni], lp[LP_IF_KY, :ni], npar[NP_BOTTOM], bounds)
    return -z - bounds[j]


@njit(**JIT_OPTIONS)
def axis_crossing(j, lp, npar, nstate, nbuf):
    """Axis length from the entry to the first point where the axis meets layer ``j``'s top (m).

    A Lipschitz march from the entry: ``|g'(s)| <= |u_z| + A (k_x |u_x| + k_y |u_y|) = Lip`` for the interface of
    amplitude ``A`` and wavenumbers ``k_x, k_y``, so from ``g(s) < 0`` no crossing lies before ``s - g(s) / Lip``;
    each step is that far, and at least :data:`SCAN_STEP_M` in depth. Bisection then brackets the first sign change
    to adjacent floats. The march stops at 1 mm below the bottom (as the reference's scan does).

    Parameters
    ----------
    j : int
        Layer, ``0..L`` (0: the surface, 0.0 returned; ``L``: the bottom).
    lp, npar, nstate, nbuf : ndarray
        As :func:`axis_gap`.

    Returns
    -------
    float
        The axis length ``t_j`` (m).
    """
    if j == 0:
        return 0.0
    down = -nstate[NS_UZ]
    nl = lp.shape[1]
    lip = down
    if j < nl:
        amp = abs(lp[LP_IF_AMP, j - 1])
        lip += amp * (lp[LP_IF_KX, j - 1] * abs(nstate[NS_UX]) + lp[LP_IF_KY, j - 1] * abs(nstate[NS_UY]))
    ds = SCAN_STEP_M / down
    s_max = (npar[NP_BOTTOM] + 1e-3) / down
    lo = 0.0
    g_lo = axis_gap(lo, j, lp, npar, nstate, nbuf)
    hi = lo + ds
    while lo < s_max:
        hi = lo + max(-g_lo / lip, ds)
        g_hi = axis_gap(hi, j, lp, npar, nstate, nbuf)
        if g_hi >= 0.0:
            break
        lo, g_lo = hi, g_hi
        hi = lo + ds
    for _ in range(200):
        mid = 0.5 * (lo + hi)
        if mid <= lo or mid >= hi:
            break
        if axis_gap(mid, j, lp, npar, nstate, nbuf) < 0.0:
            lo = mid
        else:
            hi = mid
    return 0.5 * (lo + hi)


@njit(**JIT_OPTIONS)
def start_track(px, py, pz, ux, uy, uz, lp, npar, nstate, ntrack, nbuf):
    """Start a track at the tip ``p`` with the unit axis ``u`` when the tip is below the surface and the needle is
    steeper than ``NP_MIN_SIN``: the entry where the axis met the rest surface, and every crossing ``t_j``.

    Parameters
    ----------
    px, py, pz : float
        Tip (m).
    ux, uy, uz : float
        Unit axis toward the tip.
    lp, npar : ndarray
        The tissue's ``lp`` and the needle's ``npar``.
    nstate, ntrack : ndarray
        The track: reset and written when a track starts, untouched otherwise.
    nbuf : ndarray, shape (NB_SIZE, L + 1)
        Scratch.

    Returns
    -------
    bool
        True when a track started.
    """
    if uz > -npar[NP_MIN_SIN] or pz >= 0.0:
        return False
    reset_track(nstate, ntrack)
    nstate[NS_INSERTED] = 1.0
    nstate[NS_UX], nstate[NS_UY], nstate[NS_UZ] = ux, uy, uz
    f = pz / uz
    nstate[NS_EX], nstate[NS_EY], nstate[NS_EZ] = px - f * ux, py - f * uy, pz - f * uz
    for j in range(lp.shape[1] + 1):
        ntrack[NT_CROSS, j] = axis_crossing(j, lp, npar, nstate, nbuf)
    return True


@njit(**JIT_OPTIONS)
def tent_ratio(w, slip, npar, nstate):
    """Tangential over normal reaction ``c`` of the tented skin on the tip (eq T2 of :mod:`.needle`).

    The tip has advanced ``w`` along the axis past the pressed layer's top: ``w sin(theta)`` into it and
    ``w cos(theta)`` along it (``theta`` the axis' angle to the surface). Stuck, the tent is sheared along the
    surface by ``(w - xi) cos(theta)`` (``xi`` how far its stuck point has slid along the axis) over a depth
    ``w sin(theta)``, so ``c = kappa (w - xi) cot(theta) / w`` (``kappa`` Mindlin's tangential over normal stiffness of a
    contact); Coulomb caps it at ``|c| <= mu`` (the tip skates). ``c > 0`` resists the tip's advance.

    Parameters
    ----------
    w : float
        Axial dimple (m); ``<= 0``: 0 returned.
    slip : float
        ``xi`` (m).
    npar : ndarray, shape (NP_SIZE,)
        ``NP_MU``, ``NP_KAPPA``.
    nstate : ndarray, shape (NS_SIZE,)
        The track's axis.

    Returns
    -------
    float
        ``c`` in ``[-mu, mu]``.
    """
    if w <= 0.0:
        return 0.0
    sn = -nstate[NS_UZ]
    cs = math.sqrt(nstate[NS_UX] * nstate[NS_UX] + nstate[NS_UY] * nstate[NS_UY])
    mu = npar[NP_MU]
    c = npar[NP_KAPPA] * cs / sn * (w - slip) / w
    return min(max(c, -mu), mu)


@njit(**JIT_OPTIONS)
def dimple_force(layer, w, slip, t0, lp, npar, nlp, nstate, nbuf):
    """Axial resistance (N) of the tented stack below ``layer``'s top pressed ``w`` along the axis by the tip, its chain
    force and its tangential ratio (eqs T1-T3 of :mod:`.needle`).

    The normal reaction is the layered form's equilibrium series chain of layers ``layer..L-1``
    (:func:`~.layered_law.chain_solve`, eq 4 with the fitted compression law) at the normal depth ``w sin(theta)``,
    scaled to the tent by ``NP_SCALE``: ``N = scale T(w sin(theta))`` (T1), along the surface normal (+z). Along the
    surface the tent answers ``c N`` against the tip's advance (:func:`tent_ratio`, T2). Their component along the axis
    ``u`` resists insertion: ``F = N (sin(theta) + c cos(theta))`` (T3); at 90 degrees ``F = N``.

    Parameters
    ----------
    layer : int
        The intact layer pressed, ``0..L-1``.
    w : float
        Axial dimple (m); ``<= 0``: no force.
    slip : float
        ``xi`` (m): how far the tent's stuck point has slid along the axis (0: stuck since the contact).
    t0 : float
        Newton start of the chain force ``T`` (N, a previous tick's; 0: cold).
    lp, npar, nlp, nstate : ndarray
        Tissue, needle parameters and track (axis).
    nbuf : ndarray, shape (NB_SIZE, L + 1)
        Scratch (``NB_C``, ``NB_G`` written).

    Returns
    -------
    force : float
        ``F`` (N; < 0 only when a tent sheared backwards pulls the tip in).
    t : float
        ``T`` (N; 0 with no dimple); ``N = scale T``.
    c : float
        The tangential ratio ``c``.
    """
    if w <= 0.0:
        return 0.0, 0.0, 0.0
    nl = lp.shape[1]
    down = -nstate[NS_UZ]
    z = nlp[NL_ZERO, layer:]
    t = chain_solve(
        w * down,
        t0,
        lp[LP_EA, layer:],
        lp[LP_N, layer:],
        z,
        1.0,
        z,
        nlp[NL_H, layer:],
        npar[NP_WALL],
        z,
        nbuf[NB_C, layer:nl],
        nbuf[NB_G, layer:nl],
    )
    t = max(t, 0.0)
    c = tent_ratio(w, slip, npar, nstate)
    cs = math.sqrt(nstate[NS_UX] * nstate[NS_UX] + nstate[NS_UY] * nstate[NS_UY])
    return npar[NP_SCALE] * t * (down + c * cs), t, c


@njit(**JIT_OPTIONS)
def axial_at(ins, k, front, slip, t0, lp, npar, nlp, nstate, ntrack, nbuf):
    """The axial resistance's dimple and cutting parts at the insertion ``ins`` from ``k`` ruptured layers and the crack
    front ``front``: a pure function of the state (the step and the law's look-ahead share it).

    Layer ``k`` ruptures when its dimple's axial resistance (:func:`dimple_force`, eq T3: the tent's normal reaction
    and friction projected on the axis) reaches ``F_p,k`` (eq P); the rupture releases the dimple and the next layer is
    tested at the same insertion (a cascade) as a new contact (``xi = 0``; layer ``k`` uses the state's ``xi``).
    Cutting ``beta F_p,j`` in the ruptured layer ``j`` the tip is in, on a ramp over ``x_c,j`` behind the front, while
    ``j`` is not yet cut through to the next layer's top (a front at or past it leaves nothing to cut in ``j``:
    backing out of a dimple into the cut layer above meets no cutting force, so nothing switches on at the crossing).

    Parameters
    ----------
    ins : float
        Insertion ``L`` along the track (m, > 0).
    k : int
        Layers ruptured before.
    front : float
        Crack front (m).
    slip : float
        ``xi`` of layer ``k``'s tent (m).
    t0 : float
        Newton start of layer ``k``'s chain force (N).
    lp, npar, nlp, nstate, ntrack, nbuf : ndarray
        Tissue, needle parameters, track, crossings and scratch.

    Returns
    -------
    k : int
        Layers ruptured after.
    dimple, cut : float
        Dimple and cutting forces (N).
    w_dimple : float
        Axial dimple of the next intact layer (m, >= 0).
    t : float
        Chain force of that dimple (N; 0 with none), the next Newton start.
    c : float
        The tent's tangential ratio of that dimple (:func:`tent_ratio`; 0 with none).
    """
    nl = lp.shape[1]
    cross = ntrack[NT_CROSS]
    dimple = 0.0
    t = 0.0
    c = 0.0
    start = t0
    while k < nl:
        dimple, t, c = dimple_force(k, ins - cross[k], slip, start, lp, npar, nlp, nstate, nbuf)
        if dimple < nlp[NL_FP, k]:
            break
        k += 1
        dimple = 0.0
        start = t  # the next chain is stiffer: its force is near the ruptured one's (a right start only costs a step)
        t = 0.0
        c = 0.0
        slip = 0.0  # the next layer's tent is a new contact
    w_dimple = max(ins - cross[k], 0.0) if k < nl else 0.0
    cut = 0.0
    if k > 0 and (k == nl or ins < cross[k]):
        j = -1
        for i in range(k + 1):  # the ruptured layer the tip is in: searchsorted(cross[:k + 1], ins, "right") - 1
            if cross[i] <= ins:
                j = i
        j = min(max(j, 0), k - 1)
        if j == nl - 1 or front < cross[j + 1]:  # a layer cut through to the next one's top has nothing left to cut
            xc = nlp[NL_CUT_M, j]
            ramp = min(max((ins - front + xc) / xc, 0.0), 1.0)
            cut = npar[NP_CUT_RATIO] * nlp[NL_FP, j] * ramp
    return k, dimple, cut, w_dimple, t, c


@njit(**JIT_OPTIONS)
def advance_front(ins, k, front, ntrack):
    """The crack front after a tick at ``ins`` with ``k`` ruptured layers: the deepest cut insertion.

    Inside the ruptured part of the track the front follows the tip; while the next intact layer is dimpled, the
    ruptured layers are cut through to its top.

    Parameters
    ----------
    ins : float
        Insertion (m).
    k : int
        Layers ruptured after the tick.
    front : float
        Front before (m).
    ntrack : ndarray, shape (NT_SIZE, L + 1)
        Crossings (``NT_CROSS``).

    Returns
    -------
    float
        The front (m).
    """
    nl = ntrack.shape[1] - 1
    cross = ntrack[NT_CROSS]
    if k > 0 and (k == nl or ins < cross[k]):
        return max(front, ins)
    if k > 0:
        return max(front, cross[k])
    return front


@njit(**JIT_OPTIONS)
def tent_slip(w, slip, npar, nstate):
    """``xi`` after a tick with the axial dimple ``w`` (eq T2 of :mod:`.needle`): the tent's stuck point slides (the tip
    skates) just enough to keep ``|c| <= mu``; no dimple (``w <= 0``), no contact: ``xi = 0``.

    Stuck, ``c = kappa cot(theta) (w - xi) / w``; past ``+mu`` (advancing) ``xi = w (1 - mu / (kappa cot(theta)))``,
    past ``-mu`` (backing out) ``xi = w (1 + mu / (kappa cot(theta)))``. A needle steeper than ``atan(kappa / mu)`` to
    the surface never skates while it advances.

    Parameters
    ----------
    w : float
        Axial dimple of the next intact layer (m).
    slip : float
        ``xi`` before (m; 0 for a new contact).
    npar, nstate : ndarray
        ``NP_MU``, ``NP_KAPPA`` and the track's axis.

    Returns
    -------
    float
        ``xi`` (m).
    """
    if w <= 0.0:
        return 0.0
    kc = npar[NP_KAPPA] * math.sqrt(nstate[NS_UX] * nstate[NS_UX] + nstate[NS_UY] * nstate[NS_UY]) / -nstate[NS_UZ]
    if kc <= 0.0:
        return 0.0
    mu = npar[NP_MU]
    q = kc * (w - slip) / w
    if q > mu:
        return w * (1.0 - mu / kc)
    if q < -mu:
        return w * (1.0 + mu / kc)
    return slip


@njit(**JIT_OPTIONS)
def needle_step_kernel(px, py, pz, ux, uy, uz, lp, npar, nlp, nstate, ntrack, nbuf, nout):
    """One tick of the needle at the tip ``p`` with the axis ``u`` (unit, toward the tip): force and state.

    Starts a track when there is none (:func:`start_track`); forgets it when the insertion ``L = (p - e) . u_e``
    is ``<= 0``. Then the dimple, ruptures and cutting (:func:`axial_at`), the front (:func:`advance_front`), the
    tent's slip (:func:`tent_slip`) and its reaction ``N e_z - c N t`` (``t`` the axis' direction along the surface;
    its axial part is the dimple, the rest is added off the axis),
    Dahl friction ``lambda tau pi d l_i s_i`` per ruptured layer with
    ``s_i <- sigma + (s_i - sigma) exp(-|dL| / x_0)``, and the lateral bed, the gradient of
    ``U = k(L) |delta|^2 / 4``, ``k = sum_i k_l E_i l_i``: ``-0.5 k delta`` sideways and ``k'(L) |delta|^2 / 4`` added
    to the axial resistance.

    Parameters
    ----------
    px, py, pz : float
        Tip (m).
    ux, uy, uz : float
        Axis toward the tip, normalised here (used only when a track starts; zero or non-finite: none starts).
    lp, npar, nlp : ndarray
        Tissue and needle parameters.
    nstate, ntrack : ndarray
        The track, updated.
    nbuf : ndarray, shape (NB_SIZE, L + 1)
        Scratch.
    nout : ndarray, shape (NO_SIZE,)
        Written: the tick (:data:`~.layout.NO_SIZE`); zeros out of the tissue or for a non-finite tip (the track is
        then left as it was).

    Returns
    -------
    bool
        True when the needle is in the tissue after the tick.
    """
    nout[:] = 0.0
    if not (math.isfinite(px) and math.isfinite(py) and math.isfinite(pz)):
        return nstate[NS_INSERTED] != 0.0  # bad input: no force, the track untouched
    if nstate[NS_INSERTED] == 0.0:
        norm = math.sqrt(ux * ux + uy * uy + uz * uz)
        if not (norm > 0.0 and math.isfinite(norm)):
            return False
        if not start_track(px, py, pz, ux / norm, uy / norm, uz / norm, lp, npar, nstate, ntrack, nbuf):
            return False
    ex, ey, ez = nstate[NS_EX], nstate[NS_EY], nstate[NS_EZ]
    vx, vy, vz = nstate[NS_UX], nstate[NS_UY], nstate[NS_UZ]
    dx, dy, dz = px - ex, py - ey, pz - ez
    ins = dx * vx + dy * vy + dz * vz
    if ins <= 0.0:  # withdrawn: the track is forgotten
        reset_track(nstate, ntrack)
        return False
    k0 = int(nstate[NS_RUPTURED])
    front = nstate[NS_FRONT]
    k, dimple, cut, w_dimple, t, c = axial_at(ins, k0, front, nstate[NS_SLIP], nstate[NS_T], lp, npar, nlp, nstate, ntrack, nbuf)
    nstate[NS_RUPTURED] = k
    nstate[NS_FRONT] = advance_front(ins, k, front, ntrack)
    nstate[NS_T] = t
    nstate[NS_SLIP] = tent_slip(w_dimple, nstate[NS_SLIP] if k == k0 else 0.0, npar, nstate)
    # the tent's reaction: N along the surface normal (+z), c N along the surface against the tip's advance (T1-T2)
    normal = npar[NP_SCALE] * t
    cs = math.sqrt(vx * vx + vy * vy)
    tx, ty = (vx / cs, vy / cs) if cs > 0.0 else (0.0, 0.0)
    ftx, fty, ftz = -c * normal * tx, -c * normal * ty, normal
    px_, py_, pz_ = ftx + dimple * vx, fty + dimple * vy, ftz + dimple * vz  # its part off the axis (dimple = -F_t . u)
    cross = ntrack[NT_CROSS]
    dahl = ntrack[NT_DAHL]
    step = ins - nstate[NS_LAST]
    nstate[NS_LAST] = ins
    decay = math.exp(-abs(step) / npar[NP_DAHL_M])
    sigma = math.copysign(1.0, step)
    fric = 0.0
    lateral_k = 0.0
    lateral_dk = 0.0  # d(lateral_k)/dL: the bed grows where the tip is in a cut layer
    for i in range(k):
        length = min(max(ins, cross[i]), cross[i + 1]) - cross[i]
        if step != 0.0:
            dahl[i] = sigma + (dahl[i] - sigma) * decay
        fric += npar[NP_FRICTION] * length * dahl[i]
        lateral_k += npar[NP_LATERAL] * nlp[NL_MODULUS, i] * length
        if cross[i] < ins < cross[i + 1]:
            lateral_dk += npar[NP_LATERAL] * nlp[NL_MODULUS, i]
    half = -0.5 * lateral_k
    lx, ly, lz = half * (dx - ins * vx), half * (dy - ins * vy), half * (dz - ins * vz)
    # the bed is the gradient of U = lateral_k(L) |delta|^2 / 4: its axial part, so a closed path does no net work
    bed = 0.25 * lateral_dk * ((dx - ins * vx) ** 2 + (dy - ins * vy) ** 2 + (dz - ins * vz) ** 2)
    axial = dimple + cut + fric + bed
    nout[NO_FX], nout[NO_FY], nout[NO_FZ] = -axial * vx + lx + px_, -axial * vy + ly + py_, -axial * vz + lz + pz_
    nout[NO_AXIAL], nout[NO_DIMPLE], nout[NO_CUT], nout[NO_FRICTION] = axial, dimple, cut, fric
    nout[NO_LX], nout[NO_LY], nout[NO_LZ] = lx, ly, lz
    nout[NO_DIMPLE_M], nout[NO_INSERTION_M] = w_dimple, ins
    nout[NO_RUPTURED], nout[NO_FIRST] = k, k0
    nout[NO_BED] = bed
    nout[NO_LATERAL_K] = lateral_k
    nout[NO_NORMAL], nout[NO_TANGENTIAL] = normal, c * normal
    nout[NO_TX], nout[NO_TY], nout[NO_TZ] = px_, py_, pz_
    return True


@njit(**JIT_OPTIONS)
def _chain_dimple(target, k, lp, npar, nlp, nbuf):
    """Total normal compression (m) of layers ``k..L-1`` carrying the chain force ``target`` (N): each layer's own
    monotone law solved (:func:`~.layered_law.layer_compression`, Newton); ``NB_C`` written."""
    nl = lp.shape[1]
    total = 0.0
    for i in range(k, nl):
        c, _ = layer_compression(target, lp[LP_EA, i], lp[LP_N, i], 0.0, 0.0, nlp[NL_H, i], npar[NP_WALL], 0.0)
        nbuf[NB_C, i] = c
        total += c
    return total


@njit(**JIT_OPTIONS)
def rupture_insertion(lp, npar, nlp, nstate, ntrack, nbuf):
    """Insertion ``L`` (m) at which the next intact layer ``k`` ruptures, the tip advancing from the state as it is
    (its ``xi``); inf when none is left or it never does.

    The dimple's axial resistance is ``scale T(w sin(theta)) (sin(theta) + c(w) cos(theta))`` (eq T3) with the series
    chain's ``T``, so it inverts in closed form while ``c`` is constant at the threshold: skating (``c = mu``) or stuck
    since the contact (``xi = 0``, ``c = kappa cot(theta)``): the chain force there is
    ``T* = F_p,k / (scale (sin(theta) + c cos(theta)))``, each layer's compression at ``T*`` solves its own monotone law
    (:func:`~.layered_law.layer_compression`) and ``L = t_k + sum_i c_i(T*) / sin(theta)``. A tip stuck after having
    skated (``xi != 0``, backed off and advancing again) bisects the monotone law instead (to adjacent floats).

    Parameters
    ----------
    lp, npar, nlp, nstate, ntrack : ndarray
        Tissue, needle parameters, track and crossings.
    nbuf : ndarray, shape (NB_SIZE, L + 1)
        Scratch (``NB_C`` holds the Newton starts and is written).

    Returns
    -------
    float
        ``L`` (m), or inf.
    """
    nl = lp.shape[1]
    k = int(nstate[NS_RUPTURED])
    if nstate[NS_INSERTED] == 0.0 or k >= nl:
        return math.inf
    down = -nstate[NS_UZ]
    cs = math.sqrt(nstate[NS_UX] * nstate[NS_UX] + nstate[NS_UY] * nstate[NS_UY])
    kc = npar[NP_KAPPA] * cs / down
    mu = npar[NP_MU]
    slip = nstate[NS_SLIP]
    fp = nlp[NL_FP, k]
    w = _chain_dimple(fp / (npar[NP_SCALE] * (down + mu * cs)), k, lp, npar, nlp, nbuf) / down  # skating there
    if not kc * (w - slip) >= mu * w:
        if slip == 0.0:  # stuck since the contact: c = kappa cot(theta) < mu
            w = _chain_dimple(fp / (npar[NP_SCALE] * (down + kc * cs)), k, lp, npar, nlp, nbuf) / down
        else:  # stuck after a skate: c grows with w, bisect the monotone law
            lo, hi = 0.0, max(w, 1e-6)
            while dimple_force(k, hi, slip, 0.0, lp, npar, nlp, nstate, nbuf)[0] < fp:
                lo, hi = hi, 2.0 * hi
                if hi > MAX_DIMPLE_M:
                    return math.inf
            for _ in range(200):
                mid = 0.5 * (lo + hi)
                if mid <= lo or mid >= hi:
                    break
                if dimple_force(k, mid, slip, 0.0, lp, npar, nlp, nstate, nbuf)[0] < fp:
                    lo = mid
                else:
                    hi = mid
            w = hi
    if not w <= MAX_DIMPLE_M:
        return math.inf
    return ntrack[NT_CROSS, k] + w


@njit(**JIT_OPTIONS)
def _insertion(px, py, pz, a, nstate):
    """Insertion along the track of the point ``p + a u_e`` (m)."""
    vx, vy, vz = nstate[NS_UX], nstate[NS_UY], nstate[NS_UZ]
    return (px + a * vx - nstate[NS_EX]) * vx + (py + a * vy - nstate[NS_EY]) * vy + (pz + a * vz - nstate[NS_EZ]) * vz


@njit(**JIT_OPTIONS)
def needle_law_kernel(px, py, pz, ins, re0, fric, k_tick, lp, npar, nlp, nstate, ntrack, nbuf, nlaw):
    """The axial law at the tip ``p`` after a tick, for the local contact model (``NeedleLaw``).

    The track is untouched; only the law's cache (``NS_LAW_*``: the rupture ahead and the line past it, a function of
    the track, the ruptured layers and the crack front, which the step never reads) is filled.

    - ``R_e`` = the tick's dimple + cutting, its slope by a step of :data:`LAW_STEP_M` ahead (0 when that step
      ruptures a layer);
    - the distance to the next rupture (:func:`rupture_insertion`) plus :data:`RUPTURE_MARGIN_M`, and the line past
      it: ``R_e`` and its slope at :data:`POST_MARGIN_M` beyond (the state as the two steps there leave it);
    - Dahl friction: ``F_c = lambda tau pi d sum_i l_i`` over the ruptured layers, its growth per insertion (in a
      ruptured layer the tip is in, none once past the bottom) and the state ``z = F_f / F_c``.

    Parameters
    ----------
    px, py, pz : float
        Tip (m).
    ins, re0, fric : float
        The tick's insertion (m), dimple + cutting (N) and friction (N).
    k_tick : int
        The tick's ruptured layers.
    lp, npar, nlp, nstate, ntrack : ndarray
        Tissue, needle parameters, track and crossings (read only but the ``NS_LAW_*`` cache of ``nstate``).
    nbuf : ndarray, shape (NB_SIZE, L + 1)
        Scratch.
    nlaw : ndarray, shape (NW_SIZE,)
        Written: the law (:data:`~.layout.NW_SIZE`).
    """
    nlaw[:] = 0.0
    nl = lp.shape[1]
    k = int(nstate[NS_RUPTURED])
    front = nstate[NS_FRONT]
    t0 = nstate[NS_T]
    h = LAW_STEP_M
    ins1 = _insertion(px, py, pz, h, nstate)
    k1, v1 = 0, 0.0
    if ins1 > 0.0:
        k1, d1, c1, _, _, _ = axial_at(ins1, k, front, nstate[NS_SLIP], t0, lp, npar, nlp, nstate, ntrack, nbuf)
        v1 = d1 + c1
    slope = (v1 - re0) / h if k1 == k_tick else 0.0
    ins_b = _insertion(px, py, pz, -h, nstate)  # behind: the cutting ramp fades (a pure look-up: the front stays)
    slope_behind = slope
    if ins_b > 0.0:
        kb, db, cb, _, _, _ = axial_at(ins_b, k, front, nstate[NS_SLIP], t0, lp, npar, nlp, nstate, ntrack, nbuf)
        if kb == k_tick:
            slope_behind = (re0 - (db + cb)) / h
    slip = nstate[NS_SLIP]
    cached = nstate[NS_LAW_K] == k + 1 and nstate[NS_LAW_FRONT] == front and nstate[NS_LAW_SLIP] == slip
    lr = nstate[NS_LAW_RUPTURE] if cached else rupture_insertion(lp, npar, nlp, nstate, ntrack, nbuf)
    dist = 0.0
    post = 0.0
    post_slope = 0.0
    if math.isfinite(lr):
        dist = max(lr - ins, 0.0) + RUPTURE_MARGIN_M
        if cached and ins < lr:  # the line past the rupture, at lr + margins: a function of (track, k, front) only
            post, post_slope = nstate[NS_LAW_POST], nstate[NS_LAW_POST_GRADIENT]
        else:
            a = dist + POST_MARGIN_M
            ins_a = _insertion(px, py, pz, a, nstate)
            ins_b = _insertion(px + h * nstate[NS_UX], py + h * nstate[NS_UY], pz + h * nstate[NS_UZ], a, nstate)
            if ins_a > 0.0 and ins_b > 0.0:
                t_rupture = nlp[NL_FP, k] / npar[NP_SCALE]  # the chain force at the threshold
                ka, da, ca, wa, ta, _ = axial_at(ins_a, k, front, slip, t_rupture, lp, npar, nlp, nstate, ntrack, nbuf)
                front_a = advance_front(ins_a, ka, front, ntrack)
                slip_a = tent_slip(wa, slip if ka == k else 0.0, npar, nstate)  # as the step there leaves it
                _, db, cb, _, _, _ = axial_at(ins_b, ka, front_a, slip_a, ta, lp, npar, nlp, nstate, ntrack, nbuf)
                post = da + ca
                post_slope = (db + cb - post) / h
            if ins < lr:
                nstate[NS_LAW_K], nstate[NS_LAW_FRONT], nstate[NS_LAW_SLIP] = k + 1, front, slip
                nstate[NS_LAW_RUPTURE], nstate[NS_LAW_POST], nstate[NS_LAW_POST_GRADIENT] = lr, post, post_slope
    elif not cached:
        nstate[NS_LAW_K], nstate[NS_LAW_FRONT], nstate[NS_LAW_RUPTURE] = k + 1, front, lr
        nstate[NS_LAW_SLIP] = slip
    cross = ntrack[NT_CROSS]
    cap = 0.0
    grows = 0.0
    per_length = npar[NP_FRICTION]
    for i in range(k):
        length = min(max(ins, cross[i]), cross[i + 1]) - cross[i]
        cap += per_length * length
        if cross[i] < ins < cross[i + 1]:
            grows += per_length
    if k == nl and ins >= cross[nl]:
        grows = 0.0
    z = min(max(fric / cap, -1.0), 1.0) if cap > 0.0 else 0.0
    nlaw[NW_FORCE], nlaw[NW_GRADIENT] = re0, slope
    nlaw[NW_RUPTURE_M], nlaw[NW_POST], nlaw[NW_POST_GRADIENT] = dist, post, post_slope
    nlaw[NW_CAPACITY], nlaw[NW_CAPACITY_GRADIENT], nlaw[NW_STATE] = cap, grows, z
    nlaw[NW_GRADIENT_BEHIND] = slope_behind
