"""Replay report: force-time plot shaded by the layer the tool depth reaches (at rest), and the deformation at peak force."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np

from .offline import ReplayResult


def write_report(res: ReplayResult, out_dir: Path, title: str = "") -> dict:
    """Write ``out_dir/report.png`` and ``out_dir/summary.json``; return the summary.

    matplotlib (and :mod:`skin_sim_node.bags.plots`) is imported here, not at module level, so that
    :mod:`skin_sim_node.bags.replay` imports without it.
    """
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    from .plots import LAYER_COLOURS, cross_section_legend, draw_cross_section, draw_surface

    out_dir = Path(out_dir)
    out_dir.mkdir(parents=True, exist_ok=True)
    summary = res.summary()
    (out_dir / "summary.json").write_text(json.dumps(summary, indent=2) + "\n")
    fig = plt.figure(figsize=(11, 7.5))
    gs = fig.add_gridspec(2, 2, height_ratios=[1, 1.1], width_ratios=[1, 1.5])
    ax = fig.add_subplot(gs[0, :])
    if res.stamps_ns.size:
        t = (res.stamps_ns - res.stamps_ns[0]) * 1e-9
        ax.plot(t, res.force_n, "k", lw=1.0, label="force (N)")
        top = max(res.force_n.max() * 1.1, 1e-3)
        reached = depth_layer(res)
        for li, name in enumerate(res.layer_names):
            where = reached == li
            if where.any():  # a legend entry only for a layer that appears
                ax.fill_between(
                    t,
                    0,
                    top,
                    where=where,
                    color=LAYER_COLOURS[li % 3],
                    alpha=0.6,
                    lw=0,
                    step="mid",
                    label=f"tool depth in the {name}'s rest depths ({_shaded_ms(t, where):.0f} ms in all)",
                )
        ax.axvline(t[res.peak_index], color="r", lw=0.8, ls="--", label=f"peak {res.peak_force_n:.3f} N")
        ax.set_ylim(0, top)
    ax.set_xlabel("stamp time (s)")
    ax.set_ylabel("force (N)")
    ax.legend(loc="upper right", fontsize=7)
    ax.set_title(title or "offline replay", fontsize=10)
    model = res.model_at_peak()
    x, y, z = res.tool_xyz_m[res.peak_index] if res.stamps_ns.size else (0.0, 0.0, 1.0)
    t_peak = (res.stamps_ns[res.peak_index] - res.stamps_ns[0]) * 1e-9 if res.stamps_ns.size else 0.0
    draw_surface(fig.add_subplot(gs[1, 0]), model, f"surface at peak force (t = {t_peak:.3f} s)", tool_xy=(x, y))
    a1 = fig.add_subplot(gs[1, 1])
    half = max(4 * model.cfg.tool_radius_m, 8e-3)
    draw_cross_section(a1, model, x, y, z, f"cross-section at y = {y * 1e3:.1f} mm, same tick (tool offset 0 ms)", half_m=half)
    cross_section_legend(a1)
    fig.tight_layout()
    fig.savefig(out_dir / "report.png", dpi=100)
    plt.close(fig)
    return summary


def _shaded_ms(t_s: np.ndarray, where: np.ndarray) -> float:
    """Time (ms) that ``fill_between(..., where=where, step="mid")`` shades: a thin band (the 75 um epidermis is
    crossed in a few ms) is told by its legend entry, even where it is narrower than a pixel."""
    if t_s.size < 2:
        return 0.0
    edges = np.concatenate([[t_s[0]], 0.5 * (t_s[1:] + t_s[:-1]), [t_s[-1]]])
    return 1e3 * float(np.sum(np.diff(edges)[where]))


def depth_layer(res: ReplayResult) -> np.ndarray:
    """Per answered pose: the layer whose rest depths (mean interface depths) hold the tool depth; -1 out of contact.

    In the layered form every layer acts from first contact (``n_affected`` is 3 at any touch), so shading by it
    would say "fat" from the first touch; this says how deep the press has gone.
    """
    bounds = [i.mean_depth_m for i in res.cfg.interfaces] if res.cfg is not None else []
    k = np.searchsorted(np.asarray(bounds), res.depth_m)
    return np.where(res.depth_m > 0, k, -1)


def format_summary(s: dict) -> str:
    """One human-readable paragraph from a :meth:`ReplayResult.summary` dict (force in N, positions in mm)."""
    rejected = ", ".join(f"{k} {v}" for k, v in s["rejected"].items()) or "none"
    return (
        f"poses {s['poses']}, twists {s['twists']}, answered {s['answered']}, rejected/events: {rejected}\n"
        f"peak force {s['peak_force_n']:.4f} N at tool {np.round(np.array(s['peak_tool_xyz_m'] or [0, 0, 0]) * 1e3, 3)} mm; "
        f"layers reached: {', '.join(s['layers_reached']) or 'none'}; {s['duration_s']:.3f} s; {s['grid_frames']} grid frames"
    )
