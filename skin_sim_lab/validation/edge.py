"""The sheet's edge (issue 20, item 3): the force of a drag across the edge, tick by tick.

``python -m skin_sim_lab.validation.edge`` presses a flat punch 2 mm deep 5 mm inside the sheet's +x edge, drags it
out at 10 mm/s in 10 um steps (1 ms ticks) and prints the force before the edge, the largest change per 10 um and
per 0.1 mm of travel (N and % of the force before the edge), and where the force reaches zero, for each preset named
(default: ``default`` and ``paper``). The layered form follows the tool's footprint on the sheet
(:func:`~skin_sim_node.model.modal_kernels.footprint`); the paper form tests contact at the tool's centre.
Deterministic (no timing): the numbers are figures.
"""

from __future__ import annotations

import sys
from dataclasses import dataclass

import numpy as np

from skin_sim_node.model import SkinModel, TissueConfig, preset

DEPTH_M = 2e-3
START_INSIDE_M = 5e-3
STEP_M = 10e-6
SPEED_M_S = 0.01


@dataclass(frozen=True)
class EdgeSweep:
    """Positions (m) and forces (N) of a drag across the sheet's +x edge."""

    x_m: np.ndarray
    force_n: np.ndarray

    @property
    def before_n(self) -> float:
        """The force 5 mm inside the edge (N)."""
        return float(self.force_n[0])

    def largest_drop_n(self, travel_m: float) -> tuple[float, float]:
        """The largest force decrease (N) over ``travel_m`` of travel, and the position (m) where it starts."""
        w = max(1, int(round(travel_m / STEP_M)))
        drops = self.force_n[:-w] - self.force_n[w:]
        i = int(np.argmax(drops))
        return float(drops[i]), float(self.x_m[i])

    @property
    def zero_from_m(self) -> float:
        """The first position (m) with zero force (nan if none)."""
        zero = np.flatnonzero(self.force_n == 0.0)
        return float(self.x_m[zero[0]]) if zero.size else float("nan")


def sweep(cfg: TissueConfig) -> EdgeSweep:
    """Press 2 mm deep 5 mm inside the +x edge (200 ticks), then drag out to 3 mm past the edge in 10 um steps."""
    m = SkinModel(cfg)
    hx = 0.5 * cfg.sheet_size_m[0]
    x0 = hx - START_INSIDE_M
    for i in range(200):
        m.step((x0, 0.0, -DEPTH_M * min(1.0, (i + 1) / 100)), (0.0, 0.0, -0.02), 1e-3)
    xs = x0 + STEP_M * np.arange(int(round((START_INSIDE_M + 3e-3) / STEP_M)) + 1)
    forces = np.array([m.step((float(x), 0.0, -DEPTH_M), (SPEED_M_S, 0.0, 0.0), 1e-3) for x in xs])
    return EdgeSweep(xs, forces)


def report(names=("default", "paper")) -> str:
    """The lines the module prints, one block per preset."""
    lines = ["Sheet edge: 2 mm flat-punch press 5 mm inside the +x edge, dragged out at 10 mm/s in 10 um steps"]
    for name in names:
        cfg = preset(name)
        s = sweep(cfg)
        hx = 0.5 * cfg.sheet_size_m[0]
        d10, x10 = s.largest_drop_n(STEP_M)
        d100, x100 = s.largest_drop_n(1e-4)
        f0 = s.before_n
        lines.append(
            f"preset {name} ({cfg.form} form): force before the edge {f0:.4f} N; largest drop per 10 um {d10:.4f} N "
            f"({100 * d10 / f0:.2f} %) at {1e3 * (x10 - hx):+.3f} mm from the edge; per 0.1 mm {d100:.4f} N "
            f"({100 * d100 / f0:.2f} %); zero from {1e3 * (s.zero_from_m - hx):+.3f} mm"
        )
    return "\n".join(lines)


def main(argv=None) -> int:
    """Print :func:`report` for the presets named on the command line (default: ``default paper``)."""
    names = tuple(argv if argv is not None else sys.argv[1:]) or ("default", "paper")
    print(report(names))
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
