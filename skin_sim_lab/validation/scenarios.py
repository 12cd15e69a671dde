"""The fixed indentation suite (issue 5, part 2), in the tissue frame of ``docs/model.md``.

Contacts: x = y = 0 is where both egg-carton interfaces have a peak (shallowest point);
x = 2.5 mm, y = 0 is a valley of both (half the 5 mm dermis/fat wavelength and 12.5 of
the 0.2 mm rete-ridge wavelengths). The near-edge contact sits on a peak 5 mm from the
+x sheet edge (the 120 mm sheet's edge is at x = 60 mm), so the 2.5 mm tool is 2.5 mm off it.
Depths: the epidermis/dermis peak is at 35 um and the dermis/fat peak at 0.775 mm, so
30 um reaches one layer, 0.7 mm two and 3 mm all three.
"""

from __future__ import annotations

from dataclasses import dataclass, replace

import numpy as np

from .fem import FemSetup

N_DEPTHS = 24  # samples on each force-depth curve
RAMP_SAMPLES = 100  # the paper's 100 observations (Table II)
PAPER_RAMP_FORCE_N = 5.0  # the paper's FEA load


@dataclass(frozen=True)
class Scenario:
    """One displacement-controlled indentation: a contact point and a depth ramp (m)."""

    name: str
    contact_xy_m: tuple[float, float]
    max_depth_m: float
    description: str
    edge_distance_m: float | None = None  # FEM: distance to a free sheet edge along +x

    @property
    def depths_m(self) -> np.ndarray:
        """The :data:`N_DEPTHS` indentation depths, evenly spaced from ``max_depth_m / N_DEPTHS`` to ``max_depth_m`` (m)."""
        return np.linspace(self.max_depth_m / N_DEPTHS, self.max_depth_m, N_DEPTHS)

    def fem_setup(self, mesh: FemSetup) -> FemSetup:
        """The FEM problem of this scenario at the density of ``mesh`` (depth-independent: linear)."""
        return replace(mesh, contact_xy_m=self.contact_xy_m, edge_distance_m=self.edge_distance_m)


SUITE: tuple[Scenario, ...] = (
    Scenario("peak-1layer", (0.0, 0.0), 30e-6, "on interface peaks, epidermis only (30 um)"),
    Scenario("peak-2layer", (0.0, 0.0), 0.7e-3, "on interface peaks, epidermis + dermis (0.7 mm)"),
    Scenario("peak-3layer", (0.0, 0.0), 3.0e-3, "on interface peaks, all three layers (3 mm)"),
    Scenario("valley-3layer", (2.5e-3, 0.0), 3.0e-3, "on interface valleys, all three layers (3 mm)"),
    Scenario("edge-3layer", (0.055, 0.0), 3.0e-3, "5 mm from a free sheet edge, all three layers (3 mm)", 0.005),
)
BY_NAME = {s.name: s for s in SUITE}


def paper_ramp_n(peak_force_n: float = PAPER_RAMP_FORCE_N, samples: int = RAMP_SAMPLES) -> np.ndarray:
    """The paper's load: force rising linearly to ``peak_force_n`` then released to 0, ``samples`` points.

    The paper gives neither the ramp's shape nor its timing; a symmetric triangle sampled
    quasi-statically is the simplest reading of "rises over time until 5 N, then removed".
    """
    half = samples // 2
    up = np.linspace(peak_force_n / half, peak_force_n, half)
    down = np.linspace(peak_force_n, 0.0, samples - half + 1)[1:]
    return np.concatenate([up, down])
