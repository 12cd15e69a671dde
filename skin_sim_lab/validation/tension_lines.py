"""Tension lines (issue 20, item 4): the dent's aspect ratio and the drag along and across the lines.

``python -m skin_sim_lab.validation.tension_lines`` prints, for the ``default`` (forearm tension lines) and the
``isotropic`` presets: each layer's membrane coefficient along and across the lines, the dent of a 2 mm flat-punch
press on the deformation grid (its half-width at half depth along and across the lines, and the aspect ratio of its
second moments), the normal force, and the drag (tangential force) of a 10 mm/s stroke along and across the lines;
``--figure PATH`` also draws the dent's profiles along and across the lines (docs/figures/tension_lines_dent.png).
Deterministic (no timing): the numbers are figures.

What the model can and cannot produce (docs/model.md, "Tension lines"): the lines shape the dent (the membranes'
``T_x != T_y``) and its return (``lambda_mn``); the normal force of a press sees only the layers' indentation modulus,
the geometric mean of the along and across moduli (Delafargue and Ulm 2004, eq 22), which is the calibrated one, so
it does not change; the drag is Coulomb friction on that normal force along the contact normal, fixed from the
deformed surface's slope at first contact, so a stroke started from rest drags the same along and across the lines.
"""

from __future__ import annotations

import math
import sys
from dataclasses import dataclass

import numpy as np

from skin_sim_node.model import SkinModel, TissueConfig, preset
from skin_sim_node.model.modal import modal_basis

PRESS_DEPTH_M = 2e-3
"""Depth of the press whose dent is measured (m): mid-range of the validated 0.5-3 mm."""
GRID_CELLS = 480
"""Deformation grid cells per side for the dent (0.25 mm cells on the 120 mm sheet)."""
STROKE_SPEED_M_S = 0.01
"""Stroke speed (m/s): a slow palpation stroke; past the presliding distance (about 1.1 mm at 1 mm deep) it slides at
``mu F_n`` (the friction is a law of positions: the speed does not enter it)."""
STROKE_DEPTH_M = 1e-3
STROKE_LENGTH_M = 5e-3


@dataclass(frozen=True)
class Dent:
    """The dent of a press on the deformation grid (m), along and across the tension lines."""

    depth_m: float
    half_width_along_m: float
    half_width_across_m: float
    moment_aspect: float  # sqrt(second moment along / across) of the displacement over the grid

    @property
    def aspect(self) -> float:
        """Half-width at half depth along over across."""
        return self.half_width_along_m / self.half_width_across_m


def _half_width(profile: np.ndarray, coords: np.ndarray) -> float:
    """Half-width (m) at half the peak of a centred, single-peaked profile (linear interpolation, both sides)."""
    i = int(np.argmax(profile))
    half = 0.5 * profile[i]
    widths = []
    for step in (1, -1):
        j = i
        while 0 <= j + step < profile.size and profile[j + step] > half:
            j += step
        k = j + step
        if not 0 <= k < profile.size:
            widths.append(abs(coords[j] - coords[i]))
            continue
        t = (profile[j] - half) / (profile[j] - profile[k])
        widths.append(abs(coords[j] + t * (coords[k] - coords[j]) - coords[i]))
    return 0.5 * (widths[0] + widths[1])


def dent(cfg: TissueConfig, depth_m: float = PRESS_DEPTH_M) -> Dent:
    """Press a flat punch at the sheet's centre to ``depth_m``, hold, and measure the dent on a fine grid.

    The half-widths are read on the grid row and column through the tool when the lines lie along x or y (angle 0
    or +-90 degrees); the moment aspect ``sqrt(sum u s_along^2 / sum u s_across^2)`` needs no such alignment.
    """
    cfg = cfg.replace(**{"grid.nx": GRID_CELLS, "grid.ny": GRID_CELLS, "lod.patch_only": False})
    m = SkinModel(cfg)
    for i in range(200):  # 100 ms ramp, 100 ms hold, 1 ms ticks
        m.step((0.0, 0.0, -depth_m * min(1.0, (i + 1) / 100)), (0.0, 0.0, 0.0), 1e-3)
    g = m.build_grid()
    u = -g.heights_m[0]  # surface displacement (m, down); the rest surface is z = 0
    xs, ys = g.xs_m, g.ys_m
    iy, ix = np.unravel_index(np.argmax(u), u.shape)
    wx, wy = _half_width(u[iy], xs), _half_width(u[:, ix], ys)
    c, s = math.cos(cfg.anisotropy_angle_rad), math.sin(cfg.anisotropy_angle_rad)
    along, across = (wx, wy) if abs(c) >= abs(s) else (wy, wx)
    X, Y = np.meshgrid(xs, ys)
    w = np.clip(u, 0.0, None)
    s_along = c * X + s * Y
    s_across = -s * X + c * Y
    aspect = math.sqrt(float(np.sum(w * s_along**2)) / float(np.sum(w * s_across**2)))
    return Dent(float(u.max()), along, across, aspect)


def stroke_forces(cfg: TissueConfig, across: bool) -> tuple[float, float]:
    """Press 1 mm at the centre, then stroke 5 mm at 10 mm/s along (or across) the lines; returns the mean normal and
    tangential force (N) over the stroke's second half."""
    m = SkinModel(cfg)
    dt = 1e-3
    for i in range(100):
        m.step((0.0, 0.0, -STROKE_DEPTH_M * min(1.0, (i + 1) / 50)), (0.0, 0.0, 0.0), dt)
    theta = cfg.anisotropy_angle_rad + (0.5 * math.pi if across else 0.0)
    ex, ey = math.cos(theta), math.sin(theta)
    n_ticks = int(round(STROKE_LENGTH_M / (STROKE_SPEED_M_S * dt)))
    normal, tangential = [], []
    for k in range(1, n_ticks + 1):
        s = STROKE_SPEED_M_S * dt * k
        m.step((s * ex, s * ey, -STROKE_DEPTH_M), (STROKE_SPEED_M_S * ex, STROKE_SPEED_M_S * ey, 0.0), dt)
        f = m.force_vector_n
        n = m.contact_normal
        fn = float(f @ n)
        normal.append(fn)
        tangential.append(float(np.linalg.norm(f - fn * n)))
    half = n_ticks // 2
    return float(np.mean(normal[half:])), float(np.mean(tangential[half:]))


def profiles(cfg: TissueConfig, depth_m: float = PRESS_DEPTH_M, half_m: float = 8e-3, n: int = 161):
    """The dent of :func:`dent`'s press along and across the lines through the tool (pointwise, eq 2).

    Returns ``(s, along, across)``: the distance from the tool (m) and the surface displacement (m, down) there.
    """
    m = SkinModel(cfg)
    for i in range(200):
        m.step((0.0, 0.0, -depth_m * min(1.0, (i + 1) / 100)), (0.0, 0.0, 0.0), 1e-3)
    c, s_ = math.cos(cfg.anisotropy_angle_rad), math.sin(cfg.anisotropy_angle_rad)
    s = np.linspace(-half_m, half_m, n)
    along = np.array([m.surface_displacement_at(t * c, t * s_) for t in s])
    across = np.array([m.surface_displacement_at(-t * s_, t * c) for t in s])
    return s, along, across


def figure(path, names=("default", "isotropic")) -> None:
    """Write the dent's profiles along and across the lines for each preset to ``path`` (PNG)."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, ax = plt.subplots(figsize=(6.4, 3.8))
    for name, colour in zip(names, ("C0", "C1", "C2", "C3")):
        cfg = preset(name)
        s, along, across = profiles(cfg)
        label = f"{name} (ratio {cfg.anisotropy_ratio:g})"
        ax.plot(s * 1e3, -along * 1e3, color=colour, label=f"{label}: along the lines")
        ax.plot(s * 1e3, -across * 1e3, color=colour, ls="--", label=f"{label}: across")
    ax.set_xlabel("distance from the tool's centre (mm)")
    ax.set_ylabel("surface height (mm)")
    ax.set_title("Dent of a 2 mm flat-punch press (r = 2.5 mm): tension lines")
    ax.legend(fontsize=8)
    ax.grid(alpha=0.3)
    fig.tight_layout()
    fig.savefig(path, dpi=120)
    plt.close(fig)


def report(names=("default", "isotropic")) -> str:
    """The table the module prints: membrane coefficients, dent, normal force and drag per preset."""
    lines = [
        "Tension lines: dent of a 2 mm flat-punch press (0.25 mm grid) and drag of a 1 mm deep, 10 mm/s, 5 mm stroke",
    ]
    for name in names:
        cfg = preset(name)
        r = cfg.anisotropy_ratio
        lines.append(f"\npreset {name}: anisotropy.ratio = {r:g}, angle = {math.degrees(cfg.anisotropy_angle_rad):g} deg")
        lam = modal_basis(cfg).lam[:, 0]
        for layer, l11 in zip(cfg.layers, lam):
            t = layer.tension_n_per_m
            lines.append(
                f"  {layer.name:9s} T along {t * math.sqrt(r):7.3f} N/m, across {t / math.sqrt(r):7.3f} N/m "
                f"(geometric mean {t:.3f}); lambda_11 {l11:8.2f} rad/s"
            )
        total = sum(la.tension_n_per_m for la in cfg.layers)
        lines.append(
            f"  sum over layers: along {total * math.sqrt(r):.2f}, across {total / math.sqrt(r):.2f} N/m "
            "(in vivo forearm 6.2-11.4 N/m, Flynn et al. 2011)"
        )
        d = dent(cfg)
        lines.append(
            f"  dent: depth {d.depth_m * 1e3:.3f} mm, half-width at half depth along {d.half_width_along_m * 1e3:.3f} mm, "
            f"across {d.half_width_across_m * 1e3:.3f} mm, aspect {d.aspect:.3f}; second-moment aspect {d.moment_aspect:.3f}"
        )
        fn_a, ft_a = stroke_forces(cfg, across=False)
        fn_c, ft_c = stroke_forces(cfg, across=True)
        lines.append(
            f"  stroke along the lines: normal {fn_a:.4f} N, drag {ft_a:.4f} N (drag / normal {ft_a / fn_a:.4f}); "
            f"across: normal {fn_c:.4f} N, drag {ft_c:.4f} N ({ft_c / fn_c:.4f}); drag along / across {ft_a / ft_c:.6f}"
        )
    return "\n".join(lines)


def main(argv=None) -> int:
    """Print :func:`report` for the presets named on the command line (default: ``default isotropic``);
    ``--figure PATH`` also writes :func:`figure` there."""
    args = list(argv if argv is not None else sys.argv[1:])
    path = None
    if "--figure" in args:
        i = args.index("--figure")
        path = args[i + 1]
        del args[i : i + 2]
    names = tuple(args) or ("default", "isotropic")
    print(report(names))
    if path:
        figure(path, names)
        print("wrote", path)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
