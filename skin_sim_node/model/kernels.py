"""All numba kernels of the skin model (emg3d ``core.py`` style).

Every kernel takes plain arrays and scalars and writes into preallocated outputs, so
a haptic tick allocates nothing. Each is tested compiled and as ``.py_func`` against
the NumPy reference in :mod:`skin_sim_node.model.reference`. Units are SI; depths and
displacements are positive downward (into the tissue).
"""

from __future__ import annotations

import math

from numba import njit

JIT = {"cache": True, "nogil": True}

# Step flags (bit field returned by step_kernel).
FLAG_CONTACT = 1
FLAG_BOTTOMED = 2  # tool below the tissue bottom: depth clamped
FLAG_LAYER_BOUND = 4  # a Reuss compression hit 0 or the layer thickness
FLAG_SEPARATED = 8  # tool retracted faster than the tissue: unilateral contact released
FLAG_OFF_SHEET = 16  # tool tip outside the sheet's x-y extent

# Indices into step_kernel's `out` array.
OUT_FORCE_N = 0
OUT_STRESS_PA = 1
OUT_DEPTH_M = 2
OUT_N_AFFECTED = 3
OUT_SURFACE_M = 4  # surface displacement under the tool before this tick
OUT_SETTLED = 5  # 1.0: no layer driven and every layer's displacement bound below settle_tol
OUT_FX = 6  # reaction force vector on the tool (N), tissue frame
OUT_FY = 7
OUT_FZ = 8
OUT_NX = 9  # unit contact normal
OUT_NY = 10
OUT_NZ = 11
OUT_RADIUS_M = 12  # contact radius (m), 0 out of contact
OUT_DFN_DX = 13  # gradient of the normal force magnitude w.r.t. the tool position (N/m): x, y, z
OUT_DFN_DY = 14
OUT_DFN_DZ = 15
OUT_T = 16  # layered form: last chain force per unit load scale (N), the Newton warm start of the next tick
OUT_SIZE = 17


@njit(**JIT)
def layer_bounds(x, y, iface_mean, iface_amp, iface_kx, iface_ky, bottom_m, out_bounds):
    """Depths of the layer tops at ``(x, y)`` and the bottom: ``out_bounds[0] = 0`` (surface),
    ``out_bounds[1..L-1]`` the egg-carton interfaces (section II.C), ``out_bounds[L]`` the bottom.
    ``iface_kx = 2 pi / wavelength_x``."""
    out_bounds[0] = 0.0
    for j in range(iface_mean.shape[0]):
        out_bounds[j + 1] = iface_mean[j] - iface_amp[j] * math.cos(iface_kx[j] * x) * math.cos(iface_ky[j] * y)
    out_bounds[iface_mean.shape[0] + 1] = bottom_m


@njit(**JIT)
def count_affected(depth_m, bounds):
    """Number of layers whose top lies above the tool tip (Fig 3): the first n are affected."""
    n = 0
    for i in range(bounds.shape[0] - 1):
        if depth_m > bounds[i]:
            n += 1
    return n


@njit(**JIT)
def reuss_split(n, depth_m, velocity_m_s, k, b, area, thickness, out_comp):
    """Iso-stress (Reuss) split of ``depth_m`` over the first ``n`` Kelvin-Voigt layers.

    From eq 4 (equal stress) and eq 6 (``sigma = (k_i dx_i + b_i xdot) / A_i``, common
    ``xdot``) with ``sum dx_i = depth``::

        sigma = (depth + xdot * sum(b_i / k_i)) / sum(A_i / k_i)
        dx_i  = (sigma * A_i - b_i * xdot) / k_i

    A compression outside ``[0, thickness_i]`` is held at that bound and the rest of
    the depth is split over the remaining layers (active set, at most n passes).
    Writes ``out_comp[:n]``; returns ``(stress_pa, force_n, hit_bound)``. The force on the
    tool is the stress transmitted through the stack times the top layer's area,
    ``sigma A_0`` (= ``k_0 dx_0 + b_0 xdot`` while the top layer is within its bounds).
    """
    fixed = 0  # bit i set: layer i held at a bound
    hit = False
    sigma = 0.0
    for _ in range(n + 1):
        rest = depth_m
        s_a = 0.0
        s_b = 0.0
        for i in range(n):
            if fixed >> i & 1:
                rest -= out_comp[i]
            else:
                s_a += area[i] / k[i]
                s_b += b[i] / k[i]
        if s_a <= 0.0:
            break
        sigma = (rest + velocity_m_s * s_b) / s_a
        worst = -1
        worst_excess = 0.0
        for i in range(n):
            if not fixed >> i & 1:
                c = (sigma * area[i] - b[i] * velocity_m_s) / k[i]
                out_comp[i] = c
                excess = max(-c, c - thickness[i])
                if excess > worst_excess:
                    worst_excess = excess
                    worst = i
        if worst < 0:
            break
        hit = True
        fixed |= 1 << worst
        out_comp[worst] = 0.0 if out_comp[worst] < 0.0 else thickness[worst]
    if n > 0 and fixed == (1 << n) - 1:
        # every layer at a bound (tool at the bottom): the stiffest layer's stress carries it
        sigma = 0.0
        for i in range(n):
            sigma = max(sigma, (k[i] * out_comp[i] + b[i] * velocity_m_s) / area[i])
    force = sigma * area[0] if n > 0 else 0.0
    return sigma, force, hit


@njit(**JIT)
def modal_propagator(lam, gamma, dt, out_prop):
    """Exact one-step transition of ``q'' + 2 gamma q' + lam^2 q = 0`` per mode (eq 2, damped).

    ``lam`` has shape (L, K), ``gamma`` (L,); writes ``out_prop[0..3]`` = P11, P12, P21, P22 so
    that ``q1 = P11 q0 + P12 v0`` and ``v1 = P21 q0 + P22 v0``. Closed form for under-,
    critically and over-damped modes, so any ``dt >= 0`` is stable.
    """
    for li in range(lam.shape[0]):
        layer_propagator(lam, gamma, dt, li, lam.shape[1], out_prop)


@njit(**JIT)
def layer_propagator(lam, gamma, dt, li, n_modes, out_prop):
    """:func:`modal_propagator` for layer ``li`` and its first ``n_modes`` modes only."""
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


@njit(**JIT)
def sine_table(theta, n_max, out):
    """``out[j] = sin(j * theta)`` for j = 0..n_max by the Chebyshev recurrence."""
    out[0] = 0.0
    if n_max >= 1:
        out[1] = math.sin(theta)
    two_c = 2.0 * math.cos(theta)
    for j in range(2, n_max + 1):
        out[j] = two_c * out[j - 1] - out[j - 2]


@njit(**JIT)
def layer_point_displacement(q_l, cx, cy, mode_m, mode_n, patch_a, patch_b, x, y, sx_buf, sy_buf):
    """One layer's displacement (m, down) at ``(x, y)``: eq 2 summed over its modes, on the
    patch ``[cx - a/2, cx + a/2] x [cy - b/2, cy + b/2]``; zero outside the patch."""
    xi = x - cx + 0.5 * patch_a
    eta = y - cy + 0.5 * patch_b
    if xi <= 0.0 or xi >= patch_a or eta <= 0.0 or eta >= patch_b:
        return 0.0
    sine_table(math.pi * xi / patch_a, sx_buf.shape[0] - 1, sx_buf)
    sine_table(math.pi * eta / patch_b, sy_buf.shape[0] - 1, sy_buf)
    u = 0.0
    for kk in range(q_l.shape[0]):
        u += q_l[kk] * sx_buf[mode_m[kk]] * sy_buf[mode_n[kk]]
    return u


# Kernel arguments are grouped into a few arrays (the numba dispatcher pays ~0.1 us per argument):
#   lp (LP_SIZE, L)       per-layer properties, and the interfaces in the LP_IF_* rows (column j = interface j)
#   sp (SP_SIZE,)         scalars
#   bmodes (V + L, K)     modal basis: rows [0, V) beta_table, rows [V, V + L) lambda   (modal.ModalBasis)
#   bvec (V + L,)         [0, V) truncation bound per level, [V, V + L) damping rate gamma
#   blev (2, V) int64     k_prefix, m_lim per level
#   bk (2, K) int64       mode_m, mode_n
#   mstate (6, L, K)      q, v, and the cached propagator P11, P12, P21, P22
#   lstate (LS_SIZE, L)   per-layer float state (LS_*)
#   istate (IS_SIZE, L)   per-layer int state (IS_*)
#   aux (AUX_SIZE, L + 1) per-layer scratch (AUX_*); sbuf (2, M + 1) sine tables
#   out (OUT_SIZE,)       results (OUT_*), also the contact state carried between ticks (layered form)
LP_K = 0  # Kelvin-Voigt spring k (N/m), eq 6
LP_B = 1  # Kelvin-Voigt damper b (N s/m), eq 6
LP_AREA = 2  # loaded area A (m^2), eq 6 (paper form)
LP_EA = 3  # k times mean thickness (N): the layer's modulus times the tool area (layered form)
LP_N = 4  # stiffening exponent n of the compression law (layered form)
LP_IF_MEAN = 5  # interface mean depth (m)
LP_IF_AMP = 6  # interface egg-carton amplitude (m)
LP_IF_KX = 7  # 2 pi / wavelength_x
LP_IF_KY = 8
LP_SIZE = 9
SP_BOTTOM = 0  # tissue bottom (m)
SP_HALF_X = 1
SP_HALF_Y = 2
SP_PATCH_A = 3
SP_PATCH_B = 4
SP_MODE_TOL = 5
SP_SETTLE_TOL = 6
SP_SKIP_SETTLED = 7  # 1.0: skip settled layers (lod.affected_layers)
SP_TOOL_R = 8  # tool radius (m): flat punch radius or sphere radius
SP_SPHERE = 9  # 1.0: spherical tip
SP_MU = 10  # Coulomb friction coefficient
SP_V_SLIP = 11  # viscous regularisation speed of the friction (m/s)
SP_WALL = 12  # strain beyond which the compression law continues linearly (the wall)
SP_SIZE = 16
LS_COMP = 0  # compression (m)
LS_DROPPED = 1  # displacement bound shed with outer modes since last driven (m)
LS_AMP = 2  # bound on a free layer's future displacement (m); inf when driven
LS_PROP_DT = 3  # dt of the cached propagator
LS_CX = 4  # patch centre x, y (m)
LS_CY = 5
LS_SIZE = 6
IS_DRIVEN = 0
IS_LEVEL = 1  # index into the basis levels (mode count)
IS_ACTIVE = 2
IS_PROP_K = 3  # modes in the cached propagator
IS_SIZE = 4
AUX_BOUNDS = 0  # layer tops under the tool and the bottom (L + 1)
AUX_THICK = 1
AUX_SPLIT = 2  # Reuss compressions (paper form)
AUX_C_OLD = 3  # chain compressions at the previous tick (layered form)
AUX_C = 4  # chain compressions now
AUX_G = 5  # dT/dc_i of each layer's backward-Euler residual (N/m)
AUX_DBX = 6  # d(interface depth)/dx of the averaged interfaces
AUX_DBY = 7
AUX_DBD = 8  # d(interface depth)/d(depth) through the contact radius (sphere)
AUX_SIZE = 9


@njit(**JIT)
def prepare_propagators(bmodes, bvec, blev, dt, mstate, lstate, istate):
    """Every layer's propagator for ``dt`` at its current level (cached: ``LS_PROP_DT``, ``IS_PROP_K``)."""
    nv = blev.shape[1]
    for li in range(istate.shape[1]):
        nk = blev[0, istate[IS_LEVEL, li]]
        if lstate[LS_PROP_DT, li] != dt or istate[IS_PROP_K, li] < nk:
            layer_propagator(bmodes[nv:], bvec[nv:], dt, li, nk, mstate[2:6])
            lstate[LS_PROP_DT, li] = dt
            istate[IS_PROP_K, li] = nk


@njit(**JIT)
def layer_at(li, x, y, sp, blev, bk, mstate, lstate, istate, sbuf):
    """Layer ``li``'s downward displacement (m) at ``(x, y)`` at its current level (eq 2)."""
    lv = istate[IS_LEVEL, li]
    nk = blev[0, lv]
    ml = blev[1, lv] + 1
    return layer_point_displacement(
        mstate[0, li, :nk], lstate[LS_CX, li], lstate[LS_CY, li], bk[0, :nk], bk[1, :nk], sp[SP_PATCH_A], sp[SP_PATCH_B],
        x, y, sbuf[0, :ml], sbuf[1, :ml],
    )  # fmt: skip


@njit(**JIT)
def surface_at(x, y, sp, blev, bk, mstate, lstate, istate, sbuf):
    """Downward surface displacement (m) at ``(x, y)``: eq 2 summed over the active layers."""
    surface = 0.0
    for li in range(istate.shape[1]):
        if istate[IS_ACTIVE, li]:
            surface += layer_at(li, x, y, sp, blev, bk, mstate, lstate, istate, sbuf)
    return surface


@njit(**JIT)
def drive_layer(li, comp_m, rate_m_s, x, y, sp, bmodes, bvec, blev, mstate, lstate, istate):
    """Drive layer ``li`` quasi-statically: ``q = dx_l beta``, ``v = dxdot_l beta``, centred on the tool.

    With several levels (adaptive modes) the layer takes the smallest level whose truncation
    bound ``|dx_l| trunc_err`` is within ``sp[SP_MODE_TOL]``.
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


@njit(**JIT)
def relax_layer(li, dt, sp, bmodes, bvec, blev, mstate, lstate, istate):
    """Advance a free layer by the exact damped modal propagator (release and return, eq 2).

    Keeps the displacement bound ``amp[l] = sum_k sqrt(q_k^2 + (v_k/lam_k)^2)`` when
    ``settle_tol > 0``; sheds the outermost shell of modes once its bound, added to what the layer
    already shed since it was last driven, is within the mode tolerance; with ``skip_settled`` a
    layer below ``settle_tol`` is set to rest (``active = 0``).
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


@njit(**JIT)
def settled_flag(sp, lstate, istate):
    """1.0 when no layer is driven and every layer's displacement bound is below ``settle_tol``."""
    settle_tol = sp[SP_SETTLE_TOL]
    if settle_tol <= 0.0:
        return 0.0
    for li in range(istate.shape[1]):
        if istate[IS_DRIVEN, li] or not lstate[LS_AMP, li] < settle_tol:
            return 0.0
    return 1.0


@njit(**JIT)
def step_kernel(tool_x, tool_y, tool_z, tool_vz, dt, lp, sp, bmodes, bvec, blev, bk, mstate, lstate, istate, aux, sbuf, out):
    """One haptic tick of the paper's layered model: contact, Reuss force and modal state.

    Steps 1-5 of section II.D.4. Layers the tool affects (Fig 3) are driven quasi-statically
    (``q = dx_l * beta``, centred on the tool, :func:`drive_layer`); the others evolve freely with
    the exact damped modal propagator (release and return, :func:`relax_layer`). Contact is
    unilateral and is tested against the current deformed surface. Writes ``out`` (see ``OUT_*``)
    and returns flags. Arguments: the grouped arrays described above ``LP_K``.

    Level of detail: layer ``l`` uses the first ``k_prefix[level[l]]`` modes; with several levels
    (adaptive modes) a driven layer takes the smallest level whose truncation bound is within the
    mode tolerance. With ``settle_tol > 0`` a free layer's displacement bound is kept; with
    ``skip_settled`` a layer below ``settle_tol`` is set to rest and skipped while inactive.
    """
    n_layers = istate.shape[1]
    flags = 0
    if not sp[SP_SKIP_SETTLED] > 0.0:  # every layer's propagator, driven or not, as without the lever
        prepare_propagators(bmodes, bvec, blev, dt, mstate, lstate, istate)
    depth = -tool_z
    velocity = -tool_vz
    was_contact = False
    for li in range(n_layers):
        if istate[IS_DRIVEN, li]:
            was_contact = True
    surface = surface_at(tool_x, tool_y, sp, blev, bk, mstate, lstate, istate, sbuf)
    on_sheet = abs(tool_x) <= sp[SP_HALF_X] and abs(tool_y) <= sp[SP_HALF_Y]
    if not on_sheet:
        flags |= FLAG_OFF_SHEET
    n = 0
    force = 0.0
    sigma = 0.0
    d_eff = 0.0
    bounds = aux[AUX_BOUNDS]
    thick = aux[AUX_THICK, :n_layers]
    split = aux[AUX_SPLIT, :n_layers]
    touching = on_sheet and depth > 0.0 and (was_contact or depth >= surface)
    if touching:
        ni = n_layers - 1
        layer_bounds(tool_x, tool_y, lp[LP_IF_MEAN, :ni], lp[LP_IF_AMP, :ni], lp[LP_IF_KX, :ni], lp[LP_IF_KY, :ni],
                     sp[SP_BOTTOM], bounds)  # fmt: skip
        d_eff = depth
        if depth > bounds[n_layers]:
            d_eff = bounds[n_layers]
            flags |= FLAG_BOTTOMED
        n = count_affected(d_eff, bounds)
        for li in range(n_layers):
            thick[li] = bounds[li + 1] - bounds[li]
        sigma, force, hit = reuss_split(n, d_eff, velocity, lp[LP_K], lp[LP_B], lp[LP_AREA], thick, split)
        if hit:
            flags |= FLAG_LAYER_BOUND
        if force <= 0.0 or sigma <= 0.0:
            touching = False
            force = 0.0
            sigma = 0.0
            flags |= FLAG_SEPARATED
    if touching:
        flags |= FLAG_CONTACT
    else:
        n = 0
    for li in range(n_layers):
        if li < n:
            share = split[li] / d_eff  # layer's part of the tool velocity (common velocity, eq 6); round-off safe
            drive_layer(li, split[li], velocity * min(1.0, max(0.0, share)), tool_x, tool_y, sp, bmodes, bvec, blev,
                        mstate, lstate, istate)  # fmt: skip
        else:
            lstate[LS_COMP, li] = 0.0
            relax_layer(li, dt, sp, bmodes, bvec, blev, mstate, lstate, istate)
    out[OUT_FORCE_N] = force
    out[OUT_STRESS_PA] = sigma
    out[OUT_DEPTH_M] = d_eff
    out[OUT_N_AFFECTED] = n
    out[OUT_SURFACE_M] = surface
    out[OUT_SETTLED] = settled_flag(sp, lstate, istate)
    out[OUT_FX] = 0.0
    out[OUT_FY] = 0.0
    out[OUT_FZ] = force
    out[OUT_NX] = 0.0
    out[OUT_NY] = 0.0
    out[OUT_NZ] = 1.0
    out[OUT_RADIUS_M] = sp[SP_TOOL_R] if touching else 0.0
    return flags


@njit(**JIT)
def layer_field(q_l, cx, cy, mode_m, mode_n, m_used, n_used, patch_a, patch_b, xs, ys, q_dense, sx, sy, tmp, out):
    """One layer's displacement field on the sheet grid (cell centres ``xs``, ``ys``).

    Eq 2 evaluated separably: ``u[iy, ix] = sum_n Sy[n, iy] sum_m Q[m, n] Sx[m, ix]``, only on
    the cells inside the patch centred at ``(cx, cy)``; cells outside it are zero, and the
    patch is clipped where it passes the sheet edge (the paper's incomplete deformation).
    ``m_used``/``n_used`` are the distinct 1-based mode indices present (rows/columns of Q
    that can be nonzero). Scratch: ``q_dense`` (M, N), ``sx`` (M+1, nx), ``sy`` (N+1, ny),
    ``tmp`` (N+1, nx).
    """
    out[:, :] = 0.0
    ix0, ix1 = patch_range(xs, cx, patch_a)
    iy0, iy1 = patch_range(ys, cy, patch_b)
    layer_field_box(q_l, cx, cy, mode_m, mode_n, m_used, n_used, patch_a, patch_b, xs, ys, ix0, ix1, iy0, iy1,
                    q_dense, sx, sy, tmp, out)  # fmt: skip


@njit(**JIT)
def layer_field_box(q_l, cx, cy, mode_m, mode_n, m_used, n_used, patch_a, patch_b, xs, ys, ix0, ix1, iy0, iy1,
                    q_dense, sx, sy, tmp, out):  # fmt: skip
    """:func:`layer_field` on the cells ``[iy0, iy1) x [ix0, ix1)`` only; other cells are not written.

    Cells of the box outside the patch are set to zero, so a box larger than the patch (the
    whole sheet) gives the same field. ``q_dense`` rows/columns beyond ``m_used``/``n_used`` are
    never read.
    """
    if ix0 >= ix1 or iy0 >= iy1:
        return
    for jm in range(m_used.shape[0]):
        for jn in range(n_used.shape[0]):
            q_dense[m_used[jm] - 1, n_used[jn] - 1] = 0.0
    for kk in range(q_l.shape[0]):
        q_dense[mode_m[kk] - 1, mode_n[kk] - 1] = q_l[kk]
    m_top = m_used[m_used.shape[0] - 1]
    n_top = n_used[n_used.shape[0] - 1]
    for ix in range(ix0, ix1):
        sine_table(math.pi * (xs[ix] - cx + 0.5 * patch_a) / patch_a, m_top, sx[:, ix])
    for iy in range(iy0, iy1):
        sine_table(math.pi * (ys[iy] - cy + 0.5 * patch_b) / patch_b, n_top, sy[:, iy])
    for jn in range(n_used.shape[0]):
        nn = n_used[jn] - 1
        for ix in range(ix0, ix1):
            acc = 0.0
            for jm in range(m_used.shape[0]):
                mm = m_used[jm] - 1
                acc += q_dense[mm, nn] * sx[mm + 1, ix]
            tmp[nn, ix] = acc
    lo_x = cx - 0.5 * patch_a
    hi_x = cx + 0.5 * patch_a
    lo_y = cy - 0.5 * patch_b
    hi_y = cy + 0.5 * patch_b
    for iy in range(iy0, iy1):
        in_y = ys[iy] > lo_y and ys[iy] < hi_y
        for ix in range(ix0, ix1):
            if in_y and xs[ix] > lo_x and xs[ix] < hi_x:
                acc = 0.0
                for jn in range(n_used.shape[0]):
                    nn = n_used[jn] - 1
                    acc += sy[nn + 1, iy] * tmp[nn, ix]
                out[iy, ix] = acc
            else:
                out[iy, ix] = 0.0


@njit(**JIT)
def patch_range(centres, c, side):
    """Index range of grid cell centres strictly inside ``(c - side/2, c + side/2)``."""
    lo = c - 0.5 * side
    hi = c + 0.5 * side
    i0 = 0
    while i0 < centres.shape[0] and centres[i0] <= lo:
        i0 += 1
    i1 = i0
    while i1 < centres.shape[0] and centres[i1] < hi:
        i1 += 1
    return i0, i1


@njit(**JIT)
def assemble_heights(disp, rest_tops, out_heights):
    """Heights (m, z up) of the surface and each interface from per-layer displacements.

    Step 6 of section II.D.4: the surface moves down by the sum of all layers'
    displacements; interface j (top of layer j) by the sum over layers j and below.
    ``disp`` (L, ny, nx); ``rest_tops`` (L, ny, nx) rest depths of layer tops (0 for the
    surface); ``out_heights`` (L, ny, nx).
    """
    assemble_heights_box(disp, rest_tops, 0, disp.shape[2], 0, disp.shape[1], out_heights)


@njit(**JIT)
def assemble_heights_box(disp, rest_tops, ix0, ix1, iy0, iy1, out_heights):
    """:func:`assemble_heights` on the cells ``[iy0, iy1) x [ix0, ix1)`` only."""
    last = disp.shape[0] - 1
    for iy in range(iy0, iy1):
        for ix in range(ix0, ix1):
            out_heights[last, iy, ix] = -rest_tops[last, iy, ix] - disp[last, iy, ix]
    for li in range(last - 1, -1, -1):  # h_l = h_{l+1} + rest_{l+1} - rest_l - u_l
        for iy in range(iy0, iy1):
            for ix in range(ix0, ix1):
                out_heights[li, iy, ix] = (
                    out_heights[li + 1, iy, ix] + rest_tops[li + 1, iy, ix] - rest_tops[li, iy, ix] - disp[li, iy, ix]
                )


@njit(**JIT)
def modal_energy(q, v, lam):
    """Per-layer modal energy per unit modal mass: ``sum(v^2 + lam^2 q^2) / 2``."""
    total = 0.0
    for li in range(q.shape[0]):
        for kk in range(q.shape[1]):
            total += 0.5 * (v[li, kk] ** 2 + (lam[li, kk] * q[li, kk]) ** 2)
    return total


# --- baseline membrane solvers (skin_sim_node.solvers) -------------------------------------
# One layer's PDE, rho u_tt + c u_t = T (u_xx + u_yy) - k u + p, on interior nodes of a
# rectangle with u = 0 on the edges. Used for the accuracy and stability comparisons.


@njit(**JIT)
def leapfrog_membrane_steps(u, u_prev, load, n_steps, dt, rho, tension, damping, foundation, dx, dy, tmp):
    """``n_steps`` of the explicit central-difference (leapfrog) scheme, in place.

    ``u`` holds t_n and ``u_prev`` t_(n-1) on entry, t_(n+k) and t_(n+k-1) on exit. The damping
    term is central, ``c (u+ - u-) / (2 dt)``, so the limit is ``omega_max dt <= 2`` for any ``c``.
    """
    ny, nx = u.shape
    a = rho / (dt * dt) + damping / (2.0 * dt)
    bm = rho / (dt * dt) - damping / (2.0 * dt)
    two_rho = 2.0 * rho / (dt * dt)
    idx2 = 1.0 / (dx * dx)
    idy2 = 1.0 / (dy * dy)
    for _ in range(n_steps):
        for j in range(ny):
            for i in range(nx):
                c = u[j, i]
                left = u[j, i - 1] if i > 0 else 0.0
                right = u[j, i + 1] if i < nx - 1 else 0.0
                down = u[j - 1, i] if j > 0 else 0.0
                up = u[j + 1, i] if j < ny - 1 else 0.0
                lap = (left - 2.0 * c + right) * idx2 + (down - 2.0 * c + up) * idy2
                tmp[j, i] = (two_rho * c - bm * u_prev[j, i] + tension * lap - foundation * c + load[j, i]) / a
        for j in range(ny):
            for i in range(nx):
                u_prev[j, i] = u[j, i]
                u[j, i] = tmp[j, i]


@njit(**JIT)
def mass_spring_steps(u, v, load, n_steps, dt, mass, k_x, k_y, k_ground, c_ground, c_edge, acc):
    """``n_steps`` of a Kelvin-Voigt mass-spring grid by semi-implicit (symplectic) Euler, in place.

    Node forces: neighbour springs ``k_x``/``k_y`` (N/m), ground spring ``k_ground`` and damper
    ``c_ground``, edge dampers ``c_edge`` (N*s/m), external ``load`` (N). Fixed edge nodes sit
    outside the array (u = v = 0). ``v += dt a(u, v)``, then ``u += dt v``: damping is explicit.
    """
    ny, nx = u.shape
    inv_m = 1.0 / mass
    for _ in range(n_steps):
        for j in range(ny):
            for i in range(nx):
                c = u[j, i]
                cv = v[j, i]
                left = u[j, i - 1] if i > 0 else 0.0
                right = u[j, i + 1] if i < nx - 1 else 0.0
                down = u[j - 1, i] if j > 0 else 0.0
                up = u[j + 1, i] if j < ny - 1 else 0.0
                vl = v[j, i - 1] if i > 0 else 0.0
                vr = v[j, i + 1] if i < nx - 1 else 0.0
                vd = v[j - 1, i] if j > 0 else 0.0
                vu = v[j + 1, i] if j < ny - 1 else 0.0
                f = k_x * (left - 2.0 * c + right) + k_y * (down - 2.0 * c + up) - k_ground * c - c_ground * cv
                f += c_edge * (vl + vr + vd + vu - 4.0 * cv) + load[j, i]
                acc[j, i] = f * inv_m
        for j in range(ny):
            for i in range(nx):
                v[j, i] += dt * acc[j, i]
                u[j, i] += dt * v[j, i]
