"""Figures of the deformation: surface height map plus a Fig 4 style cross-section.

In the runtime, not the lab, because two user tools draw with it: the demo's picture (:mod:`skin_sim_node.demo`) and
the replay report (:mod:`.report`); the lab's figures (:mod:`skin_sim_lab.viz`) use it too. matplotlib (the ``lab``
extra) is imported at module level, so its users import this module inside the function that draws."""

from __future__ import annotations

from pathlib import Path

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt
import numpy as np

from ..model import SkinModel

LAYER_COLOURS = ("#f2c9a5", "#d9777a", "#f5e08e")  # epidermis, dermis, fat


def punch_face_gap_m(model: SkinModel, x0: float, y0: float, tool_z: float, n: int = 201) -> float:
    """Largest height of the drawn surface above a flat punch's face over its footprint's diameter along y = y0.

    The modal surface is smooth: it cannot form the corner of a flat punch, so under the punch's edge it lies
    above the face by this much (the force uses the tip depth, not this surface).
    """
    r = model.cfg.tool_radius_m
    xs = np.linspace(x0 - r, x0 + r, n)
    return float(np.max(model.cross_section(xs, y0)[0] - tool_z))


CLIP_NOTE_M = 1e-6
"""A cross-section whose interfaces were clipped by more than 1 um (a thousandth of the 1 mm axis ticks, invisible
below it) says so on the axes."""


def clipped_layer_tops(heights_m: np.ndarray, bottom_m: float) -> np.ndarray:
    """The surface and each interface as drawn: no interface above the deformed layer top above it, none below the
    stack's bottom.

    Each layer's displacement is its own smooth modal field, so under a deep press an interface can come out above
    the surface (a negative layer thickness, e.g. the dermis/fat boundary at 2.6 mm under a flat punch); a layer is
    never thinner than zero, so the picture clips it.

    Parameters
    ----------
    heights_m : ndarray, shape (L, n)
        The surface (row 0) and each layer's top below it, z up (m): :meth:`SkinModel.cross_section`.
    bottom_m : float
        The stack's bottom (m, z up: minus the total thickness).

    Returns
    -------
    ndarray, shape (L, n)
        Row 0 unchanged; every other row at most the row above and at least ``bottom_m``.
    """
    tops = np.minimum.accumulate(np.asarray(heights_m, dtype=float), axis=0)
    tops[1:] = np.maximum(tops[1:], bottom_m)
    return tops


def draw_tool(ax, shape: str, x0_m: float, tool_z_m: float, radius_m: float, top_mm: float = 2.0) -> None:
    """The tool in a cross-section (mm axes): a flat punch as a rectangle, a sphere as a disk above its tip."""
    from matplotlib.patches import Circle, Rectangle

    r, x0, z = radius_m * 1e3, x0_m * 1e3, tool_z_m * 1e3
    label = f"tool ({shape}, r = {r:.2f} mm), tip z = {z:.2f} mm"
    if shape == "sphere":
        ax.add_patch(Circle((x0, z + r), r, color="#777", alpha=0.85, zorder=5, label=label))
    else:
        ax.add_patch(Rectangle((x0 - r, z), 2 * r, max(top_mm - z, r), fc="#777", ec="k", alpha=0.6, zorder=5, label=label))


def draw_cross_section(
    ax, model: SkinModel, x0: float, y0: float, tool_z: float | None, title: str, half_m: float | None = None
) -> None:
    """Fill each layer between its top and the next along y = y0, centred on x0 (mm axes); draw the tool.

    A flat punch whose face the smooth modal surface cannot follow gets a note of the gap on the axes
    (:func:`punch_face_gap_m`), so the picture does not show a punch inside the tissue unexplained.
    ``half_m``: half-width of the section (default 0.6 patch widths).
    """
    half = half_m if half_m is not None else 0.6 * model.cfg.patch_size_m[0]
    xs = np.linspace(x0 - half, x0 + half, 1200)
    heights = clipped_layer_tops(model.cross_section(xs, y0), -model.cfg.total_thickness_m)
    clipped_m = float(np.max(model.cross_section(xs, y0) - heights))
    bottom = np.full_like(xs, -model.cfg.total_thickness_m)
    tops = list(heights) + [bottom]
    for li, layer in enumerate(model.cfg.layers):
        ax.fill_between(xs * 1e3, tops[li + 1] * 1e3, tops[li] * 1e3, color=LAYER_COLOURS[li % 3], label=layer.name, lw=0)
        ax.plot(xs * 1e3, tops[li] * 1e3, color="k", lw=0.5)
    shape = getattr(model.cfg, "tool_shape", "flat")
    if tool_z is not None and tool_z < 0.0:
        draw_tool(ax, shape, x0, tool_z, model.cfg.tool_radius_m, top_mm=2.2)
        gap = punch_face_gap_m(model, x0, y0, tool_z) if shape == "flat" else 0.0
        if gap > 0.02e-3:
            ax.text(
                0.01,
                0.98,
                f"under the punch's edge the modal surface lies up to {gap * 1e3:.2f} mm above its face\n"
                "(the smooth field cannot form the corner; the force uses the tip depth)",
                transform=ax.transAxes,
                fontsize=7,
                va="top",
                bbox={"fc": "w", "alpha": 0.9, "lw": 0},
                zorder=7,  # over the tool, which would otherwise hide part of the note
            )
    if clipped_m > CLIP_NOTE_M:
        ax.text(
            0.01,
            0.02,
            f"interfaces drawn clipped to the layer above and the bottom (the layers' smooth modal fields put one up to "
            f"{clipped_m * 1e3:.2f} mm past it here)",
            transform=ax.transAxes,
            fontsize=6,
            va="bottom",
            bbox={"fc": "w", "alpha": 0.8, "lw": 0},
            zorder=7,
        )
    ax.set_xlim((x0 - half) * 1e3, (x0 + half) * 1e3)
    ax.set_xlabel("x (mm)")
    ax.set_ylabel("z (mm)")
    ax.set_ylim(-model.cfg.total_thickness_m * 1e3 * 1.05, 2.2)
    ax.set_title(title, fontsize=9)


def cross_section_legend(ax) -> None:
    """The layers and the tool of :func:`draw_cross_section`, below the axes: inside, a deep press puts the tool's
    corner and the fat under any corner of the legend."""
    ax.legend(loc="upper center", bbox_to_anchor=(0.5, -0.14), ncol=2, fontsize=7, frameon=False)


def draw_surface(ax, model: SkinModel, title: str, tool_xy: tuple[float, float] | None = None) -> None:
    """Surface height map (mm) of ``model``'s display grid; ``tool_xy``: the tool's footprint drawn dashed."""
    from matplotlib.patches import Circle

    g = model.build_grid()
    ext = [g.xs_m[0] * 1e3, g.xs_m[-1] * 1e3, g.ys_m[0] * 1e3, g.ys_m[-1] * 1e3]
    im = ax.imshow(g.heights_m[0] * 1e3, origin="lower", extent=ext, cmap="viridis")
    if tool_xy is not None:
        r = model.cfg.tool_radius_m * 1e3
        ax.add_patch(Circle((tool_xy[0] * 1e3, tool_xy[1] * 1e3), r, fill=False, ec="w", lw=1.0, ls="--"))
        title += "; dashed: tool footprint"
        half = max(6 * r, 10.0)
        ax.set_xlim(tool_xy[0] * 1e3 - half, tool_xy[0] * 1e3 + half)
        ax.set_ylim(tool_xy[1] * 1e3 - half, tool_xy[1] * 1e3 + half)
    ax.set_xlabel("x (mm)")
    ax.set_ylabel("y (mm)")
    ax.set_title(title, fontsize=9)
    plt.colorbar(im, ax=ax, label="surface height (mm)")


def save_figure(fig, path: str | Path, title: str = "", rect=(0, 0, 1, 1)) -> Path:
    """Title, lay out within ``rect`` (figure fraction), write ``path`` (folders created) and close ``fig``."""
    if title:
        fig.suptitle(title, fontsize=10)
    fig.tight_layout(rect=rect)
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    fig.savefig(path, dpi=110)
    plt.close(fig)
    return path
