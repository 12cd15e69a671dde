"""``skin-sim calibrate``: fit the model parameters its form cannot take from first principles.

Fitted (log-parameters, ``scipy.optimize.least_squares``):

- ``layers.{epidermis,dermis,fat}.stiffness_n_per_m``: the Kelvin-Voigt springs ``k`` of
  eq 6. The paper gives none; neither default rule is right for a punch on layers: Sneddon's
  flat punch on a half-space (the paper form) ignores each layer's thickness and the bottom; the
  column ``k = E A / h`` (the layered form) ignores the load spreading sideways under the punch.
  Layered form: the epidermis spring is not fitted: all layers are in series from first contact and
  its compliance is 0.1 % of the chain's (392 700 vs 752 N/m for the fat), so force data cannot see
  it (a fit from the default start wanders along the dermis/epidermis trade-off); its modulus is the
  measured 1.5 MPa (Geerligs et al. 2011).
- ``layers.*.stiffening`` (layered form only; one exponent ``n`` shared by the layers): the
  compression law ``f = k h ((1 - c/h)^-n - 1) / n`` (docs/model.md section 6).
- ``patch.foundation_length_m`` (only when surface fields are given): the membranes' static
  shape does not depend on ``T`` (it cancels when the shape is normalised to the depth,
  ``docs/model.md`` section 3); with the patch at the paper's 60 mm, the foundation's decay
  length ``l`` is the one parameter that sets how far the static indentation spreads
  (:mod:`skin_sim_node.model.modal`).

Not fitted: thicknesses and interfaces (measured geometry), densities and tensions (they set
only the dynamics, which static data cannot see), dampers ``b`` (no rate data in a static FEM).

Data: the large-deformation reference (default; the 3D egg-carton neo-Hookean force-depth curves of
the peak, valley and edge scenarios to 3 mm plus the surface field at 3 mm, ``--reference nonlinear``),
the linear FEM (``--reference linear``: the suite's peak and valley scenarios), or a user's CSV with
columns ``x, y, depth, force`` (metres, newtons; force only; ``CSV_UNITS``). Output: a config YAML
(``tissue.*`` parameters) and the residuals.
"""

from __future__ import annotations

import argparse
import csv
import json
import sys
from dataclasses import dataclass
from pathlib import Path

import numpy as np
from scipy.interpolate import RegularGridInterpolator
from scipy.optimize import least_squares

from msgs_schema.tissue import LAYER_NAMES
from skin_sim_lab.solvers import static_indentation
from skin_sim_node.model import SkinModel, TissueConfig, preset
from skin_sim_node.model.config import dump_yaml

from .methods import skin_membrane, static_force_n
from .references import converged_fem, nonlinear_references
from .scenarios import BY_NAME

K_NAMES = tuple(f"layers.{n}.stiffness_n_per_m" for n in LAYER_NAMES)
N_NAMES = tuple(f"layers.{n}.stiffening" for n in LAYER_NAMES)
STIFFENING_NAME = "layers.*.stiffening"  # the one fitted exponent, reported under this name
N_BOUNDS = (0.0, 10.0)  # the schema's bounds of layers.*.stiffening
FOUNDATION_NAME = "patch.foundation_length_m"
FOUNDATION_BOUNDS_M = (1e-4, 0.06)  # 0.1 mm (finer than any grid) to the paper's patch side (a bare membrane)
FOUNDATION_START_M = 5e-3  # the start when the base has none (l = 0): about the stack's thickness
STIFFENING_RESTART = 1.0
"""Second start of the exponent (layered form): from the default's small n the fit can stall at the n = 0 bound with
the dermis/fat split swapped (seen on synthetic data with n = 1.2); the better of the two fits is kept."""


@dataclass
class IndentData:
    """Force-depth samples at one contact, optionally the surface field at the deepest one."""

    x_m: float
    y_m: float
    depths_m: np.ndarray
    forces_n: np.ndarray
    field_xy_m: np.ndarray | None = None  # (n, 2) sample points
    field_down_m: np.ndarray | None = None  # (n,) downward surface displacement at depths_m[-1]


def model_response(cfg: TissueConfig, data: IndentData) -> tuple[np.ndarray, np.ndarray | None]:
    """The model's static forces at ``data.depths_m`` and its surface field at the last depth."""
    model = SkinModel(cfg)
    forces = np.array([static_force_n(model, data.x_m, data.y_m, d) for d in data.depths_m])
    field = None
    if data.field_xy_m is not None:
        field = np.array([model.surface_displacement_at(x, y) for x, y in data.field_xy_m])
    return forces, field


def residuals(cfg: TissueConfig, datasets: list[IndentData]) -> np.ndarray:
    """Per-set force residuals / rms(force) and field residuals / depth, each set weighted equally."""
    out = []
    for d in datasets:
        f, u = model_response(cfg, d)
        scale = np.sqrt(np.mean(d.forces_n**2))
        out.append((f - d.forces_n) / scale / np.sqrt(f.size))
        if u is not None:
            out.append((u - d.field_down_m) / d.depths_m[-1] / np.sqrt(u.size))
    return np.concatenate(out)


def _fits_stiffening(base: TissueConfig) -> bool:
    return base.form == "layered"


def fitted_springs(base: TissueConfig) -> tuple[str, ...]:
    """The spring parameters fitted for ``base``'s form (layered: dermis and fat; paper: all three)."""
    return K_NAMES[1:] if base.form == "layered" else K_NAMES


def _apply(base: TissueConfig, p: np.ndarray, fit_field: bool) -> TissueConfig:
    """``p``: log k (:func:`fitted_springs`), the stiffening exponent (layered form), log foundation length (fields)."""
    ks = fitted_springs(base)
    changes = dict(zip(ks, np.exp(p[: len(ks)]).tolist()))
    i = len(ks)
    if _fits_stiffening(base):
        changes.update(dict.fromkeys(N_NAMES, float(p[i])))
        i += 1
    if fit_field:
        changes[FOUNDATION_NAME] = float(np.exp(p[i]))
    return base.replace(**changes)


@dataclass
class Fit:
    """A calibration result: the fitted config, the fitted parameters, RMS residual at the end and at the start, evaluations."""

    cfg: TissueConfig
    params: dict
    residual_rms: float
    residual_rms_start: float
    n_evals: int


def fit(datasets: list[IndentData], base: TissueConfig | None = None, fit_field: bool | None = None) -> Fit:
    """Least-squares fit of the layer springs, the stiffening exponent (layered form) and the foundation length (when
    fields are given)."""
    base = base or preset("default")
    if fit_field is None:
        fit_field = any(d.field_xy_m is not None for d in datasets)
    flat = base.as_flat()
    names = list(fitted_springs(base))
    p0 = [np.log(flat[n]) for n in names]
    lo, hi = [np.log(1e-3)] * len(names), [np.log(1e7)] * len(names)
    if _fits_stiffening(base):
        p0.append(float(np.mean([flat[n] for n in N_NAMES])))
        lo.append(N_BOUNDS[0])
        hi.append(N_BOUNDS[1])
        names.append(STIFFENING_NAME)
    if fit_field:
        p0.append(np.log(base.foundation_length_m or FOUNDATION_START_M))
        lo.append(np.log(FOUNDATION_BOUNDS_M[0]))
        hi.append(np.log(FOUNDATION_BOUNDS_M[1]))
        names.append(FOUNDATION_NAME)
    p0 = np.clip(np.array(p0), np.array(lo) + 1e-9, np.array(hi) - 1e-9)

    def fun(p):
        return residuals(_apply(base, p, fit_field), datasets)

    r0 = fun(p0)
    starts = [p0]
    if _fits_stiffening(base):  # the exponent's lower bound (Hencky, n = 0) traps a start near it: also start at n = 1
        alt = p0.copy()
        alt[len(fitted_springs(base))] = STIFFENING_RESTART
        starts.append(alt)
    sols = [
        least_squares(fun, p, bounds=(lo, hi), x_scale=1.0, diff_step=1e-4, xtol=1e-12, ftol=1e-12, gtol=1e-12) for p in starts
    ]
    sol = min(sols, key=lambda r: r.cost)
    cfg = _apply(base, sol.x, fit_field)
    params = {n: float(v if n == STIFFENING_NAME else np.exp(v)) for n, v in zip(names, sol.x)}
    rms = float(np.sqrt(np.mean(sol.fun**2) * sol.fun.size / len(datasets)))
    rms0 = float(np.sqrt(np.mean(r0**2) * r0.size / len(datasets)))
    return Fit(cfg, params, rms, rms0, int(sum(r.nfev for r in sols)))


CSV_COLUMNS = ("x", "y", "depth", "force")
CSV_UNITS = "x, y, depth in metres (m), force in newtons (N)"
# Plausibility bounds of a measured skin indentation (metres, newtons). A depth beyond the tissue's
# thickness cannot be an indentation of it (a file in millimetres gives depths of 0.1-5, x1000 too
# large); a force above 50 N is beyond any skin indentation rig in docs/validation.md and would
# crush the tissue; a contact off the sheet is outside the model.
MAX_PLAUSIBLE_FORCE_N = 50.0


class CalibrationInputError(ValueError):
    """Bad calibration input; its message is the one line the command prints."""


def read_csv(path: str | Path, cfg: TissueConfig | None = None) -> list[IndentData]:
    """A measured indentation CSV (columns x, y, depth, force; SI: m, m, m, N) grouped by contact point.

    Raises
    ------
    CalibrationInputError
        Missing or empty file, a missing column, a non-number, a non-finite value, or implausible
        magnitudes for ``cfg`` (default preset): depth <= 0 or beyond the tissue thickness (a file in
        millimetres), force < 0 or > 50 N, a contact off the sheet.
    """
    cfg = cfg or preset("default")
    path = Path(path)
    if not path.is_file():
        raise CalibrationInputError(f"{path}: no such file")
    with open(path, newline="") as fh:
        reader = csv.DictReader(fh)
        header = [h.strip() for h in (reader.fieldnames or [])]
        if not header:
            raise CalibrationInputError(f"{path}: empty file (expected a header {','.join(CSV_COLUMNS)}; {CSV_UNITS})")
        missing = [c for c in CSV_COLUMNS if c not in header]
        if missing:
            raise CalibrationInputError(
                f"{path}: missing column(s) {', '.join(missing)} (header has {', '.join(header)}; need {', '.join(CSV_COLUMNS)})"
            )
        reader.fieldnames = header
        rows = []
        for r in reader:
            vals = []
            for c in CSV_COLUMNS:
                raw = (r.get(c) or "").strip()
                try:
                    v = float(raw)
                except ValueError:
                    raise CalibrationInputError(f"{path} line {reader.line_num}: column '{c}' is not a number: {raw!r}") from None
                if not np.isfinite(v):
                    raise CalibrationInputError(f"{path} line {reader.line_num}: column '{c}' is not finite: {raw!r}")
                vals.append(v)
            rows.append(vals)
    if not rows:
        raise CalibrationInputError(f"{path}: no data rows after the header")
    a = np.array(rows)
    _check_magnitudes(path, a, cfg)
    groups: dict[tuple[float, float], list] = {}
    for x, y, d, f in a:
        groups.setdefault((float(x), float(y)), []).append((d, f))
    out = []
    for (x, y), pts in groups.items():
        pts.sort()
        out.append(IndentData(x, y, np.array([p[0] for p in pts]), np.array([p[1] for p in pts])))
    return out


def _check_magnitudes(path: Path, a: np.ndarray, cfg: TissueConfig) -> None:
    x, y, d, f = a.T
    hint = f"; units are {CSV_UNITS}"
    total = cfg.total_thickness_m
    if d.max() > total:
        mm = " (is the file in millimetres? /1000 it would fit)" if d.max() / 1e3 <= total else ""
        raise CalibrationInputError(f"{path}: depth up to {d.max():g} m exceeds the tissue thickness {total:g} m{mm}{hint}")
    if d.min() <= 0:
        raise CalibrationInputError(f"{path}: depth {d.min():g} m <= 0: depths are positive indentations below the surface{hint}")
    if f.min() < 0 or f.max() > MAX_PLAUSIBLE_FORCE_N:
        bad = f.min() if f.min() < 0 else f.max()
        raise CalibrationInputError(f"{path}: force {bad:g} N outside 0..{MAX_PLAUSIBLE_FORCE_N:g} N{hint}")
    sx, sy = cfg.sheet_size_m
    if np.abs(x).max() > sx / 2 or np.abs(y).max() > sy / 2:
        raise CalibrationInputError(
            f"{path}: contact (x, y) up to ({np.abs(x).max():g}, {np.abs(y).max():g}) m is off the "
            f"{sx:g} x {sy:g} m sheet centred on the origin{hint}"
        )


def fem_datasets(progress: bool = True) -> list[IndentData]:
    """Calibration data from the converged FEM: the suite's peak and valley scenarios."""
    out = []
    for name in ("peak-1layer", "peak-2layer", "peak-3layer", "valley-3layer"):
        sc = BY_NAME[name]
        fem = converged_fem(sc, progress)
        X, Y = np.meshgrid(fem.sample_x_m[::2], fem.sample_y_m[::2])
        field = fem.surface_per_depth[::2, ::2] * sc.max_depth_m
        xy = np.stack([X.ravel(), Y.ravel()], 1)
        out.append(IndentData(*sc.contact_xy_m, sc.depths_m, fem.force_n(sc.depths_m), xy, field.ravel()))
    return out


def nonlinear_datasets(progress: bool = True, field_stride: int = 3) -> list[IndentData]:
    """Calibration data from the large-deformation reference: the 3D neo-Hookean peak, valley and edge solves of
    the default preset (force at every load step to 3 mm, surface field at 3 mm on every ``field_stride``-th sample)."""
    out = []
    for name, ref in nonlinear_references(progress).items():
        X, Y = np.meshgrid(ref.sample_x_m[::field_stride], ref.sample_y_m[::field_stride])
        xy = np.stack([X.ravel(), Y.ravel()], 1)
        field = ref.field_down_m[::field_stride, ::field_stride].ravel()
        out.append(IndentData(*BY_NAME[name].contact_xy_m, ref.depths_m, ref.forces_n, xy, field))
    return out


def main(argv=None) -> int:
    """``skin-sim calibrate``: fit to the FEM reference or a ``--csv`` of measured indentations; write ``--out`` YAML."""
    ap = argparse.ArgumentParser(
        prog="skin-sim calibrate",
        description=__doc__.split("\n")[0],
        epilog=f"CSV units: {CSV_UNITS}. One row per sample; rows with the same (x, y) form one force-depth curve. "
        "Depth is the indentation below the undeformed surface (positive), force the normal reaction (positive). "
        "Implausible magnitudes (a depth beyond the tissue thickness, e.g. a file in millimetres; a force above "
        f"{MAX_PLAUSIBLE_FORCE_N:g} N) are rejected with a one-line error.",
    )
    ap.add_argument(
        "--csv", help=f"measured indentation CSV with header x,y,depth,force ({CSV_UNITS}); default: the FEM reference"
    )
    ap.add_argument("--out", default="calibrated.yaml", help="config YAML to write (tissue.* parameters)")
    ap.add_argument("--modes", type=int, default=None, help="modes per axis of the model being fitted")
    ap.add_argument(
        "--reference",
        choices=("nonlinear", "linear"),
        default="nonlinear",
        help="without --csv: fit to the large-deformation reference (default) or the linear FEM",
    )
    ap.add_argument("--form", choices=("layered", "paper"), default="layered", help="tissue form being fitted")
    a = ap.parse_args(argv)
    base = preset("default").replace(form=a.form)
    if a.modes:
        base = base.replace(**{"modes.m": a.modes, "modes.n": a.modes, "lod.adaptive_modes": False})  # else ignored
    try:
        if a.csv:
            data = read_csv(a.csv, base)
        else:
            print(f"skin-sim calibrate: fitting the {a.form} form to the {a.reference} reference", flush=True)
            data = nonlinear_datasets() if a.reference == "nonlinear" else fem_datasets()
    except CalibrationInputError as exc:
        print(f"skin-sim calibrate: error: {exc}", file=sys.stderr)
        return 2
    res = fit(data, base)
    dump_yaml({f"tissue.{k}": v for k, v in res.cfg.as_flat().items()}, a.out)
    print(
        json.dumps(
            {
                "params": res.params,
                "residual_rms_start": res.residual_rms_start,
                "residual_rms": res.residual_rms,
                "evaluations": res.n_evals,
                "out": a.out,
            },
            indent=2,
        )
    )
    return 0


if __name__ == "__main__":
    raise SystemExit(main())


def fit_membrane(datasets: list[IndentData], cfg: TissueConfig, n: int = 59) -> dict:
    """The mass-spring / FD baseline's two static parameters: tension ``T`` and foundation ``k_A``.

    A single membrane has no layer structure, so these two are all it has: ``T`` sets how far
    the indentation spreads, ``k_A`` (the Kelvin-Voigt grid's ground springs) how stiff it is.
    Fitted to the same force and field data as :func:`fit` (contact offsets are ignored:
    the membrane is homogeneous).
    """

    def response(p):
        mem = skin_membrane(cfg, float(np.exp(p[0])), float(np.exp(p[1])))
        f1, u1 = static_indentation(mem, n, n, 1.0, (0.0, 0.0), cfg.tool_radius_m)
        step = mem.size_x_m / (n + 1)
        xs = -0.5 * mem.size_x_m + step * np.arange(1, n + 1)
        return f1, xs, u1

    def fun(p):
        f1, xs, u1 = response(p)
        interp = RegularGridInterpolator((xs, xs), u1, bounds_error=False, fill_value=0.0)
        out = []
        for d in datasets:
            out.append((f1 * d.depths_m - d.forces_n) / np.sqrt(np.mean(d.forces_n**2)) / np.sqrt(d.depths_m.size))
            if d.field_xy_m is not None:
                rel = d.field_xy_m - np.array([d.x_m, d.y_m])
                u = interp(rel[:, ::-1]) * d.depths_m[-1]
                out.append((u - d.field_down_m) / d.depths_m[-1] / np.sqrt(u.size))
        return np.concatenate(out)

    p0 = np.log([sum(la.tension_n_per_m for la in cfg.layers), 1e4])
    sol = least_squares(fun, p0, diff_step=1e-4)
    return {
        "tension_n_per_m": float(np.exp(sol.x[0])),
        "foundation_n_per_m3": float(np.exp(sol.x[1])),
        "residual_rms": float(np.sqrt(np.mean(sol.fun**2) * sol.fun.size / len(datasets))),
    }
