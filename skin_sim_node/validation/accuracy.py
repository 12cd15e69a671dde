"""``skin-sim chart validation --only accuracy``: the model against the converged large-deformation reference.

Issue 11, "How it is shown", Accuracy: force error (mean over the peak, valley and edge scenarios of the
relative RMS error over the force-depth curve, depths 0-3 mm) aim <= 5 %, and field error (RMS of the surface
displacement difference over the sampled patch at 3 mm, over the depth) aim <= 10 %, against the 3D egg-carton
compressible neo-Hookean reference (:func:`.references.nonlinear_3d`, the default preset's moduli) at the 1 kHz
setting. The reference always has the *default preset's* tissue (the physical skin); the model configs scored
against it are the default, the paper form and a calibrated config (``--config``).

Static answers: :func:`.methods.static_force_n` (the layered chain with its dampers relaxed).
"""

from __future__ import annotations

import argparse
import json
from dataclasses import dataclass
from pathlib import Path

import numpy as np
from tqdm import tqdm

from skin_sim_node.model import SkinModel, TissueConfig, preset
from skin_sim_node.model.config import load_tissue_config

from .methods import static_dt_s, static_force_n
from .metrics import field_error, force_depth_error
from .references import nonlinear_references
from .scenarios import BY_NAME

FORCE_AIM, FIELD_AIM = 0.05, 0.10  # issue 11: force <= 5 %, field <= 10 %
OUT = Path(__file__).resolve().parents[2] / "docs" / "validation"


@dataclass
class Scored:
    """One config's errors against the reference, per scenario and mean."""

    label: str
    force_err: dict[str, float]
    field_err: dict[str, float]
    forces_n: dict[str, np.ndarray]  # the model's, at the reference's depths

    @property
    def force_mean(self) -> float:
        return float(np.mean(list(self.force_err.values())))

    @property
    def field_mean(self) -> float:
        return float(np.mean(list(self.field_err.values())))


def model_field_m(model: SkinModel, ref) -> np.ndarray:
    """The model's downward surface displacement on the reference's sample grid (after a static press)."""
    X, Y = np.meshgrid(ref.sample_x_m, ref.sample_y_m)
    return np.array([model.surface_displacement_at(x, y) for x, y in zip(X.ravel(), Y.ravel())]).reshape(X.shape)


def score(cfg: TissueConfig, label: str, refs: dict) -> Scored:
    """Force and field errors of ``cfg`` on every reference scenario."""
    fe, ue, forces = {}, {}, {}
    model = SkinModel(cfg)
    for name, ref in refs.items():
        x, y = BY_NAME[name].contact_xy_m
        f = np.array([static_force_n(model, x, y, d) for d in ref.depths_m])
        forces[name] = f
        fe[name] = force_depth_error(f, ref.forces_n)
        model.reset()
        model.step((x, y, -ref.depths_m[-1]), (0.0, 0.0, 0.0), static_dt_s(cfg))
        ue[name] = field_error(model_field_m(model, ref), ref.field_down_m, ref.depths_m[-1])
    return Scored(label, fe, ue, forces)


def paper_form_default() -> TissueConfig:
    """The paper's form on the default tissue with the Sneddon springs it shipped with (before the layered form)."""
    from msgs_schema.tissue import _TOOL_RADIUS_M, PAPER_MODULI_PA, flat_punch_stiffness_n_per_m

    k = {f"layers.{n}.stiffness_n_per_m": flat_punch_stiffness_n_per_m(e, _TOOL_RADIUS_M) for n, e in PAPER_MODULI_PA.items()}
    return preset("default").replace(form="paper", **k)


def table(rows: list[Scored]) -> str:
    names = list(rows[0].force_err)
    head = "| config | " + " | ".join(f"force {n}" for n in names) + " | **force mean** | " + \
        " | ".join(f"field {n}" for n in names) + " | **field mean** |"  # fmt: skip
    lines = [head, "|---" * (2 * len(names) + 3) + "|"]
    for r in rows:
        f = " | ".join(f"{100 * r.force_err[n]:.1f} %" for n in names)
        u = " | ".join(f"{100 * r.field_err[n]:.1f} %" for n in names)
        lines.append(f"| {r.label} | {f} | **{100 * r.force_mean:.1f} %** | {u} | **{100 * r.field_mean:.1f} %** |")
    return "\n".join(lines)


def curves(rows: list[Scored], refs: dict) -> str:
    """Force at each reference depth: reference and every config (N)."""
    lines = []
    for name, ref in refs.items():
        lines += [f"{name}: depth (mm) | reference (N) | " + " | ".join(r.label for r in rows)]
        for i, d in enumerate(ref.depths_m):
            lines.append(f"  {d * 1e3:.1f} | {ref.forces_n[i]:.4f} | " + " | ".join(f"{r.forces_n[name][i]:.4f}" for r in rows))
    return "\n".join(lines)


def _verdict(err: float, aim: float) -> str:
    return "PASS" if err <= aim else "MISS"


def run(configs: dict[str, TissueConfig] | None = None, out: Path | None = OUT, progress: bool = True) -> list[Scored]:
    """Score every config, print the table (and aims), write ``accuracy.md`` and ``accuracy.json``."""
    print("accuracy against the 3D neo-Hookean reference (peak, valley, edge; cached solves)", flush=True)
    refs = nonlinear_references(progress)
    configs = configs or {"default (layered)": preset("default"), "paper form, Sneddon springs": paper_form_default()}
    rows = [score(c, label, refs) for label, c in tqdm(configs.items(), desc="scoring configs", disable=not progress)]
    text = table(rows)
    aims = f"aims: force <= {FORCE_AIM:.0%}, field <= {FIELD_AIM:.0%} (mean over {', '.join(refs)})"
    verdicts = [f"- {r.label}: force {100 * r.force_mean:.1f} % ({_verdict(r.force_mean, FORCE_AIM)}), "
                f"field {100 * r.field_mean:.1f} % ({_verdict(r.field_mean, FIELD_AIM)})" for r in rows]  # fmt: skip
    full = "\n".join([text, "", aims, *verdicts, "", curves(rows, refs)])
    print(full)
    if out is not None:
        head = "# Accuracy against the large-deformation reference\n\nWritten by `skin-sim chart validation --only accuracy`.\n\n"
        (out / "accuracy.md").write_text(head + "\n".join([text, "", aims, *verdicts]) + "\n")
        (out / "accuracy.json").write_text(json.dumps(
            [{"label": r.label, "force_err": r.force_err, "field_err": r.field_err, "force_mean": r.force_mean,
              "field_mean": r.field_mean} for r in rows], indent=1) + "\n")  # fmt: skip
    return rows


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(prog="skin-sim chart validation --only accuracy", description=__doc__.split("\n")[0])
    ap.add_argument("--config", action="append", default=[], help="also score this config YAML (tissue.* parameters)")
    a = ap.parse_args(argv)
    configs = {"default (layered)": preset("default"), "paper form, Sneddon springs": paper_form_default()}
    for p in a.config:
        configs[Path(p).name] = load_tissue_config(p)
    run(configs)
    return 0
