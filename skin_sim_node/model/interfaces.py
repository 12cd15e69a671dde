"""Egg-carton layer interfaces (paper section II.C, Figs 2-3), vectorised NumPy API.

Interface ``j`` lies at depth (positive down, metres, below the rest surface z = 0)::

    d_j(x, y) = D_j - A_j * cos(2 pi x / wx_j) * cos(2 pi y / wy_j)

with ``D_j`` the summed mean thickness of the layers above it. The interface is at its
shallowest (a "peak", ``D_j - A_j``) at x = y = 0 and at its deepest (a "valley",
``D_j + A_j``) at x = wx_j / 2, y = 0. The per-tick version is
:func:`skin_sim_node.model.paper.layer_bounds`.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from .config import TissueConfig


def interface_depths_m(cfg: TissueConfig, x, y) -> np.ndarray:
    """Depth (m, positive down) of every interface at ``(x, y)``; shape ``(n_interfaces, *x.shape)``."""
    x = np.asarray(x, dtype=float)
    y = np.asarray(y, dtype=float)
    return np.stack(
        [
            i.mean_depth_m - i.amplitude_m * np.cos(2 * np.pi * x / i.wavelength_x_m) * np.cos(2 * np.pi * y / i.wavelength_y_m)
            for i in cfg.interfaces
        ]
    )


@dataclass(frozen=True)
class LayerClassification:
    """Which layers a tool tip affects (Fig 3): the first ``n_affected`` layers."""

    n_affected: int  # 0 none, 1 epidermis, 2 + dermis, 3 + fat
    bottomed: bool  # the tip is below the tissue's bottom: depth is clamped there
    layer_tops_m: tuple[float, ...]  # depth of each layer's top at (x, y)
    bottom_m: float


def classify(cfg: TissueConfig, x: float, y: float, depth_m: float) -> LayerClassification:
    """Which layers a tool tip at ``(x, y)`` and ``depth_m`` below the rest surface affects.

    A layer is affected once the tip is strictly below its top. A tip below the
    tissue's bottom affects all layers and is flagged ``bottomed``: the model clamps
    its depth to the bottom rather than failing.
    """
    tops = (0.0, *interface_depths_m(cfg, x, y).ravel().tolist())
    bottom = cfg.total_thickness_m
    n = 0 if depth_m <= 0.0 else sum(1 for t in tops if depth_m > t)
    return LayerClassification(n, depth_m > bottom, tuple(tops), bottom)
