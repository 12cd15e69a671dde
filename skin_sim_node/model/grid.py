"""Grid kernels: each layer's displacement field on the sheet and the heights of the surface and interfaces.

Section II.D.4, step 6: the display grid is built only when asked for (:meth:`SkinModel.build_grid`),
never on the force path. Kernel style as :mod:`.modal_kernels`; each is tested compiled and as
``.py_func`` against :mod:`skin_sim_lab.oracles.reference`. Rows are y, columns x; heights are z up.
"""

from __future__ import annotations

import math

from numba import njit

from .modal_kernels import sine_table


@njit(cache=True, nogil=True)
def layer_field(q_l, cx, cy, mode_m, mode_n, m_used, n_used, patch_a, patch_b, xs, ys, q_dense, sx, sy, tmp, out):
    """One layer's displacement field on the sheet grid (eq 2), evaluated separably.

    ``u[iy, ix] = sum_n Sy[n, iy] sum_m Q[m, n] Sx[m, ix]``, only on the cells inside the patch centred at
    ``(cx, cy)``; cells outside it are zero, and the patch is clipped where it passes the sheet edge (the
    paper's incomplete deformation).

    Parameters
    ----------
    q_l : ndarray, shape (K,)
        The layer's modal amplitudes (m).
    cx, cy : float
        Patch centre (m).
    mode_m, mode_n : ndarray of int64, shape (K,)
        1-based mode indices.
    m_used, n_used : ndarray of int64
        The distinct mode indices present, ascending (the rows and columns of ``Q`` that can be nonzero).
    patch_a, patch_b : float
        Patch sides (m).
    xs, ys : ndarray, shapes (nx,), (ny,)
        Cell centres (m).
    q_dense, sx, sy, tmp : ndarray, shapes (M, N), (M + 1, nx), (N + 1, ny), (N + 1, nx)
        Scratch.
    out : ndarray, shape (ny, nx)
        Written: the displacement (m, down).
    """
    out[:, :] = 0.0
    ix0, ix1 = patch_range(xs, cx, patch_a)
    iy0, iy1 = patch_range(ys, cy, patch_b)
    layer_field_box(
        q_l, cx, cy, mode_m, mode_n, m_used, n_used, patch_a, patch_b, xs, ys, ix0, ix1, iy0, iy1, q_dense, sx, sy, tmp, out
    )


@njit(cache=True, nogil=True)
def layer_field_box(
    q_l, cx, cy, mode_m, mode_n, m_used, n_used, patch_a, patch_b, xs, ys, ix0, ix1, iy0, iy1, q_dense, sx, sy, tmp, out
):
    """:func:`layer_field` (eq 2) on the cells ``[iy0, iy1) x [ix0, ix1)`` only; other cells are not written.

    Cells of the box outside the patch are set to zero, so a box larger than the patch (the
    whole sheet) gives the same field. ``q_dense`` rows/columns beyond ``m_used``/``n_used`` are
    never read.

    Parameters
    ----------
    q_l, cx, cy, mode_m, mode_n, m_used, n_used, patch_a, patch_b, xs, ys, q_dense, sx, sy, tmp, out
        As :func:`layer_field`.
    ix0, ix1, iy0, iy1 : int
        The box (cell indices, end exclusive).
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


@njit(cache=True, nogil=True)
def layer_field_box_rot(
    q_l,
    cx,
    cy,
    mode_m,
    mode_n,
    m_used,
    n_used,
    patch_a,
    patch_b,
    cos_t,
    sin_t,
    xs,
    ys,
    ix0,
    ix1,
    iy0,
    iy1,
    q_dense,
    sx,
    sy,
    tmp,
    out,
):
    """:func:`layer_field_box` (eq 2) of a patch turned by the tension lines' angle (``cos_t``, ``sin_t``).

    At angle 0 this is :func:`layer_field_box` (separable). Turned, a cell's patch coordinates ``xi, eta`` depend on
    both its x and y (:func:`~.modal_kernels.layer_point_displacement_rot`), so each cell inside the patch takes its
    own sine tables and the sum over the layer's modes: ``O(K)`` per cell instead of the separable ``O(M + N)``; the
    display grid only, never the force path. Cells of the box outside the patch are set to zero.

    Parameters
    ----------
    q_l, cx, cy, mode_m, mode_n, m_used, n_used, patch_a, patch_b, xs, ys, ix0, ix1, iy0, iy1, q_dense, sx, sy, tmp, out
        As :func:`layer_field_box`; ``sx[:, 0]`` and ``sy[:, 0]`` are the scratch of a turned patch.
    cos_t, sin_t : float
        Cosine and sine of the angle of the patch's first side from the x axis.
    """
    if sin_t == 0.0 and cos_t == 1.0:
        layer_field_box(
            q_l, cx, cy, mode_m, mode_n, m_used, n_used, patch_a, patch_b, xs, ys, ix0, ix1, iy0, iy1, q_dense, sx, sy, tmp, out
        )
        return
    m_top = m_used[m_used.shape[0] - 1]
    n_top = n_used[n_used.shape[0] - 1]
    sxc = sx[:, 0]
    syc = sy[:, 0]
    for iy in range(iy0, iy1):
        dy = ys[iy] - cy
        for ix in range(ix0, ix1):
            dx = xs[ix] - cx
            xi = cos_t * dx + sin_t * dy + 0.5 * patch_a
            eta = cos_t * dy - sin_t * dx + 0.5 * patch_b
            if xi <= 0.0 or xi >= patch_a or eta <= 0.0 or eta >= patch_b:
                out[iy, ix] = 0.0
                continue
            sine_table(math.pi * xi / patch_a, m_top, sxc)
            sine_table(math.pi * eta / patch_b, n_top, syc)
            acc = 0.0
            for kk in range(q_l.shape[0]):
                acc += q_l[kk] * sxc[mode_m[kk]] * syc[mode_n[kk]]
            out[iy, ix] = acc


@njit(cache=True, nogil=True)
def patch_box(xs, ys, cx, cy, patch_a, patch_b, cos_t, sin_t):
    """Index box of the grid cells that may lie inside a patch turned by ``(cos_t, sin_t)``: its bounding box.

    The turned ``a x b`` patch spans ``|cos| a/2 + |sin| b/2`` in x and ``|sin| a/2 + |cos| b/2`` in y about its
    centre; at angle 0 this is :func:`patch_range` in x and in y.

    Parameters
    ----------
    xs, ys : ndarray
        Cell centres (m), ascending.
    cx, cy : float
        Patch centre (m).
    patch_a, patch_b : float
        Patch sides (m).
    cos_t, sin_t : float
        Cosine and sine of the angle of the patch's first side from the x axis.

    Returns
    -------
    ix0, ix1, iy0, iy1 : int
        The box (cell indices, end exclusive).
    """
    ix0, ix1 = patch_range(xs, cx, abs(cos_t) * patch_a + abs(sin_t) * patch_b)
    iy0, iy1 = patch_range(ys, cy, abs(sin_t) * patch_a + abs(cos_t) * patch_b)
    return ix0, ix1, iy0, iy1


@njit(cache=True, nogil=True)
def patch_range(centres, c, side):
    """Index range of the grid cell centres strictly inside the patch ``(c - side/2, c + side/2)`` (eq 2's support).

    Parameters
    ----------
    centres : ndarray, shape (n,)
        Cell centres (m), ascending.
    c : float
        Patch centre (m).
    side : float
        Patch side (m).

    Returns
    -------
    i0, i1 : int
        First inside and one past the last inside (``i0 == i1``: none).
    """
    lo = c - 0.5 * side
    hi = c + 0.5 * side
    i0 = 0
    while i0 < centres.shape[0] and centres[i0] <= lo:
        i0 += 1
    i1 = i0
    while i1 < centres.shape[0] and centres[i1] < hi:
        i1 += 1
    return i0, i1


@njit(cache=True, nogil=True)
def assemble_heights(disp, rest_tops, out_heights):
    """Heights (m, z up) of the surface and each interface from per-layer displacements (section II.D.4, step 6).

    The surface moves down by the sum of all layers' displacements; interface ``j`` (the top of layer ``j``)
    by the sum over layers ``j`` and below.

    Parameters
    ----------
    disp : ndarray, shape (L, ny, nx)
        Per-layer downward displacements (m).
    rest_tops : ndarray, shape (L, ny, nx)
        Rest depths of the layer tops (m; 0 for the surface).
    out_heights : ndarray, shape (L, ny, nx)
        Written: heights (m, z up).
    """
    assemble_heights_box(disp, rest_tops, 0, disp.shape[2], 0, disp.shape[1], out_heights)


@njit(cache=True, nogil=True)
def assemble_heights_box(disp, rest_tops, ix0, ix1, iy0, iy1, out_heights):
    """:func:`assemble_heights` (section II.D.4, step 6) on the cells ``[iy0, iy1) x [ix0, ix1)`` only.

    Parameters
    ----------
    disp, rest_tops, out_heights
        As :func:`assemble_heights`; other cells of ``out_heights`` are not written.
    ix0, ix1, iy0, iy1 : int
        The box (cell indices, end exclusive).
    """
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
