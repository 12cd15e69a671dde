"""``python -m skin_sim_lab.validation.fit_law``: refit the layered form's equilibrium compression law to the
flat-punch neo-Hookean reference's force *and* its slope (issue 20, item 3a).

What is fitted: the load-spreading factors of dermis and fat (``skin_sim_node.model.calibration.LOAD_SPREADING``: the layer
springs ``k_i = s_i E_i A / h_i``), the stiffening exponent ``n`` (``STIFFENING_EXPONENT``, common to every layer)
and, optionally, the wall strain (``WALL_STRAIN``). The epidermis is not fitted (0.1 % of the chain's compliance).

Against what: the axisymmetric compressible neo-Hookean flat-punch solve at the project's reference level
(:data:`.references.AXI_REFERENCE_LEVEL`, docs/validation/large_deformation.md), default moduli, flat layers; its
linear-law solve on the same mesh for the small-strain stiffness. The reference is quasi-static (hyperelastic
equilibrium), so what is fitted is the chain's **equilibrium elastic law**: the chain solved with its dampers
relaxed (``dt`` large, :data:`.methods.STATIC_DT_S`), at the tool's centre on the default sheet (the fat lobule's
peak under the origin, as ``skin-sim bench-model --physics`` and the issue-20 figures are taken). A slow viscoelastic
branch added to the chain changes the rate response, not this law.

Residuals (each a relative error, least squares): the force at :data:`FORCE_DEPTHS_M`, the slope ``dF/dd`` at
:data:`SLOPE_DEPTHS_M` (the reference's slope: the local quadratic through its three nearest load stops), the
small-strain stiffness (weight :data:`SMALL_STRAIN_WEIGHT`), and a penalty on any layer strain above
:data:`MAX_STRAIN` at 3 mm.
"""

from __future__ import annotations

import argparse

import numpy as np
from scipy.optimize import least_squares

from skin_sim_node.model import SkinModel, TissueConfig, preset
from skin_sim_node.model import calibration as schema
from skin_sim_node.model.layered_law import chain_solve
from skin_sim_node.model.layout import AUX_THICK, LP_EA

from .methods import STATIC_DT_S, static_force_n
from .references import AXI_REFERENCE_LEVEL, axisym

FORCE_DEPTHS_M = (0.1e-3, 0.2e-3, 0.5e-3, 1e-3, 1.5e-3, 2e-3, 2.5e-3, 3e-3)
SLOPE_DEPTHS_M = (0.5e-3, 1e-3, 1.5e-3, 2e-3, 2.5e-3, 3e-3)
SMALL_STRAIN_WEIGHT = 2.0
MAX_STRAIN = 0.9
"""Largest layer strain ``c / h`` allowed at the deepest fit depth (3 mm), as a penalty (weight :data:`STRAIN_WEIGHT`):
a layer cannot be compressed to its thickness, but without this the best fit (wall 0.536) compresses the 1.25 mm
dermis by 117 % at 3 mm (the series columns have no lateral flow, so the fit hides it in one layer's strain)."""
STRAIN_WEIGHT = 10.0
WALL_GRID = tuple(round(0.3 + 0.05 * i, 2) for i in range(14))  # 0.3 .. 0.95: starts of the wall-strain fit


def curve_slope(depths_m, forces_n, at_m) -> float:
    """``dF/dd`` at ``at_m`` of a sampled curve (0 at 0 prepended): the slope of the quadratic through the three
    samples nearest ``at_m``."""
    d = np.concatenate([[0.0], np.asarray(depths_m)])
    f = np.concatenate([[0.0], np.asarray(forces_n)])
    i = int(np.clip(np.searchsorted(d, at_m), 1, len(d) - 2))
    c = np.polyfit(d[i - 1 : i + 2] - at_m, f[i - 1 : i + 2], 2)
    return float(c[1])


def reference_targets(level: int = AXI_REFERENCE_LEVEL) -> dict:
    """The reference's force and slope at the fit depths and its small-strain (linear-law) stiffness."""
    nh = axisym(None, level, progress=False)
    lin = axisym(None, level, law="linear", progress=False)
    return {
        "force": np.array([float(nh.force_n(d)) for d in FORCE_DEPTHS_M]),
        "slope": np.array([curve_slope(nh.depths_m, nh.forces_n, d) for d in SLOPE_DEPTHS_M]),
        "k0": float(lin.force_n(1e-3) / 1e-3),
        "level": level,
    }


class Chain:
    """The default's equilibrium chain at the sheet's origin, with the spreading factors, ``n`` and wall as knobs."""

    def __init__(self, cfg: TissueConfig | None = None):
        self.cfg = cfg or preset("default")
        m = SkinModel(self.cfg)
        static_force_n(m, 0.0, 0.0, 1e-3)
        args = m._form._args  # (lp, sp, ..., aux, sbuf, out)
        self.h = args[9][AUX_THICK, : len(self.cfg.layers)].copy()  # thicknesses under the flat tool at the origin
        self.ea0 = args[0][LP_EA].copy()
        self.s0 = np.array([schema.LOAD_SPREADING[la.name] for la in self.cfg.layers])

    def forces(self, spreading, n, wall, depths_m) -> np.ndarray:
        """Quasi-static chain force (N) at ``depths_m`` (``spreading`` per layer, ``n`` per layer or common)."""
        ea = self.ea0 * np.asarray(spreading) / self.s0
        nn = np.broadcast_to(np.asarray(n, dtype=float), ea.shape).copy()
        b = np.zeros_like(ea)
        c = np.empty_like(ea)
        g = np.empty_like(ea)
        out = []
        for d in depths_m:
            out.append(chain_solve(d, 0.0, ea, nn, b, STATIC_DT_S, np.zeros_like(ea), self.h, wall, np.zeros_like(ea), c, g))
        return np.array(out)

    def slopes(self, spreading, n, wall, depths_m, h: float = 1e-7) -> np.ndarray:
        """``dF/dd`` (N/m) by central differences of :meth:`forces`."""
        d = np.asarray(depths_m)
        return (self.forces(spreading, n, wall, d + h) - self.forces(spreading, n, wall, d - h)) / (2 * h)

    def strains(self, spreading, n, wall, depth_m: float) -> np.ndarray:
        """Each layer's strain ``c_i / h_i`` at ``depth_m``."""
        ea = self.ea0 * np.asarray(spreading) / self.s0
        nn = np.broadcast_to(np.asarray(n, dtype=float), ea.shape).copy()
        c = np.empty_like(ea)
        g = np.empty_like(ea)
        zero = np.zeros_like(ea)  # no dampers, no old compression, no viscoelastic arms: the equilibrium law
        chain_solve(depth_m, 0.0, ea, nn, zero, STATIC_DT_S, zero, self.h, wall, zero, c, g)
        return c / self.h

    def k0(self, spreading) -> float:
        """Small-strain stiffness ``1 / sum(h_i / EA_i)`` (N/m)."""
        ea = self.ea0 * np.asarray(spreading) / self.s0
        return float(1.0 / np.sum(self.h / ea))


def fit(fit_wall: bool = False, level: int = AXI_REFERENCE_LEVEL, per_layer_n: bool = False, max_strain: bool = True) -> dict:
    """Least-squares fit of (dermis, fat spreading, n[, wall]); returns the parameters and the errors."""
    ref = reference_targets(level)
    ch = Chain()
    s_epi = ch.s0[0]

    def unpack(p):
        n = (p[2], p[2], p[3]) if per_layer_n else p[2]
        wall = p[-1] if fit_wall else schema.WALL_STRAIN
        return (s_epi, p[0], p[1]), n, wall

    def res(p):
        s, n, wall = unpack(p)
        rf = ch.forces(s, n, wall, FORCE_DEPTHS_M) / ref["force"] - 1
        rk = ch.slopes(s, n, wall, SLOPE_DEPTHS_M) / ref["slope"] - 1
        r0 = SMALL_STRAIN_WEIGHT * (ch.k0(s) / ref["k0"] - 1)
        over = max(0.0, float(ch.strains(s, n, wall, FORCE_DEPTHS_M[-1]).max()) - MAX_STRAIN) if max_strain else 0.0
        return np.concatenate([rf, rk, [r0, STRAIN_WEIGHT * over]])

    nn = 2 if per_layer_n else 1
    w0 = schema.WALL_STRAIN
    if fit_wall:  # the residual has local minima in the wall strain: start from the best of a grid
        grid = []
        for w in WALL_GRID:
            g = least_squares(
                lambda q, w=w: res(np.concatenate([q, [w]])),
                [ch.s0[1], ch.s0[2]] + [0.3] * nn,
                bounds=([1.0, 1.0] + [0.0] * nn, [8.8, 8.8] + [5.0] * nn),
            )
            grid.append((float(np.sum(g.fun**2)), w))
        w0 = min(grid)[1]
    p0 = [ch.s0[1], ch.s0[2]] + [0.3 if fit_wall else schema.FITTED_STIFFENING_EXPONENT] * nn + ([w0] if fit_wall else [])
    lo = [1.0, 1.0] + [0.0] * nn + ([0.3] if fit_wall else [])
    hi = [8.8, 8.8] + [5.0] * nn + ([0.999] if fit_wall else [])
    sol = least_squares(res, p0, bounds=(lo, hi), x_scale="jac")
    s, n, wall = unpack(sol.x)
    return {"spreading": s, "n": n, "wall": float(wall), "rms": float(np.sqrt(np.mean(sol.fun**2))), "ref": ref, "chain": ch}


def report(p: dict) -> str:
    """The fitted parameters and the force and slope errors at the fit depths."""
    ch, ref = p["chain"], p["ref"]
    s, n, wall = p["spreading"], p["n"], p["wall"]
    lines = [
        f"reference: axisymmetric neo-Hookean flat punch, level {ref['level']}; small-strain (linear law) {ref['k0']:.1f} N/m",
        f"fit: LOAD_SPREADING dermis {s[1]:.3f}, fat {s[2]:.3f}; n = {np.round(n, 4)}; wall strain {wall:.4f}; "
        f"rms {p['rms']:.4f}",
        f"small-strain stiffness {ch.k0(s):.1f} N/m ({100 * (ch.k0(s) / ref['k0'] - 1):+.1f} %)",
    ]
    f = ch.forces(s, n, wall, FORCE_DEPTHS_M)
    for d, fm, fr in zip(FORCE_DEPTHS_M, f, ref["force"]):
        lines.append(f"  F at {d * 1e3:.1f} mm: {fm:.4f} N vs {fr:.4f} N ({100 * (fm / fr - 1):+.1f} %)")
    e = ch.strains(s, n, wall, FORCE_DEPTHS_M[-1])
    lines.append(f"  layer strains at {FORCE_DEPTHS_M[-1] * 1e3:g} mm: " + ", ".join(f"{x:.3f}" for x in e))
    k = ch.slopes(s, n, wall, SLOPE_DEPTHS_M)
    for d, km, kr in zip(SLOPE_DEPTHS_M, k, ref["slope"]):
        lines.append(f"  dF/dd at {d * 1e3:.1f} mm: {km:.1f} N/m vs {kr:.1f} N/m ({100 * (km / kr - 1):+.1f} %)")
    return "\n".join(lines)


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--wall", action="store_true", help="fit the wall strain too")
    ap.add_argument("--per-layer-n", action="store_true", help="fit one exponent per layer (dermis, fat)")
    ap.add_argument("--no-strain-cap", action="store_true", help=f"drop the MAX_STRAIN = {MAX_STRAIN} penalty")
    ap.add_argument("--level", type=int, default=AXI_REFERENCE_LEVEL, help="reference mesh level")
    a = ap.parse_args(argv)
    print(report(fit(a.wall, a.level, a.per_layer_n, not a.no_strain_cap)))
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
