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

from .friction import presliding_step
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
    NL_TENT_K,
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
    NP_LATERAL,
    NP_MIN_SIN,
    NP_MU,
    NP_SCALE,
    NP_WALL,
    NS_AX,
    NS_AY,
    NS_DEVZ,
    NS_EX,
    NS_EY,
    NS_EZ,
    NS_FRONT,
    NS_INSERTED,
    NS_LAST,
    NS_LAW_DEV,
    NS_LAW_FRONT,
    NS_LAW_K,
    NS_LAW_POST,
    NS_LAW_POST_GRADIENT,
    NS_LAW_RUPTURE,
    NS_RUPTURED,
    NS_T,
    NS_TENT,
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
        The track: reset and written when a track starts (the tent's anchor ``NS_AX``, ``NS_AY``, ``NS_TENT`` kept:
        cleared by :func:`reset_track` unless the caller restored it), untouched otherwise.
    nbuf : ndarray, shape (NB_SIZE, L + 1)
        Scratch.

    Returns
    -------
    bool
        True when a track started.
    """
    if uz > -npar[NP_MIN_SIN] or pz >= 0.0:
        return False
    ax, ay, tent = nstate[NS_AX], nstate[NS_AY], nstate[NS_TENT]
    reset_track(nstate, ntrack)
    nstate[NS_AX], nstate[NS_AY], nstate[NS_TENT] = ax, ay, tent  # a tent kept across a restart (needle.reset(True))
    nstate[NS_INSERTED] = 1.0
    nstate[NS_UX], nstate[NS_UY], nstate[NS_UZ] = ux, uy, uz
    f = pz / uz
    nstate[NS_EX], nstate[NS_EY], nstate[NS_EZ] = px - f * ux, py - f * uy, pz - f * uz
    for j in range(lp.shape[1] + 1):
        ntrack[NT_CROSS, j] = axis_crossing(j, lp, npar, nstate, nbuf)
    return True


@njit(**JIT_OPTIONS)
def dimple_force(layer, wn, t0, lp, npar, nlp, nbuf):
    """The tent's normal reaction (N) on a tip ``wn`` below ``layer``'s top, along the surface normal (eq T1 of
    :mod:`.needle`).

    The layered form's equilibrium series chain of layers ``layer..L-1`` (:func:`~.layered_law.chain_solve`, eq 4 with
    the fitted compression law) at the normal depth ``wn``, scaled to the tent by ``NP_SCALE``: ``N = scale T(wn)``. A
    function of the tip's depth only: the normal reaction is the gradient of a potential.

    Parameters
    ----------
    layer : int
        The intact layer pressed, ``0..L-1``.
    wn : float
        Normal depth of the tip below the layer's top where the axis crosses it (m); ``<= 0``: no force.
    t0 : float
        Newton start of the chain force ``T`` (N, a previous tick's; 0: cold).
    lp, npar, nlp : ndarray
        Tissue and needle parameters.
    nbuf : ndarray, shape (NB_SIZE, L + 1)
        Scratch (``NB_C``, ``NB_G`` written).

    Returns
    -------
    normal : float
        ``N`` (N, >= 0).
    t : float
        ``T`` (N; 0 with no dimple).
    """
    if wn <= 0.0:
        return 0.0, 0.0
    nl = lp.shape[1]
    z = nlp[NL_ZERO, layer:]
    t = chain_solve(
        wn,
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
    return npar[NP_SCALE] * t, t


@njit(**JIT_OPTIONS)
def axial_at(ins, dvx, dvy, dvz, k, front, ax, ay, tent, t0, lp, npar, nlp, nstate, ntrack, nbuf):
    """The axial resistance's dimple and cutting parts with the tip at the insertion ``ins`` plus the deviation ``dv``
    from the axis, ``k`` ruptured layers, the crack front ``front`` and the tent's anchor ``a``: a pure function of
    the state (the step and the law's look-ahead share it).

    The tent of the next intact layer ``k`` answers the tip with its normal reaction ``N`` at the tip's normal depth
    ``w_n`` below the layer's top where the axis crosses it (:func:`dimple_force`, T1) and its friction on the
    surface, the presliding law of :mod:`.friction` (:func:`~.friction.presliding_step`: a spring ``k_t,k`` from the
    anchor ``a`` to the tip, capped at ``mu N``, the anchor dragged beyond; T2). Layer ``k`` ruptures when ``N``
    reaches ``F_p,k`` (eq P); the rupture releases the tent and the next layer is tested at the same tip (a cascade)
    as a new contact (its anchor at the tip). The dimple is the tent's force projected on the axis,
    ``N sin(theta) - f_t . u`` (T3). Cutting ``beta F_p,j`` in the ruptured layer ``j`` the tip is in, on a ramp over
    ``x_c,j`` behind the front, while ``j`` is not yet cut through to the next layer's top (a front at or past it leaves
    nothing to cut in ``j``: backing out of a dimple into the cut layer above meets no cutting force).

    Parameters
    ----------
    ins : float
        Insertion ``L`` along the track (m, > 0).
    dvx, dvy, dvz : float
        The tip's deviation from the axis, ``(p - e) - L u_e`` (m).
    k : int
        Layers ruptured before.
    front : float
        Crack front (m).
    ax, ay : float
        The tent's anchor on the surface plane (m), used when ``tent`` is 1.
    tent : float
        1.0: the anchor holds layer ``k``'s tent; 0.0: none (a new contact: the anchor is set at the tip).
    t0 : float
        Newton start of layer ``k``'s chain force (N).
    lp, npar, nlp, nstate, ntrack, nbuf : ndarray
        Tissue, needle parameters, track, crossings and scratch.

    Returns
    -------
    k : int
        Layers ruptured after.
    dimple, cut : float
        Dimple (axial part of the tent's force) and cutting forces (N).
    w_dimple : float
        The next intact layer's normal depth over ``sin(theta)``: its axial dimple (m, >= 0).
    t : float
        Chain force of that dimple (N; 0 with none), the next Newton start; ``N = scale t``.
    ax, ay, tent : float
        The anchor after the tick and whether it holds a tent (with none: the tip's position and 0).
    ftx, fty : float
        The tent's friction on the tip (N), along the surface.
    """
    nl = lp.shape[1]
    cross = ntrack[NT_CROSS]
    down = -nstate[NS_UZ]
    vx, vy = nstate[NS_UX], nstate[NS_UY]
    tipx = nstate[NS_EX] + ins * vx + dvx
    tipy = nstate[NS_EY] + ins * vy + dvy
    t = 0.0
    normal = 0.0
    start = t0
    wn = 0.0
    while k < nl:
        wn = (ins - cross[k]) * down - dvz
        normal, t = dimple_force(k, wn, start, lp, npar, nlp, nbuf)
        if normal < nlp[NL_FP, k]:
            break
        k += 1
        start = t  # the next chain is stiffer: its force is near the ruptured one's (a right start only costs a step)
        normal = 0.0
        t = 0.0
        tent = 0.0  # the next layer's tent is a new contact
    dimple = 0.0
    w_dimple = 0.0
    ftx = 0.0
    fty = 0.0
    if k < nl and normal > 0.0:
        if tent == 0.0:
            ax, ay = tipx, tipy
        ax, ay, _, ftx, fty, _, _ = presliding_step(
            tipx, tipy, 0.0, 0.0, 0.0, 1.0, ax, ay, 0.0, nlp[NL_TENT_K, k], npar[NP_MU] * normal
        )
        tent = 1.0
        dimple = normal * down - (ftx * vx + fty * vy)
        w_dimple = wn / down
    else:
        ax, ay, tent = tipx, tipy, 0.0
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
    return k, dimple, cut, w_dimple, t, ax, ay, tent, ftx, fty


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
def needle_step_kernel(px, py, pz, ux, uy, uz, lp, npar, nlp, nstate, ntrack, nbuf, nout):
    """One tick of the needle at the tip ``p`` with the axis ``u`` (unit, toward the tip): force and state.

    Starts a track when there is none (:func:`start_track`); forgets it when the insertion ``L = (p - e) . u_e``
    is ``<= 0``. Then the dimple, ruptures and cutting (:func:`axial_at`), the front (:func:`advance_front`), the
    tent's anchor and its reaction ``N e_z + f_t`` (its axial part is the dimple, the rest is added off the axis),
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
            nstate[NS_TENT] = 0.0  # no track: no tent either
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
    dvx, dvy, dvz = dx - ins * vx, dy - ins * vy, dz - ins * vz  # the tip off the axis
    k, dimple, cut, w_dimple, t, ax, ay, tent, ftx, fty = axial_at(
        ins,
        dvx,
        dvy,
        dvz,
        k0,
        front,
        nstate[NS_AX],
        nstate[NS_AY],
        nstate[NS_TENT],
        nstate[NS_T],
        lp,
        npar,
        nlp,
        nstate,
        ntrack,
        nbuf,
    )
    nstate[NS_RUPTURED] = k
    nstate[NS_FRONT] = advance_front(ins, k, front, ntrack)
    nstate[NS_T] = t
    nstate[NS_AX], nstate[NS_AY], nstate[NS_TENT], nstate[NS_DEVZ] = ax, ay, tent, dvz
    # the tent's reaction: N along the surface normal (+z), the presliding friction f_t along the surface (T1-T2)
    normal = npar[NP_SCALE] * t
    px_, py_, pz_ = ftx + dimple * vx, fty + dimple * vy, normal + dimple * vz  # its part off the axis (dimple = -F_t . u)
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
    lx, ly, lz = half * dvx, half * dvy, half * dvz
    # the bed is the gradient of U = lateral_k(L) |delta|^2 / 4: its axial part, so a closed path does no net work
    bed = 0.25 * lateral_dk * (dvx * dvx + dvy * dvy + dvz * dvz)
    axial = dimple + cut + fric + bed
    nout[NO_FX], nout[NO_FY], nout[NO_FZ] = -axial * vx + lx + px_, -axial * vy + ly + py_, -axial * vz + lz + pz_
    nout[NO_AXIAL], nout[NO_DIMPLE], nout[NO_CUT], nout[NO_FRICTION] = axial, dimple, cut, fric
    nout[NO_LX], nout[NO_LY], nout[NO_LZ] = lx, ly, lz
    nout[NO_DIMPLE_M], nout[NO_INSERTION_M] = w_dimple, ins
    nout[NO_RUPTURED], nout[NO_FIRST] = k, k0
    nout[NO_BED] = bed
    nout[NO_LATERAL_K] = lateral_k
    nout[NO_NORMAL], nout[NO_TANGENTIAL] = normal, math.sqrt(ftx * ftx + fty * fty)
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
    """Insertion ``L`` (m) at which the next intact layer ``k`` ruptures, the tip advancing along the axis from the
    state as it is (its height off the axis, ``NS_DEVZ``); inf when none is left or it never does.

    The criterion is on the tent's normal reaction, ``N = scale T(w_n) = F_p,k`` (eq P), and ``N`` depends on the
    normal depth only: the chain force there is ``T* = F_p,k / scale``, each layer's compression at ``T*`` solves its
    own monotone law (:func:`~.layered_law.layer_compression`), ``w_n* = sum_i c_i(T*)`` and
    ``L = t_k + (w_n* + delta_z) / sin(theta)``. The friction's history (the anchor) does not enter.

    Parameters
    ----------
    lp, npar, nlp, nstate, ntrack : ndarray
        Tissue, needle parameters, track and crossings.
    nbuf : ndarray, shape (NB_SIZE, L + 1)
        Scratch (``NB_C`` written).

    Returns
    -------
    float
        ``L`` (m), or inf.
    """
    nl = lp.shape[1]
    k = int(nstate[NS_RUPTURED])
    if nstate[NS_INSERTED] == 0.0 or k >= nl:
        return math.inf
    wn = _chain_dimple(nlp[NL_FP, k] / npar[NP_SCALE], k, lp, npar, nlp, nbuf)
    if not wn <= MAX_DIMPLE_M:
        return math.inf
    return ntrack[NT_CROSS, k] + (wn + nstate[NS_DEVZ]) / -nstate[NS_UZ]


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
    ax, ay, tent = nstate[NS_AX], nstate[NS_AY], nstate[NS_TENT]
    vx, vy, vz = nstate[NS_UX], nstate[NS_UY], nstate[NS_UZ]
    dvx = px - nstate[NS_EX] - ins * vx  # the tip off the axis (a step along the axis keeps it)
    dvy = py - nstate[NS_EY] - ins * vy
    dvz = pz - nstate[NS_EZ] - ins * vz
    ins1 = _insertion(px, py, pz, h, nstate)
    k1, v1 = 0, 0.0
    if ins1 > 0.0:
        k1, d1, c1, _, _, _, _, _, _, _ = axial_at(
            ins1, dvx, dvy, dvz, k, front, ax, ay, tent, t0, lp, npar, nlp, nstate, ntrack, nbuf
        )
        v1 = d1 + c1
    slope = (v1 - re0) / h if k1 == k_tick else 0.0
    ins_b = _insertion(px, py, pz, -h, nstate)  # behind: the cutting ramp fades (a pure look-up: the front stays)
    slope_behind = slope
    if ins_b > 0.0:
        kb, db, cb, _, _, _, _, _, _, _ = axial_at(
            ins_b, dvx, dvy, dvz, k, front, ax, ay, tent, t0, lp, npar, nlp, nstate, ntrack, nbuf
        )
        if kb == k_tick:
            slope_behind = (re0 - (db + cb)) / h
    dev = nstate[NS_DEVZ]
    cached = nstate[NS_LAW_K] == k + 1 and nstate[NS_LAW_FRONT] == front and nstate[NS_LAW_DEV] == dev
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
                ka, da, ca, _, ta, axa, aya, tenta, _, _ = axial_at(
                    ins_a, dvx, dvy, dvz, k, front, ax, ay, tent, t_rupture, lp, npar, nlp, nstate, ntrack, nbuf
                )
                front_a = advance_front(ins_a, ka, front, ntrack)  # the anchor and front as the step there leaves them
                _, db, cb, _, _, _, _, _, _, _ = axial_at(
                    ins_b, dvx, dvy, dvz, ka, front_a, axa, aya, tenta, ta, lp, npar, nlp, nstate, ntrack, nbuf
                )
                post = da + ca
                post_slope = (db + cb - post) / h
            if ins < lr:
                nstate[NS_LAW_K], nstate[NS_LAW_FRONT], nstate[NS_LAW_DEV] = k + 1, front, dev
                nstate[NS_LAW_RUPTURE], nstate[NS_LAW_POST], nstate[NS_LAW_POST_GRADIENT] = lr, post, post_slope
    elif not cached:
        nstate[NS_LAW_K], nstate[NS_LAW_FRONT], nstate[NS_LAW_RUPTURE] = k + 1, front, lr
        nstate[NS_LAW_DEV] = dev
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
