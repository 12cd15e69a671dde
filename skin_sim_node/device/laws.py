"""The contact model's laws as the device renders them between server updates (pure): the legacy velocity friction
law, the presliding friction's anchor update (issue 30) and the needle's axial law (issue 22). The renderer
(:class:`skin_sim_node.device.render.ContactRenderer`) composes them; each is tested on its own against the model's
kernels."""

from __future__ import annotations

import math

import numpy as np

from msgs_schema.contact_model import LocalModel, NeedleLaw


def _finite(v) -> bool:
    return bool(np.isfinite(v).all())


def friction_law_force(normal, fn: float, mu: float, slip_speed_m_s: float, v) -> np.ndarray:
    """``F_n (n - mu v_t / sqrt(|v_t|^2 + v_s^2))``, ``v_t = (I - n n^T) v`` (N): the layered form's contact force
    (:func:`skin_sim_node.model.layered_contact.contact_jacobians`) at normal force ``fn`` and tool velocity ``v``.

    Its tangential part opposes ``v_t`` (``F . v_t = -mu F_n |v_t|^2 / r <= 0``: it only dissipates) and is at most
    ``mu F_n``. ``slip_speed_m_s`` 0 with ``v_t`` 0: no friction (the sign is undefined; the law's limit is 0).
    """
    n = normal
    f = fn * n
    if mu <= 0.0 or v is None:
        return f
    vt = v - float(n @ v) * n
    r = math.sqrt(float(vt @ vt) + slip_speed_m_s * slip_speed_m_s)
    return f - (fn * mu / r) * vt if r > 0.0 else f


def presliding_update(x, n, z, k_t: float, limit_n: float) -> tuple[float, float, float, float, float, float, float]:
    """The presliding law's step at the device (plain Python, the same operations in the same order as the model's
    kernel :func:`skin_sim_node.model.friction.presliding_step`, so the same inputs give the same bits).

    Parameters
    ----------
    x, n, z : sequence of 3 float
        Device position (m), unit contact normal, anchor before the step (m).
    k_t, limit_n : float
        Presliding stiffness (N/m) and slip level ``mu F_n`` (N); either ``<= 0``: no friction.

    Returns
    -------
    tuple of 7 float
        The new anchor (m), the friction force ``-k_t s`` (N) and how far the anchor slipped (m).
    """
    zx, zy, zz = float(z[0]), float(z[1]), float(z[2])
    nx, ny, nz = float(n[0]), float(n[1]), float(n[2])
    dx = float(x[0]) - zx
    dy = float(x[1]) - zy
    dz = float(x[2]) - zz
    dn = dx * nx + dy * ny + dz * nz
    sx = dx - dn * nx
    sy = dy - dn * ny
    sz = dz - dn * nz
    s = math.sqrt(sx * sx + sy * sy + sz * sz)
    if k_t <= 0.0 or limit_n <= 0.0:
        return zx + sx, zy + sy, zz + sz, 0.0, 0.0, 0.0, s
    r = limit_n / k_t
    slip = 0.0
    if s > r:
        slip = s - r
        w = slip / s
        zx += w * sx
        zy += w * sy
        zz += w * sz
        w = r / s
        sx *= w
        sy *= w
        sz *= w
    return zx, zy, zz, -k_t * sx, -k_t * sy, -k_t * sz, slip


class PreslidingRender:
    """A model's presliding friction as the renderer evaluates it, with its own anchor (issue 30; ``ContactModel.msg``).

    ``F(x) = F_n(x) n - k_t s(x) + residual``, the anchor starting at the model's ``friction_anchor_m`` and moved by
    :func:`presliding_update` at every evaluation (the same ``x`` twice moves it no further: a blend's second
    evaluation changes nothing). Caps: ``grad(F_n)`` and ``k_t`` each at the device's stiffness cap (the law's ``K``,
    ``n grad^T - k_t P`` when sticking, then has norm at most the cap); a capped ``k_t`` starts from the stretch that
    gives the model's tangential force at ``x0``, so ``F(x0) = f0`` still. A new model starts a new anchor (its own).
    """

    __slots__ = ("grad", "k_t", "z", "residual", "slip_m", "slipping")

    def __init__(self, m: LocalModel, max_k: float):
        g = m.normal_force_gradient_n_per_m
        gain = float(np.linalg.norm(g))
        self.grad = g * (max_k / gain) if gain > max_k else g.copy()
        k_model = float(m.tangential_stiffness_n_per_m)
        self.k_t = min(k_model, max_k)
        n = m.normal
        z = np.asarray(m.friction_anchor_m, dtype=float)
        if self.k_t < k_model:  # the same tangential force at x0 from the softer spring: a longer stretch
            d = m.x0_m - z
            s0 = d - float(n @ d) * n
            z = m.x0_m - s0 * (k_model / self.k_t)
        self.z = z.copy()
        self.slip_m = 0.0  # the anchor's slip summed over this model's evaluations (m)
        self.slipping = False  # the last evaluation slipped
        self.residual = np.zeros(3)
        self.residual = m.f0_n - self._law(m, m.x0_m, move=False)

    def _law(self, m: LocalModel, x: np.ndarray, move: bool = True) -> np.ndarray:
        n = m.normal
        fn = m.normal_force_n + float(self.grad @ (x - m.x0_m))
        zx, zy, zz, fx, fy, fz, slip = presliding_update(x, n, self.z, self.k_t, m.friction_coefficient * max(fn, 0.0))
        if move:
            self.z[0], self.z[1], self.z[2] = zx, zy, zz
            self.slip_m += slip
            self.slipping = slip > 0.0
        return fn * n + np.array((fx, fy, fz))

    def force(self, m: LocalModel, x: np.ndarray) -> np.ndarray:
        """The law at ``x`` (N, before the renderer's one-sided rule and cone), moving the anchor to ``x``."""
        f = self._law(m, x)
        if m.normal_force_n > 0.0:  # f0's part beyond the law, shrinking with the normal force as friction does
            fn = m.normal_force_n + float(self.grad @ (x - m.x0_m))
            f = f + self.residual * min(max(fn, 0.0) / m.normal_force_n, 1.0)
        return f


class NeedleRender:
    """A model's needle law as the renderer evaluates it, with its own state (issue 22; ``ContactModel.msg``).

    Along the track's axis ``u``, ``s = u . (x - x0)``::

        F(x) = f0 + (I - u u^T) K (x - x0) + (I - u u^T) D (v - v0) - u (R(s) - R(0)),
        R(s) = max(R_e(s), 0) + F_c(s) z(s),   F_c(s) = max(F_c0 + F_c' s, 0),

    ``R_e`` the line ``axial_force_n + g s`` (``g`` ahead of ``x0``, the slope behind it for ``s < 0``: the cutting
    force fades behind the crack front) until the first ``s >= rupture_distance_m``, from then (latched for the
    rest of this model: a step back does not undo a rupture, so nothing toggles at the threshold) the post-rupture
    line. ``z`` is the Dahl state: it starts from the model's ``friction_state`` at ``x0`` (``s = 0``) and follows the
    device's own axial moves, ``z <- sigma + (z - sigma) exp(-|ds| / x_0)``, exact for any step (rate-independent),
    ``|z| <= 1``. A new model starts a new state (its own ``z`` at its own ``x0``, no latch).

    Physics first, clamps last; how each stage of the renderer's chain applies:

    - **K cap** (the device's largest stable stiffness): ``K`` is capped as for every model before it is projected
      off the axis (so ``(I - u u^T) K`` is within the cap); the axial slopes ``g`` before and after the rupture are
      each capped at it in magnitude (the dimple before a rupture is a stiff spring along the axis, up to
      3.2 N/mm for 18 G: rendered at more than the device holds, it is the active sampled spring the cap exists for);
      the Dahl stick stiffness, at most ``2 F_c / x_0`` at a reversal, is kept under the cap by rendering with
      ``x_0 >= 2 F_c,max / K_cap`` (``F_c,max`` the capacity at the validity radius). The threshold stays where
      the law puts it (``rupture_distance_m``): the cap lowers a steep peak between server updates, never moves the
      drop;
    - **one-sided rule and friction cone**: not applied. The needle is inside the tissue: on retraction the shaft
      friction pulls the tool in, which the flat and sphere paths' "the tissue never pulls" would erase;
      ``max(R_e, 0)`` is the physical one-sidedness of the dimple and the cutting (they only resist insertion);
    - **D**: only its part off the axis; the axial law is rate-independent (Dahl, position laws);
    - **validity radius, time-to-live, fade, crossfade**: unchanged, on the whole vector (a stale or left needle
      model fades out over ``fade_s`` on the device's clock);
    - **magnitude limit**: unchanged, last, on the whole vector (a puncture peak above it is flattened: the bridge's
      ``--force-scale`` scales the vector before it, see ``docs/devices.md``);
    - **passivity observer and controller**: unchanged on the whole vector, except that the controller's damping is
      not projected off the normal (the needle's force may pull along it). The drop itself is passive: the resistance
      falls while the tool advances against it, so the energy the tissue absorbed before it is not returned.
    """

    __slots__ = ("law", "u", "grad", "back_grad", "post_grad", "dahl_length_m", "r0", "z", "s_last", "latched")

    def __init__(self, law: NeedleLaw, max_k: float, radius_m: float):
        self.law = law
        u = np.asarray(law.axis, dtype=float)
        self.u = u / float(np.linalg.norm(u))
        self.grad = float(np.clip(law.axial_gradient_n_per_m, -max_k, max_k))
        self.back_grad = float(np.clip(law.axial_gradient_behind_n_per_m, -max_k, max_k))
        self.post_grad = float(np.clip(law.post_rupture_gradient_n_per_m, -max_k, max_k))
        fc_max = law.friction_capacity_n + abs(law.friction_capacity_gradient_n_per_m) * radius_m
        self.dahl_length_m = max(law.dahl_length_m, 2.0 * fc_max / max_k if max_k > 0 else math.inf)
        self.r0 = law.resistance_n
        self.z = float(law.friction_state)
        self.s_last = 0.0
        self.latched = False

    def resistance(self, s: float) -> float:
        """``R(s)`` (N, > 0 resists insertion) after moving the state to ``s`` (m): Dahl over ``s - s_last``, then the
        latch. Evaluating twice at the same ``s`` gives the same value (no move, no change)."""
        ds = s - self.s_last
        if ds != 0.0:
            sigma = 1.0 if ds > 0.0 else -1.0
            self.z = sigma + (self.z - sigma) * math.exp(-abs(ds) / self.dahl_length_m)
            self.s_last = s
        law = self.law
        if not self.latched and law.rupture_distance_m > 0.0 and s >= law.rupture_distance_m:
            self.latched = True
        if self.latched:
            re = law.post_rupture_force_n + self.post_grad * (s - law.rupture_distance_m)
        else:
            re = law.axial_force_n + (self.grad if s >= 0.0 else self.back_grad) * s
        fc = max(law.friction_capacity_n + law.friction_capacity_gradient_n_per_m * s, 0.0)
        return max(re, 0.0) + fc * self.z

    def force(self, m: LocalModel, K: np.ndarray, D: np.ndarray, x: np.ndarray, v: np.ndarray | None) -> np.ndarray:
        """The needle model's force at ``x`` (and ``v`` for the off-axis ``D`` term), moving the state to ``x``."""
        u = self.u
        dx = x - m.x0_m
        lat = K @ dx
        if v is not None:
            lat = lat + D @ (v - m.v0_m_s)
        lat = lat - float(u @ lat) * u
        return m.f0_n + lat - u * (self.resistance(float(u @ dx)) - self.r0)
