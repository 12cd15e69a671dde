"""Figures of the deformation: surface height map plus a Fig 4 style cross-section."""

from __future__ import annotations

from pathlib import Path

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402

from ..model import SkinModel  # noqa: E402

LAYER_COLOURS = ("#f2c9a5", "#d9777a", "#f5e08e")  # epidermis, dermis, fat


def draw_cross_section(ax, model: SkinModel, x0: float, y0: float, tool_z: float | None, title: str) -> None:
    """Fill each layer between its top and the next along y = y0, centred on x0 (mm axes)."""
    half = 0.6 * model.cfg.patch_size_m[0]
    xs = np.linspace(x0 - half, x0 + half, 1200)
    heights = model.cross_section(xs, y0)
    bottom = np.full_like(xs, -model.cfg.total_thickness_m)
    tops = list(heights) + [bottom]
    for li, layer in enumerate(model.cfg.layers):
        ax.fill_between(xs * 1e3, tops[li + 1] * 1e3, tops[li] * 1e3, color=LAYER_COLOURS[li % 3], label=layer.name, lw=0)
        ax.plot(xs * 1e3, tops[li] * 1e3, color="k", lw=0.5)
    if tool_z is not None and tool_z < 0.0:
        r = model.cfg.tool_radius_m
        ax.fill_between([(x0 - r) * 1e3, (x0 + r) * 1e3], [tool_z * 1e3] * 2, [2.0] * 2, color="#777", alpha=0.8, label="tool")
    ax.set_xlabel("x (mm)")
    ax.set_ylabel("z (mm)")
    ax.set_ylim(-model.cfg.total_thickness_m * 1e3 * 1.05, 1.5)
    ax.set_title(title, fontsize=9)


def draw_surface(ax, model: SkinModel, title: str) -> None:
    g = model.build_grid()
    ext = [g.xs_m[0] * 1e3, g.xs_m[-1] * 1e3, g.ys_m[0] * 1e3, g.ys_m[-1] * 1e3]
    im = ax.imshow(g.heights_m[0] * 1e3, origin="lower", extent=ext, cmap="viridis")
    ax.set_xlabel("x (mm)")
    ax.set_ylabel("y (mm)")
    ax.set_title(title, fontsize=9)
    plt.colorbar(im, ax=ax, label="surface height (mm)")


def save_figure(fig, path: str | Path, title: str = "") -> Path:
    """Title, lay out, write ``path`` (folders created) and close ``fig``."""
    if title:
        fig.suptitle(title, fontsize=10)
    fig.tight_layout()
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    fig.savefig(path, dpi=110)
    plt.close(fig)
    return path


def layer_heights_figure(
    xs, ys, layer_heights, y_row_m: float, path: str | Path, title: str = "", bottom_m: float | None = None
) -> Path:
    """Surface map and cross-section from a published ``tissue/layer_heights`` image (rows y, cols x, 3).

    ``bottom_m``: depth of the tissue bottom (positive), drawn as the bottom of the last layer.
    """
    fig, (a0, a1) = plt.subplots(1, 2, figsize=(11, 4.2), gridspec_kw={"width_ratios": [1, 1.5]})
    ext = [xs[0] * 1e3, xs[-1] * 1e3, ys[0] * 1e3, ys[-1] * 1e3]
    im = a0.imshow(layer_heights[:, :, 0] * 1e3, origin="lower", extent=ext, cmap="viridis")
    plt.colorbar(im, ax=a0, label="surface height (mm)")
    a0.set_xlabel("x (mm)")
    a0.set_ylabel("y (mm)")
    a0.set_title("surface height (tissue/layer_heights)", fontsize=9)
    row = int(np.argmin(np.abs(ys - y_row_m)))
    tops = [layer_heights[row, :, i] for i in range(layer_heights.shape[2])]
    bottom = np.full_like(xs, -bottom_m if bottom_m is not None else min(t.min() for t in tops) - 4e-3)
    for i, (top, below) in enumerate(zip(tops, tops[1:] + [bottom])):
        a1.fill_between(xs * 1e3, below * 1e3, top * 1e3, color=LAYER_COLOURS[i % 3], lw=0)
        a1.plot(xs * 1e3, top * 1e3, "k", lw=0.5)
    a1.set_xlabel("x (mm)")
    a1.set_ylabel("z (mm)")
    a1.set_title(f"cross-section at y = {ys[row] * 1e3:.1f} mm (grid resolution)", fontsize=9)
    return save_figure(fig, path, title)
