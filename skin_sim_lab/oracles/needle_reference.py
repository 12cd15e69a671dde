"""The needle's pure-Python/NumPy reference (issue 22's first cut of :mod:`.needle`; issue 31: the tented skin's
normal reaction and friction before a rupture, the tip skating, and each layer's cutting fade; issue 31 review: the
tent's friction is the presliding anchor of :mod:`~skin_sim_node.model.friction`, the puncture criterion its normal
reaction).

:class:`NumpyNeedleModel` steps the physics of :mod:`.needle` (its module docstring) with NumPy and Python loops: the
interface crossings by a 2 um scan and bisection, the rupture insertion by bisection on the normal law, the tent's friction by
:func:`~skin_sim_node.model.friction.presliding_reference`, the law's
look-ahead by stepping copies of the model. Far too slow for a haptic tick (a track start takes tens of milliseconds);
:mod:`.needle_kernels` are tested against it compiled and as ``.py_func`` (tests/test_needle_kernels.py), as the
tissue's kernels are against :mod:`.reference`.
"""

from __future__ import annotations

import math

import numpy as np

from msgs_schema.contact_model import NeedleLaw
from skin_sim_node.model.calibration import CALIBRATED_TOOL_RADIUS_M, WALL_STRAIN, youngs_moduli_pa
from skin_sim_node.model.config import TissueConfig, equilibrium
from skin_sim_node.model.friction import presliding_reference
from skin_sim_node.model.interfaces import interface_depths_m
from skin_sim_node.model.layered_law import chain_solve
from skin_sim_node.model.layout import LP_EA, LP_N, pack_layers
from skin_sim_node.model.needle import LATERAL_FACTOR, MIN_ANGLE_RAD, NeedleParams, NeedleTick


class NumpyNeedleModel:
    """The needle of :class:`~.needle.NeedleModel` in pure Python/NumPy (the first cut, unchanged): the slow reference
    its kernels are tested against; same API and attributes."""

    def __init__(self, cfg: TissueConfig, params: NeedleParams | None = None):
        self.cfg = equilibrium(cfg)
        self.params = params or NeedleParams()
        lp = pack_layers(self.cfg)
        self._ea = lp[LP_EA].copy()
        self._n = lp[LP_N].copy()
        self._h = np.array([la.thickness_m for la in self.cfg.layers])
        self._moduli = np.array(youngs_moduli_pa(self.cfg))
        self._scale = (0.5 * self.params.outer_diameter_m + self.cfg.foundation_length_m) / CALIBRATED_TOOL_RADIUS_M  # the tent
        # the tent's stick stiffness: kappa F_p / w*, w* the normal depth where N reaches F_p (bisection)
        self._tent_k = np.zeros(len(self._h))
        for i in range(len(self._h)):
            fp = self.params.puncture_force_n(i)
            lo, hi = 0.0, 1e-4
            while self._normal_at(i, hi) < fp:
                hi *= 2.0
            for _ in range(200):
                mid = 0.5 * (lo + hi)
                if mid <= lo or mid >= hi:
                    break
                lo, hi = (mid, hi) if self._normal_at(i, mid) < fp else (lo, mid)
            self._tent_k[i] = self.params.tent_shear_ratio * fp / (0.5 * (lo + hi))
        self.reset()

    def reset(self, keep_tent: bool = False) -> None:
        """Needle out of the tissue: no track (``keep_tent``: the tent's anchor kept for the next track)."""
        nl = len(self._h)
        if not keep_tent:
            self.anchor: np.ndarray | None = None  # the tent's stuck point (x, y) on the surface plane; None: no tent
        self.dev_z = 0.0  # the tip's height off the axis at the last step
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
        self.reset(keep_tent=True)
        self.inserted = True
        self.axis = axis.copy()
        self.entry = tip - (tip[2] / axis[2]) * axis
        for j in range(len(self._h) + 1):
            self.crossings[j] = self._crossing(j)
        return True

    # --- laws ---------------------------------------------------------------------------------
    def _normal_at(self, layer: int, wn: float) -> float:
        """The tent's normal reaction ``N = scale T(w_n)`` (N) at the normal depth ``w_n``."""
        if wn <= 0.0:
            return 0.0
        sub = slice(layer, len(self._h))
        n = self._h[sub].size
        c, g = np.zeros(n), np.zeros(n)
        t = chain_solve(wn, 0.0, self._ea[sub].copy(), self._n[sub].copy(), np.zeros(n), 1.0,
                        np.zeros(n), self._h[sub].copy(), WALL_STRAIN, np.zeros(n), c, g)  # fmt: skip
        return self._scale * max(t, 0.0)

    def dimple_force_n(self, layer: int, w_m: float) -> float:
        """The tent's normal reaction ``N`` (N) below ``layer``'s top pressed ``w_m`` along the axis (on the axis)."""
        return self._normal_at(layer, w_m * -self.axis[2])

    def rupture_insertion_m(self) -> float:
        """Insertion ``L`` (m) at which the next intact layer ruptures, the tip advancing along the axis at its height
        off it: ``N`` reaches ``F_p`` (bisection on the monotone normal law); inf when every layer is ruptured or the
        dimple never reaches it."""
        k = self.ruptured
        if not self.inserted or k >= len(self._h):
            return math.inf
        fp = self.params.puncture_force_n(k)
        hi = 1e-4
        while self._normal_at(k, hi) < fp:
            hi *= 2.0
            if hi > 1.0:
                return math.inf
        lo = 0.0
        for _ in range(200):
            mid = 0.5 * (lo + hi)
            if mid <= lo or mid >= hi:
                break
            lo, hi = (mid, hi) if self._normal_at(k, mid) < fp else (lo, mid)
        return float(self.crossings[k] + (hi + self.dev_z) / -self.axis[2])

    def copy(self) -> NumpyNeedleModel:
        """An independent copy (state arrays included) for look-ahead."""
        c = object.__new__(type(self))
        c.__dict__.update(self.__dict__)
        for name in ("entry", "axis", "crossings", "dahl"):
            setattr(c, name, getattr(self, name).copy())
        c.anchor = None if self.anchor is None else self.anchor.copy()
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
        re0 = tick.dimple_n + tick.cutting_n  # the slopes are of dimple and cutting; the bed's part is added at x0
        ahead = self.copy()
        t1 = ahead.step(np.asarray(tip_m) + h * self.axis, self.axis)
        slope = (t1.dimple_n + t1.cutting_n - re0) / h if t1.ruptured == tick.ruptured else 0.0
        slope_behind = slope
        if ins - h > 0.0:  # behind: the cutting force fades behind the crack front
            b = self.copy().step(np.asarray(tip_m) - h * self.axis, self.axis)
            if b.ruptured == tick.ruptured:
                slope_behind = (re0 - (b.dimple_n + b.cutting_n)) / h
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
            axial_force_n=re0 + tick.bed_n,
            axial_gradient_n_per_m=slope,
            axial_gradient_behind_n_per_m=slope_behind,
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
            self.anchor = None  # no track: no tent either
            return NeedleTick(np.zeros(3))
        ins = float((p - self.entry) @ self.axis)
        if ins <= 0.0:  # withdrawn: the track is forgotten
            self.reset()
            return NeedleTick(np.zeros(3))
        nl = len(self._h)
        punctured = []
        deviation = (p - self.entry) - ins * self.axis
        down = -self.axis[2]
        self.dev_z = float(deviation[2])
        normal = 0.0
        while self.ruptured < nl:  # the criterion: the tent's normal reaction at the tip's normal depth reaches F_p
            wn = (ins - self.crossings[self.ruptured]) * down - deviation[2]
            normal = self._normal_at(self.ruptured, wn)
            if normal < pr.puncture_force_n(self.ruptured):
                break
            punctured.append(self.ruptured)
            self.ruptured += 1
            self.anchor = None  # the next layer's tent is a new contact
            normal = 0.0
        # the tent: N along +z and the presliding friction of the tip on it (friction.presliding_reference)
        f_tent = np.zeros(3)
        dimple = w_dimple = 0.0
        if self.ruptured < nl and normal > 0.0:
            tip_plane = np.array([p[0], p[1], 0.0])
            z0 = tip_plane if self.anchor is None else np.array([self.anchor[0], self.anchor[1], 0.0])
            z_new, f_t, _ = presliding_reference(tip_plane, (0.0, 0.0, 1.0), z0, self._tent_k[self.ruptured],
                                                 pr.tip_friction * normal)  # fmt: skip
            self.anchor = z_new[:2].copy()
            f_tent = f_t + normal * np.array([0.0, 0.0, 1.0])
            dimple = -float(f_tent @ self.axis)
            w_dimple = wn / down
        else:
            self.anchor = None
        tent_lateral = f_tent + dimple * self.axis
        lam = pr.lubrication_factor
        # cutting at the crack front, inside the ruptured part of the track
        cut = 0.0
        inside = self.ruptured > 0 and (self.ruptured == nl or ins < self.crossings[self.ruptured])
        if inside:
            j = int(np.searchsorted(self.crossings[: self.ruptured + 1], ins, side="right")) - 1
            j = min(max(j, 0), self.ruptured - 1)
            if j == nl - 1 or self.front_m < self.crossings[j + 1]:  # a layer cut through has nothing left to cut
                xc = pr.cut_fade_m(j)
                ramp = min(max((ins - self.front_m + xc) / xc, 0.0), 1.0)
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
        lateral_dk = 0.0
        for i in range(self.ruptured):
            length = min(max(ins, self.crossings[i]), self.crossings[i + 1]) - self.crossings[i]
            if self.crossings[i] < ins < self.crossings[i + 1]:
                lateral_dk += LATERAL_FACTOR * self._moduli[i]
            if step != 0.0:
                sigma = math.copysign(1.0, step)
                self.dahl[i] = sigma + (self.dahl[i] - sigma) * math.exp(-abs(step) / pr.dahl_length_m)
            fric += lam * pr.shaft_shear_pa * math.pi * pr.outer_diameter_m * length * self.dahl[i]
            lateral_k += LATERAL_FACTOR * self._moduli[i] * length
        bed = 0.25 * lateral_dk * float(deviation @ deviation)  # the bed's axial part: gradient of k(L) |delta|^2 / 4
        axial = dimple + cut + fric + bed
        lateral = -0.5 * lateral_k * deviation
        force = -axial * self.axis + lateral + tent_lateral
        return NeedleTick(force, axial, dimple, cut, fric, lateral, w_dimple, ins, self.ruptured, tuple(punctured), bed,
                          0.0, normal, float(np.hypot(f_tent[0], f_tent[1])), tent_lateral)  # fmt: skip
