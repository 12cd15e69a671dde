"""The modal kernels both tissue forms share: each layer's membrane as a modal series (eqs 1-3, 9).

A layer's displacement is ``u(x, y, t) = sum_k q_k(t) sin(m_k pi xi / a) sin(n_k pi eta / b)`` on its
patch (eq 2); a driven layer takes the indentation shape (eq 3, ``q = c beta``), a free one returns
by the exact damped propagator of each mode (eq 2 with damping; eq 9 is its one-mode example).
Also the opening of a haptic tick, which both forms' tick kernels share (:func:`begin_tick`).

Kernel style as emg3d's ``core.py``: ``@njit(cache=True, nogil=True)``, plain arrays and scalars,
outputs preallocated by the caller, so a haptic tick allocates nothing. Each kernel is tested compiled
and as ``.py_func`` against :mod:`skin_sim_lab.oracles.reference`. The grouped arrays (``sp``,
``bmodes``, ``mstate``, ...) are described in :mod:`.layout`.
"""

from __future__ import annotations

import math

from numba import njit

from .layout import (
    FLAG_OFF_SHEET,
    IS_ACTIVE,
    IS_DRIVEN,
    IS_LEVEL,
    IS_PROP_K,
    LS_AMP,
    LS_COMP,
    LS_CX,
    LS_CY,
    LS_DROPPED,
    LS_PROP_DT,
    OUT_DEPTH_M,
    OUT_FORCE_N,
    OUT_FX,
    OUT_FY,
    OUT_FZ,
    OUT_N_AFFECTED,
    OUT_NX,
    OUT_NY,
    OUT_NZ,
    OUT_RADIUS_M,
    OUT_SETTLED,
    OUT_STRESS_PA,
    OUT_SURFACE_M,
    SP_COS,
    SP_HALF_X,
    SP_HALF_Y,
    SP_MODE_TOL,
    SP_PATCH_A,
    SP_PATCH_B,
    SP_SETTLE_TOL,
    SP_SIN,
    SP_SKIP_SETTLED,
)


@njit(cache=True, nogil=True)
def modal_propagator(lam, gamma, dt, out_prop):
    """Exact one-step transition of ``q'' + 2 gamma q' + lam^2 q = 0`` for every mode (eq 2, damped).

    Parameters
    ----------
    lam : ndarray, shape (L, K)
        Modal angular frequencies ``lambda_mn`` (rad/s, eq 3).
    gamma : ndarray, shape (L,)
        Modal damping rate of each layer (1/s).
    dt : float
        Step (s), any ``dt >= 0``: closed form for under-, critically and over-damped modes.
    out_prop : ndarray, shape (4, L, K)
        Written: P11, P12, P21, P22 with ``q1 = P11 q0 + P12 v0``, ``v1 = P21 q0 + P22 v0``.
    """
    for li in range(lam.shape[0]):
        layer_propagator(lam, gamma, dt, li, lam.shape[1], out_prop)


@njit(cache=True, nogil=True)
def layer_propagator(lam, gamma, dt, li, n_modes, out_prop):
    """:func:`modal_propagator` for layer ``li`` and its first ``n_modes`` modes only (eq 2, damped).

    Parameters
    ----------
    lam, gamma, dt, out_prop
        As :func:`modal_propagator`; only ``out_prop[:, li, :n_modes]`` is written.
    li : int
        Layer.
    n_modes : int
        Modes to propagate (a level's prefix).
    """
    g = gamma[li]
    for kk in range(n_modes):
        w2 = lam[li, kk] ** 2
        disc = w2 - g * g
        if disc > 0.0:
            w = math.sqrt(disc)
            e = math.exp(-g * dt)
            ec = e * math.cos(w * dt)
            es = e * (math.sin(w * dt) / w)
        else:
            s = math.sqrt(-disc)
            e1 = math.exp(-(g - s) * dt)
            e2 = math.exp(-(g + s) * dt)
            ec = 0.5 * (e1 + e2)
            es = 0.5 * (e1 - e2) / s if s * dt > 1e-8 else dt * math.exp(-g * dt)
        out_prop[0, li, kk] = ec + g * es
        out_prop[1, li, kk] = es
        out_prop[2, li, kk] = -w2 * es
        out_prop[3, li, kk] = ec - g * es


@njit(cache=True, nogil=True)
def sine_table(theta, n_max, out):
    """``out[j] = sin(j theta)`` for ``j = 0..n_max`` by the Chebyshev recurrence (the sines of eq 2).

    Parameters
    ----------
    theta : float
        Angle (rad): ``pi xi / a`` for the x sines of eq 2.
    n_max : int
        Largest multiple.
    out : ndarray, shape (>= n_max + 1,)
        Written.
    """
    out[0] = 0.0
    if n_max >= 1:
        out[1] = math.sin(theta)
    two_c = 2.0 * math.cos(theta)
    for j in range(2, n_max + 1):
        out[j] = two_c * out[j - 1] - out[j - 2]


@njit(cache=True, nogil=True)
def layer_point_displacement(q_l, cx, cy, mode_m, mode_n, patch_a, patch_b, x, y, sx_buf, sy_buf):
    """One layer's downward displacement (m) at ``(x, y)``: eq 2 summed over its modes, the patch along the axes.

    :func:`layer_point_displacement_rot` at angle 0 (``cos = 1``, ``sin = 0``), which is exact there.

    Parameters
    ----------
    q_l : ndarray, shape (K,)
        The layer's modal amplitudes (m).
    cx, cy : float
        Patch centre (m); the patch is ``[cx - a/2, cx + a/2] x [cy - b/2, cy + b/2]``.
    mode_m, mode_n : ndarray of int64, shape (K,)
        1-based mode indices.
    patch_a, patch_b : float
        Patch sides (m).
    x, y : float
        Point (m).
    sx_buf, sy_buf : ndarray, shape (M + 1,)
        Scratch for the sine tables.

    Returns
    -------
    float
        The displacement (m, down); 0 outside the patch.
    """
    return layer_point_displacement_rot(q_l, cx, cy, mode_m, mode_n, patch_a, patch_b, 1.0, 0.0, x, y, sx_buf, sy_buf)


@njit(cache=True, nogil=True)
def layer_point_displacement_rot(q_l, cx, cy, mode_m, mode_n, patch_a, patch_b, cos_t, sin_t, x, y, sx_buf, sy_buf):
    """One layer's downward displacement (m) at ``(x, y)`` on a patch turned by the tension lines' angle (eq 2).

    The point in the patch's frame is ``xi = cos (x - cx) + sin (y - cy) + a/2`` (along the lines) and
    ``eta = -sin (x - cx) + cos (y - cy) + b/2`` (across); the modes are the sines of eq 2 in ``xi, eta``.
    At ``cos = 1, sin = 0`` this is bit for bit the unturned patch.

    Parameters
    ----------
    q_l, cx, cy, mode_m, mode_n, patch_a, patch_b, x, y, sx_buf, sy_buf
        As :func:`layer_point_displacement`.
    cos_t, sin_t : float
        Cosine and sine of the angle of the patch's first side from the x axis (``SP_COS``, ``SP_SIN``).

    Returns
    -------
    float
        The displacement (m, down); 0 outside the patch.
    """
    dx = x - cx
    dy = y - cy
    xi = cos_t * dx + sin_t * dy + 0.5 * patch_a
    eta = cos_t * dy - sin_t * dx + 0.5 * patch_b
    if xi <= 0.0 or xi >= patch_a or eta <= 0.0 or eta >= patch_b:
        return 0.0
    sine_table(math.pi * xi / patch_a, sx_buf.shape[0] - 1, sx_buf)
    sine_table(math.pi * eta / patch_b, sy_buf.shape[0] - 1, sy_buf)
    u = 0.0
    for kk in range(q_l.shape[0]):
        u += q_l[kk] * sx_buf[mode_m[kk]] * sy_buf[mode_n[kk]]
    return u


@njit(cache=True, nogil=True)
def prepare_propagators(bmodes, bvec, blev, dt, mstate, lstate, istate):
    """Every layer's propagator (eq 2, damped) for ``dt`` at its current level, into ``mstate[2:6]``.

    Cached: a layer whose ``LS_PROP_DT`` is ``dt`` and whose ``IS_PROP_K`` covers its level is skipped.

    Parameters
    ----------
    bmodes, bvec, blev : ndarray
        The modal basis (:mod:`.layout`).
    dt : float
        Step (s).
    mstate, lstate, istate : ndarray
        The state; the propagator rows and the cache slots are written.
    """
    nv = blev.shape[1]
    for li in range(istate.shape[1]):
        nk = blev[0, istate[IS_LEVEL, li]]
        if lstate[LS_PROP_DT, li] != dt or istate[IS_PROP_K, li] < nk:
            layer_propagator(bmodes[nv:], bvec[nv:], dt, li, nk, mstate[2:6])
            lstate[LS_PROP_DT, li] = dt
            istate[IS_PROP_K, li] = nk


@njit(cache=True, nogil=True)
def layer_at(li, x, y, sp, blev, bk, mstate, lstate, istate, sbuf):
    """Layer ``li``'s downward displacement (m) at ``(x, y)`` at its current level (eq 2).

    Parameters
    ----------
    li : int
        Layer.
    x, y : float
        Point (m).
    sp, blev, bk, mstate, lstate, istate, sbuf : ndarray
        The grouped arrays (:mod:`.layout`); ``sbuf`` is scratch.

    Returns
    -------
    float
        :func:`layer_point_displacement_rot` with the layer's modes, amplitudes and patch (turned by ``SP_COS``,
        ``SP_SIN``).
    """
    lv = istate[IS_LEVEL, li]
    nk = blev[0, lv]
    ml = blev[1, lv] + 1
    return layer_point_displacement_rot(
        mstate[0, li, :nk],
        lstate[LS_CX, li],
        lstate[LS_CY, li],
        bk[0, :nk],
        bk[1, :nk],
        sp[SP_PATCH_A],
        sp[SP_PATCH_B],
        sp[SP_COS],
        sp[SP_SIN],
        x,
        y,
        sbuf[0, :ml],
        sbuf[1, :ml],
    )


@njit(cache=True, nogil=True)
def surface_at(x, y, sp, blev, bk, mstate, lstate, istate, sbuf):
    """Downward surface displacement (m) at ``(x, y)``: eq 2 summed over the active layers (section II.D.4, step 6).

    Parameters
    ----------
    x, y : float
        Point (m).
    sp, blev, bk, mstate, lstate, istate, sbuf : ndarray
        As :func:`layer_at`.

    Returns
    -------
    float
        The sum of the active layers' displacements (m, down).
    """
    surface = 0.0
    for li in range(istate.shape[1]):
        if istate[IS_ACTIVE, li]:
            surface += layer_at(li, x, y, sp, blev, bk, mstate, lstate, istate, sbuf)
    return surface


@njit(cache=True, nogil=True)
def _disk_part(u, r):
    """``int_0^u sqrt(r^2 - t^2) dt`` for ``u`` clamped to ``[-r, r]`` (m^2): a quarter-disk strip's area.

    Parameters
    ----------
    u : float
        Upper limit (m).
    r : float
        Disk radius (m), ``> 0``.

    Returns
    -------
    float
        The integral (odd in ``u``; ``pi r^2 / 4`` at ``u >= r``).
    """
    v = min(r, max(-r, u))
    return 0.5 * (v * math.sqrt(max(r * r - v * v, 0.0)) + r * r * math.asin(v / r))


@njit(cache=True, nogil=True)
def _disk_corner(x, y, r):
    """Area and first moment in x of the disk ``|p| <= r`` (centred at 0) cut to ``{X <= x, Y <= y}``.

    The area is ``int_{-r}^{x} [min(y, s) + s]_+ dX`` with ``s = sqrt(r^2 - X^2)`` the half chord, in closed form
    (:func:`_disk_part`); the moment ``int X (...) dX`` uses ``int X s dX = -(r^2 - X^2)^(3/2) / 3``.

    Parameters
    ----------
    x, y : float
        The corner (m, relative to the disk centre).
    r : float
        Disk radius (m), ``> 0``.

    Returns
    -------
    area, moment_x : float
        m^2 and m^3.
    """
    xc = min(r, max(-r, x))
    yc = min(r, max(-r, y))
    w = math.sqrt(max(r * r - yc * yc, 0.0))  # half width of the chord at height yc
    m = min(w, max(-w, xc))
    strip = _disk_part(m, r) + _disk_part(w, r)  # int_{-w}^{m} s
    cube_m = -((max(r * r - m * m, 0.0)) ** 1.5) / 3.0
    cube_w = -(abs(yc) ** 3) / 3.0  # -(r^2 - w^2)^(3/2) / 3
    strip_x = cube_m - cube_w  # int_{-w}^{m} X s
    lin_x = 0.5 * (m * m - w * w)  # int_{-w}^{m} X
    if yc >= 0.0:
        full = 2.0 * (_disk_part(xc, r) + 0.25 * math.pi * r * r)
        full_x = -2.0 * ((max(r * r - xc * xc, 0.0)) ** 1.5) / 3.0
        return full - (strip - yc * (m + w)), full_x - (strip_x - yc * lin_x)
    return strip + yc * (m + w), strip_x + yc * lin_x


@njit(cache=True, nogil=True)
def _chord_in(x, y0, y1, r):
    """Length (m) of the disk's chord at ``X = x`` inside ``[y0, y1]`` (disk centred at 0, radius ``r``)."""
    if abs(x) >= r:
        return 0.0
    s = math.sqrt(r * r - x * x)
    return max(0.0, min(y1, s) - max(y0, -s))


@njit(cache=True, nogil=True)
def footprint(x, y, r, half_x, half_y):
    """The tool's contact disk on the sheet: overlap fraction, its derivatives and the overlap's centroid.

    The disk of radius ``r`` centred at ``(x, y)`` against the sheet ``[-half_x, half_x] x [-half_y, half_y]``:
    the exact overlap area ``A`` by inclusion-exclusion of four disk corners (:func:`_disk_corner`), the fraction
    ``f = A / (pi r^2)``, ``df/dx = (L(x0) - L(x1)) / (pi r^2)`` with ``L`` the chord inside the sheet at its edges
    ``x0, x1`` (and the same in y), and ``df/dr`` from Euler's theorem (``A`` is homogeneous of degree 2 in ``r`` and
    the edge offsets). A disk wholly on the sheet returns ``(1, 0, 0, 0, x, y)`` without any of this.

    Parameters
    ----------
    x, y : float
        Disk centre (m).
    r : float
        Contact radius (m), ``> 0``.
    half_x, half_y : float
        Half the sheet's extents (m).

    Returns
    -------
    frac, dfrac_dx, dfrac_dy, dfrac_dr : float
        The fraction of the disk on the sheet (0..1) and its derivatives (1/m).
    cx, cy : float
        Centroid of the overlap (m); the disk centre when it is empty.
    """
    if abs(x) + r <= half_x and abs(y) + r <= half_y:
        return 1.0, 0.0, 0.0, 0.0, x, y
    x0 = -half_x - x
    x1 = half_x - x
    y0 = -half_y - y
    y1 = half_y - y
    a11, mx11 = _disk_corner(x1, y1, r)
    a01, mx01 = _disk_corner(x0, y1, r)
    a10, mx10 = _disk_corner(x1, y0, r)
    a00, mx00 = _disk_corner(x0, y0, r)
    b11, my11 = _disk_corner(y1, x1, r)  # the same corners with x and y swapped: the moments in y
    b01, my01 = _disk_corner(y1, x0, r)
    b10, my10 = _disk_corner(y0, x1, r)
    b00, my00 = _disk_corner(y0, x0, r)
    area = max(0.0, a11 - a01 - a10 + a00)
    disk = math.pi * r * r
    if area <= 0.0:
        return 0.0, 0.0, 0.0, 0.0, x, y
    mx = mx11 - mx01 - mx10 + mx00
    my = my11 - my10 - my01 + my00
    lx0 = _chord_in(x0, y0, y1, r)
    lx1 = _chord_in(x1, y0, y1, r)
    ly0 = _chord_in(y0, x0, x1, r)
    ly1 = _chord_in(y1, x0, x1, r)
    # Euler: 2 A = r dA/dr + x1 L(x1) - x0 L(x0) + y1 L(y1) - y0 L(y0); f = A / (pi r^2)
    dfrac_dr = -(x1 * lx1 - x0 * lx0 + y1 * ly1 - y0 * ly0) / (disk * r)
    cx = min(min(x + r, half_x), max(max(x - r, -half_x), x + mx / area))  # within the overlap's box (round-off
    cy = min(min(y + r, half_y), max(max(y - r, -half_y), y + my / area))  # of a sliver's tiny area)
    return min(1.0, area / disk), (lx0 - lx1) / disk, (ly0 - ly1) / disk, dfrac_dr, cx, cy


@njit(cache=True, nogil=True)
def begin_tick(tool_x, tool_y, tool_z, dt, sp, bmodes, bvec, blev, bk, mstate, lstate, istate, sbuf):
    """:func:`begin_tick_reach` with no reach: contact only with the tool's centre on the sheet (the paper form)."""
    return begin_tick_reach(tool_x, tool_y, tool_z, dt, 0.0, sp, bmodes, bvec, blev, bk, mstate, lstate, istate, sbuf)


@njit(cache=True, nogil=True)
def begin_tick_reach(tool_x, tool_y, tool_z, dt, reach, sp, bmodes, bvec, blev, bk, mstate, lstate, istate, sbuf):
    """The opening both tick kernels share (section II.D.4, steps 1-2): propagators, surface and contact test.

    Without ``lod.affected_layers`` every layer's propagator is prepared for ``dt``, driven or not.
    Contact is unilateral and tested against the current deformed surface: the tool touches when it is
    on the sheet (its centre within ``reach`` of it), below the rest surface and either was in contact (a layer
    is driven) or reaches the surface displacement under it.

    Parameters
    ----------
    tool_x, tool_y, tool_z : float
        Tool tip (m, tissue frame, z up).
    dt : float
        Step (s).
    reach : float
        How far past the sheet's edge the tool's centre may be and still touch (m): 0 in the paper form (contact
        at the tool's centre), the tool radius in the layered form, whose force then follows the footprint
        (:func:`footprint`).
    sp, bmodes, bvec, blev, bk, mstate, lstate, istate, sbuf : ndarray
        The grouped arrays (:mod:`.layout`).

    Returns
    -------
    flags : int
        ``FLAG_OFF_SHEET`` when the tool is off the sheet (beyond ``reach``), else 0.
    was_contact : bool
        A layer was driven (the previous tick ended in contact).
    surface : float
        Surface displacement under the tool before this tick (m, down).
    touching : bool
        The tool touches the tissue.
    """
    flags = 0
    if not sp[SP_SKIP_SETTLED] > 0.0:  # every layer's propagator, driven or not, as without the lever
        prepare_propagators(bmodes, bvec, blev, dt, mstate, lstate, istate)
    was_contact = False
    for li in range(istate.shape[1]):
        if istate[IS_DRIVEN, li]:
            was_contact = True
    surface = surface_at(tool_x, tool_y, sp, blev, bk, mstate, lstate, istate, sbuf)
    on_sheet = abs(tool_x) <= sp[SP_HALF_X] + reach and abs(tool_y) <= sp[SP_HALF_Y] + reach
    if not on_sheet:
        flags |= FLAG_OFF_SHEET
    depth = -tool_z
    touching = on_sheet and depth > 0.0 and (was_contact or depth >= surface)
    return flags, was_contact, surface, touching


@njit(cache=True, nogil=True)
def end_tick(force_n, stress_pa, depth_m, n_affected, surface_m, fx, fy, fz, nx, ny, nz, radius_m, sp, lstate, istate, out):
    """The results both tick kernels write (section II.D.4, step 5), and the settled flag of the new state.

    Parameters
    ----------
    force_n, stress_pa, depth_m, n_affected, surface_m : float
        ``OUT_FORCE_N`` .. ``OUT_SURFACE_M`` (:mod:`.layout`).
    fx, fy, fz, nx, ny, nz : float
        The force vector (N) and the unit contact normal.
    radius_m : float
        Contact radius (m).
    sp, lstate, istate : ndarray
        The grouped arrays, for :func:`settled_flag`.
    out : ndarray, shape (OUT_SIZE,)
        Written: the slots above and ``OUT_SETTLED``.
    """
    out[OUT_FORCE_N] = force_n
    out[OUT_STRESS_PA] = stress_pa
    out[OUT_DEPTH_M] = depth_m
    out[OUT_N_AFFECTED] = n_affected
    out[OUT_SURFACE_M] = surface_m
    out[OUT_SETTLED] = settled_flag(sp, lstate, istate)
    out[OUT_FX] = fx
    out[OUT_FY] = fy
    out[OUT_FZ] = fz
    out[OUT_NX] = nx
    out[OUT_NY] = ny
    out[OUT_NZ] = nz
    out[OUT_RADIUS_M] = radius_m


@njit(cache=True, nogil=True)
def drive_layer(li, comp_m, rate_m_s, x, y, sp, bmodes, bvec, blev, mstate, lstate, istate):
    """Drive layer ``li`` quasi-statically, centred on the tool: ``q = dx_l beta``, ``v = dxdot_l beta`` (eq 3).

    With several levels (adaptive modes) the layer takes the smallest level whose truncation
    bound ``|dx_l| trunc_err`` is within ``sp[SP_MODE_TOL]``.

    Parameters
    ----------
    li : int
        Layer.
    comp_m : float
        Its compression ``dx_l`` (m): ``B_mn = dx_l beta_mn``.
    rate_m_s : float
        Its compression rate (m/s): ``B*_mn lambda_mn = dxdot_l beta_mn``.
    x, y : float
        Tool position (m): the new patch centre.
    sp, bmodes, bvec, blev, mstate, lstate, istate : ndarray
        The grouped arrays (:mod:`.layout`); the layer's state is written.
    """
    n_levels = blev.shape[1]
    lv = 0
    if n_levels > 1:
        lv = n_levels - 1
        for i in range(n_levels):
            if abs(comp_m) * bvec[i] <= sp[SP_MODE_TOL]:
                lv = i
                break
    nk = blev[0, lv]
    for kk in range(nk):
        mstate[0, li, kk] = comp_m * bmodes[lv, kk]
        mstate[1, li, kk] = rate_m_s * bmodes[lv, kk]
    for kk in range(nk, blev[0, istate[IS_LEVEL, li]]):  # fewer modes than last tick
        mstate[0, li, kk] = 0.0
        mstate[1, li, kk] = 0.0
    lstate[LS_COMP, li] = comp_m
    istate[IS_LEVEL, li] = lv
    lstate[LS_DROPPED, li] = 0.0
    lstate[LS_CX, li] = x
    lstate[LS_CY, li] = y
    istate[IS_DRIVEN, li] = 1
    istate[IS_ACTIVE, li] = 1
    lstate[LS_AMP, li] = math.inf


@njit(cache=True, nogil=True)
def relax_layer(li, dt, sp, bmodes, bvec, blev, mstate, lstate, istate):
    """Advance a free layer by the exact damped modal propagator: release and return (eq 2, eq 9).

    Keeps the displacement bound ``amp[l] = sum_k sqrt(q_k^2 + (v_k/lam_k)^2)`` when
    ``settle_tol > 0``; sheds the outermost shell of modes once its bound, added to what the layer
    already shed since it was last driven, is within the mode tolerance; with ``skip_settled`` a
    layer below ``settle_tol`` is set to rest (``active = 0``).

    Parameters
    ----------
    li : int
        Layer.
    dt : float
        Step (s); the propagator in ``mstate[2:6]`` is for this ``dt`` (prepared here with ``skip_settled``).
    sp, bmodes, bvec, blev, mstate, lstate, istate : ndarray
        The grouped arrays (:mod:`.layout`); the layer's state is written.
    """
    nv = blev.shape[1]
    lam = bmodes[nv:]
    settle_tol = sp[SP_SETTLE_TOL]
    skip_settled = sp[SP_SKIP_SETTLED] > 0.0
    q = mstate[0]
    v = mstate[1]
    istate[IS_DRIVEN, li] = 0
    if not istate[IS_ACTIVE, li]:
        return
    nk = blev[0, istate[IS_LEVEL, li]]
    if skip_settled and (lstate[LS_PROP_DT, li] != dt or istate[IS_PROP_K, li] < nk):
        layer_propagator(lam, bvec[nv:], dt, li, nk, mstate[2:6])
        lstate[LS_PROP_DT, li] = dt
        istate[IS_PROP_K, li] = nk
    bound = 0.0
    for kk in range(nk):
        q0 = q[li, kk]
        v0 = v[li, kk]
        q1 = mstate[2, li, kk] * q0 + mstate[3, li, kk] * v0
        v1 = mstate[4, li, kk] * q0 + mstate[5, li, kk] * v0
        q[li, kk] = q1
        v[li, kk] = v1
        if settle_tol > 0.0:
            r = v1 / lam[li, kk]
            bound += math.sqrt(q1 * q1 + r * r)
    lstate[LS_AMP, li] = bound if settle_tol > 0.0 else math.inf
    lv = istate[IS_LEVEL, li]
    if nv > 1 and lv > 0:  # shed the outer shell once it is negligible
        k0 = blev[0, lv - 1]
        tail = 0.0
        for kk in range(k0, nk):
            r = v[li, kk] / lam[li, kk]
            tail += math.sqrt(q[li, kk] * q[li, kk] + r * r)
        if lstate[LS_DROPPED, li] + tail <= sp[SP_MODE_TOL]:
            for kk in range(k0, nk):
                q[li, kk] = 0.0
                v[li, kk] = 0.0
            istate[IS_LEVEL, li] = lv - 1
            lstate[LS_DROPPED, li] += tail
    if skip_settled and bound < settle_tol:
        for kk in range(nk):
            q[li, kk] = 0.0
            v[li, kk] = 0.0
        istate[IS_ACTIVE, li] = 0
        lstate[LS_AMP, li] = 0.0


@njit(cache=True, nogil=True)
def settled_flag(sp, lstate, istate):
    """1.0 when no layer is driven and every layer's displacement bound (from eq 2) is below ``settle_tol``.

    Parameters
    ----------
    sp, lstate, istate : ndarray
        The grouped arrays (:mod:`.layout`).

    Returns
    -------
    float
        1.0 or 0.0 (always 0.0 when ``settle_tol`` is 0: not tracked).
    """
    settle_tol = sp[SP_SETTLE_TOL]
    if settle_tol <= 0.0:
        return 0.0
    for li in range(istate.shape[1]):
        if istate[IS_DRIVEN, li] or not lstate[LS_AMP, li] < settle_tol:
            return 0.0
    return 1.0


@njit(cache=True, nogil=True)
def modal_energy(q, v, lam):
    """Modal energy per unit modal mass, summed over layers and modes (eq 2): ``sum(v^2 + lam^2 q^2) / 2``.

    Parameters
    ----------
    q, v : ndarray, shape (L, K)
        Modal amplitudes (m) and velocities (m/s).
    lam : ndarray, shape (L, K)
        Modal angular frequencies (rad/s).

    Returns
    -------
    float
        The energy (m^2/s^2).
    """
    total = 0.0
    for li in range(q.shape[0]):
        for kk in range(q.shape[1]):
            total += 0.5 * (v[li, kk] ** 2 + (lam[li, kk] * q[li, kk]) ** 2)
    return total
