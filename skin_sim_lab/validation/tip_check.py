"""``python -m skin_sim_lab.validation.tip_check``: the model's force and stiffness against the neo-Hookean
references, flat punch and sphere (issue 20, items 2 and 3a).

For each tip it prints, at 0.05 / 0.1 / 0.2 / 0.5 / 1 / 2 / 3 mm, the model's quasi-static force and ``dF/dd``
(the chain with its dampers relaxed, :func:`.methods.static_force_n`; ``dF/dd`` by a central difference of it)
against the reference's, with the % error, and the small-strain stiffness. References (cached solves):

- flat punch: the axisymmetric solve at :data:`.references.AXI_REFERENCE_LEVEL`; ``dF/dd`` from the local quadratic
  through its three nearest load stops (0.1 mm apart); small strain: its linear-law solve;
- sphere: :mod:`.sphere` at :data:`.sphere.SPHERE_REFERENCE_LEVEL` (load stops at every check depth); small strain:
  the Hertz-like ``d^1.5`` exponent between 0.05 and 0.1 mm (the sphere has no constant small-strain stiffness).

The model is evaluated on the reference's geometry: flat layers (interface amplitudes 0), at the origin; the flat
punch also on the default egg-carton sheet at the origin (the fat lobule's peak, as the issue-20 figures were taken).
"""

from __future__ import annotations

import argparse
import math

import numpy as np

from skin_sim_node.model import SkinModel, TissueConfig, preset

from .fit_law import curve_slope
from .methods import static_force_n
from .references import AXI_REFERENCE_LEVEL, axisym
from .sphere import CHECK_DEPTHS_M, SPHERE_REFERENCE_LEVEL, reference, sphere_setup

FD_STEP_M = 1e-6  # central difference of the model's static force (its chain is exact to 1e-13)
SMALL_STRAIN_DEPTH_M = 2e-6  # the model's small-strain stiffness: its dF/dd at 2 um (1-3 um difference)


def flat_layers(cfg: TissueConfig) -> TissueConfig:
    """``cfg`` with flat interfaces (amplitudes 0): the references' geometry."""
    return cfg.replace(**{f"interfaces.{i.name}.amplitude_m": 0.0 for i in cfg.interfaces})


def model_curve(cfg: TissueConfig, depths_m=CHECK_DEPTHS_M) -> tuple[np.ndarray, np.ndarray]:
    """Quasi-static force (N) and ``dF/dd`` (N/m) of ``cfg`` at the origin."""
    m = SkinModel(cfg)
    f = np.array([static_force_n(m, 0.0, 0.0, d) for d in depths_m])
    k = np.array(
        [
            (static_force_n(m, 0.0, 0.0, d + FD_STEP_M) - static_force_n(m, 0.0, 0.0, d - FD_STEP_M)) / (2 * FD_STEP_M)
            for d in depths_m
        ]
    )
    return f, k


def rows(tip: str, cfg: TissueConfig | None = None, sheet: str = "flat layers") -> dict:
    """The table of one tip: model and reference force and slope at :data:`~.sphere.CHECK_DEPTHS_M`."""
    base = cfg or preset("default")
    c = base.replace(**{"tool.shape": tip})
    if sheet == "flat layers":
        c = flat_layers(c)
    f, k = model_curve(c)
    if tip == "flat":
        ref = axisym(None, AXI_REFERENCE_LEVEL, progress=False)
        fr = np.array([float(ref.force_n(d)) for d in CHECK_DEPTHS_M])
        kr = np.array([curve_slope(ref.depths_m, ref.forces_n, d) for d in CHECK_DEPTHS_M])
        lin = axisym(None, AXI_REFERENCE_LEVEL, law="linear", progress=False)
        small = (float(model_curve(c, (SMALL_STRAIN_DEPTH_M,))[1][0]), float(lin.force_n(1e-3) / 1e-3))
        label = (
            f"flat punch r = {c.tool_radius_m * 1e3:g} mm, {sheet}; reference: neo-Hookean axisym. level {AXI_REFERENCE_LEVEL}"
        )
    else:
        ref = reference(sphere_setup(None, SPHERE_REFERENCE_LEVEL), progress=False)
        fr = np.array([float(ref.force_n(d)) for d in CHECK_DEPTHS_M])
        kr = np.array([float(ref.stiffness_n_per_m(d)) for d in CHECK_DEPTHS_M])
        d0, d1 = CHECK_DEPTHS_M[0], CHECK_DEPTHS_M[1]
        small = (math.log(f[1] / f[0]) / math.log(d1 / d0), math.log(fr[1] / fr[0]) / math.log(d1 / d0))
        label = f"sphere R = {c.tool_radius_m * 1e3:g} mm, {sheet}; reference: neo-Hookean sphere, level {SPHERE_REFERENCE_LEVEL}"
    return {"tip": tip, "label": label, "f": f, "fr": fr, "k": k, "kr": kr, "small": small}


def table(r: dict) -> str:
    """Markdown table of :func:`rows`."""
    out = [
        f"{r['label']}",
        "",
        "| depth (mm) | F model (N) | F ref (N) | error | dF/dd model (N/m) | dF/dd ref (N/m) | error |",
        "|---|---|---|---|---|---|---|",
    ]
    for d, f, fr, k, kr in zip(CHECK_DEPTHS_M, r["f"], r["fr"], r["k"], r["kr"]):
        out.append(
            f"| {d * 1e3:g} | {f:.5f} | {fr:.5f} | {100 * (f / fr - 1):+.1f} % "
            f"| {k:.1f} | {kr:.1f} | {100 * (k / kr - 1):+.1f} % |"
        )
    m, ref = r["small"]
    if r["tip"] == "flat":
        out.append(
            f"\nsmall-strain stiffness (dF/dd at 2 um): model {m:.1f} N/m, reference (linear law) {ref:.1f} N/m "
            f"({100 * (m / ref - 1):+.1f} %)"
        )
    else:
        out.append(f"\nforce exponent between 0.05 and 0.1 mm: model {m:.3f}, reference {ref:.3f} (Hertz 1.5)")
    return "\n".join(out)


def fit_sphere_factor(cfg: TissueConfig | None = None) -> tuple[float, float]:
    """Least-squares (in ``log F``, depths :data:`~.sphere.CHECK_DEPTHS_M`) value of
    :data:`~skin_sim_node.model.layered_contact.SPHERE_LOAD_FACTOR` for the model's chain against the sphere reference, and
    the largest force error after it. ``s`` is proportional to the factor below its cap, so the fit is closed form."""
    from skin_sim_node.model.layered_contact import SPHERE_LOAD_FACTOR

    r = rows("sphere", cfg)
    lr = np.log(r["fr"] / r["f"])
    c = SPHERE_LOAD_FACTOR * math.exp(float(lr.mean()))
    return c, float(np.max(np.abs(np.exp(lr - lr.mean()) - 1)))


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--tip", choices=("flat", "sphere", "both"), default="both")
    ap.add_argument("--fit-sphere", action="store_true", help="print the fitted SPHERE_LOAD_FACTOR and stop")
    a = ap.parse_args(argv)
    if a.fit_sphere:
        c, worst = fit_sphere_factor()
        print(f"SPHERE_LOAD_FACTOR fit: {c:.4f} (largest force error after the fit {100 * worst:.1f} %)")
        return 0
    tips = ("flat", "sphere") if a.tip == "both" else (a.tip,)
    for tip in tips:
        print(table(rows(tip)), "\n", flush=True)
        if tip == "flat":
            print(table(rows(tip, sheet="default sheet, origin")), "\n", flush=True)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
