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

from .methods import GridMethod, ModalMethod, skin_membrane, static_dt_s, static_force_n
from .metrics import field_error, field_max_error, force_depth_error, peak_error
from .references import nonlinear_references
from .scenarios import BY_NAME, paper_ramp_n
from .stats import table_ii, table_markdown

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
        """Mean relative force error over the scenarios."""
        return float(np.mean(list(self.force_err.values())))

    @property
    def field_mean(self) -> float:
        """Mean relative surface-field error over the scenarios."""
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
    """The paper's form on the default tissue with the Sneddon springs it shipped with (before the layered form) and the
    paper's bare membranes (no foundation)."""
    from msgs_schema.tissue import TOOL_RADIUS_M
    from skin_sim_node.model.calibration import PAPER_MODULI_PA, flat_punch_stiffness_n_per_m

    k = {f"layers.{n}.stiffness_n_per_m": flat_punch_stiffness_n_per_m(e, TOOL_RADIUS_M) for n, e in PAPER_MODULI_PA.items()}
    return preset("default").replace(form="paper", **k, **{"patch.foundation_length_m": 0.0})


def table(rows: list[Scored]) -> str:
    """The scored configs as a markdown table: force and field error per scenario and their means."""
    names = list(rows[0].force_err)
    head = (
        "| config | "
        + " | ".join(f"force {n}" for n in names)
        + " | **force mean** | "
        + " | ".join(f"field {n}" for n in names)
        + " | **field mean** |"
    )
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
    verdicts = [
        f"- {r.label}: force {100 * r.force_mean:.1f} % ({_verdict(r.force_mean, FORCE_AIM)}), "
        f"field {100 * r.field_mean:.1f} % ({_verdict(r.field_mean, FIELD_AIM)})"
        for r in rows
    ]
    full = "\n".join([text, "", aims, *verdicts, "", curves(rows, refs)])
    print(full)
    if out is not None:
        head = "# Accuracy against the large-deformation reference\n\nWritten by `skin-sim chart validation --only accuracy`.\n\n"
        (out / "accuracy.md").write_text(head + "\n".join([text, "", aims, *verdicts]) + "\n")
        (out / "accuracy.json").write_text(
            json.dumps(
                [
                    {
                        "label": r.label,
                        "force_err": r.force_err,
                        "field_err": r.field_err,
                        "force_mean": r.force_mean,
                        "field_mean": r.field_mean,
                    }
                    for r in rows
                ],
                indent=1,
            )
            + "\n"
        )
    return rows


@dataclass(frozen=True)
class _RefScenario:
    """A reference solve seen as a scenario: its contact and *its* depths (the 3D march may stop short of 3 mm)."""

    name: str
    contact_xy_m: tuple[float, float]
    depths_m: np.ndarray

    @property
    def max_depth_m(self) -> float:
        """The deepest indentation of the scenario (m)."""
        return float(self.depths_m[-1])


SPEED_MODES = (1, 3, 10, 15, 20, 40)  # 15: the default's mode count (the 1 kHz setting)
SPEED_GRID = 120  # the default output grid
SPEED_NODES = (29, 59)  # membrane baselines over the patch: 2 mm and 1 mm


def speed_methods(cfg: TissueConfig | None = None, membrane_fit: dict | None = None) -> list:
    """Both forms at :data:`SPEED_MODES` (fixed counts) and the one-membrane baselines (mass-spring, explicit FD),
    as shipped and with ``T, k_A`` fitted to the nonlinear reference (``membrane_fit``)."""
    cfg = cfg or preset("default")
    paper = paper_form_default()
    ms = [ModalMethod(m, SPEED_GRID, cfg, f"layered (default) {m}x{m}") for m in SPEED_MODES]
    ms += [ModalMethod(m, SPEED_GRID, paper, f"paper form {m}x{m}") for m in SPEED_MODES]
    for kind in ("mass-spring", "explicit FD"):
        ms += [GridMethod(kind, n, skin_membrane(cfg), cfg, f"{kind} {n}x{n}") for n in SPEED_NODES]
        if membrane_fit:
            mem = skin_membrane(cfg, membrane_fit["tension_n_per_m"], membrane_fit["foundation_n_per_m3"])
            ms += [GridMethod(kind, n, mem, cfg, f"{kind} {n}x{n}, T and k_A fitted") for n in SPEED_NODES]
    return ms


def speed_accuracy(out: Path | None = OUT, progress: bool = True) -> list[dict]:
    """The speed-accuracy chart against the 3D neo-Hookean reference: time per update (``step`` + ``build_grid`` at
    1 kHz for the model; one 1 ms tick of sub-steps at 0.9 x the stability limit for the membranes) against the force
    and field errors (mean over the peak, valley and edge solves). Writes ``speed_accuracy_nonlinear.{csv,png}``."""
    from . import calibrate

    refs = nonlinear_references(progress)
    mem_fit = calibrate.fit_membrane(calibrate.nonlinear_datasets(progress), preset("default"))
    rows = []
    for m in tqdm(speed_methods(membrane_fit=mem_fit), desc="speed-accuracy (nonlinear reference)", disable=not progress):
        row = {"method": m.label, "s_per_update": m.seconds_per_update()}
        for name, ref in refs.items():
            sc = _RefScenario(name, BY_NAME[name].contact_xy_m, ref.depths_m)
            o = m.run(sc, ref)
            row[f"force_{name}"] = force_depth_error(o.forces_n, ref.forces_n)
            row[f"field_{name}"] = field_error(o.field_m, ref.field_down_m, sc.max_depth_m)
        row["force_err_mean"] = float(np.mean([row[f"force_{n}"] for n in refs]))
        row["field_err_mean"] = float(np.mean([row[f"field_{n}"] for n in refs]))
        rows.append(row)
    lines = ["| method | time per update (ms) | force error (mean) | field error (mean) |", "|---|---|---|---|"]
    lines += [
        f"| {r['method']} | {r['s_per_update'] * 1e3:.4g} | {100 * r['force_err_mean']:.1f} % | "
        f"{100 * r['field_err_mean']:.1f} % |"
        for r in rows
    ]
    text = "\n".join(lines)
    print(text)
    print("membrane baseline fitted to the nonlinear reference:", json.dumps(mem_fit))
    if out is not None:
        import csv

        import matplotlib

        matplotlib.use("Agg")
        import matplotlib.pyplot as plt

        with open(out / "speed_accuracy_nonlinear.csv", "w", newline="") as fh:
            w = csv.DictWriter(fh, fieldnames=list(rows[0]))
            w.writeheader()
            w.writerows(rows)
        (out / "speed_accuracy_nonlinear.md").write_text(
            "# Speed vs accuracy against the 3D neo-Hookean reference\n\nWritten by "
            "`skin-sim chart validation --only speed` (one run on a shared 2-core machine).\n\n" + text + "\n\n"
            f"Membrane baseline fitted to the nonlinear reference: `{json.dumps(mem_fit)}`\n"
        )
        fig, axes = plt.subplots(1, 2, figsize=(13, 5.2))
        families: dict[str, list] = {}
        for r in rows:
            fam = (
                r["method"].rsplit(" ", 1)[0]
                if r["method"][0] in "lp"
                else r["method"].split(" ")[0] + (", fitted" if "fitted" in r["method"] else "")
            )
            families.setdefault(fam, []).append(r)
        for ax, key, title in (
            (axes[0], "force_err_mean", "force-depth error (relative RMS)"),
            (axes[1], "field_err_mean", "surface-field error (RMS / depth)"),
        ):
            for fam, members in families.items():
                ax.loglog([r["s_per_update"] for r in members], [r[key] for r in members], "o-", lw=0.8, ms=5, label=fam)
                for r in members:
                    tag = r["method"].split(" ")[-1] if r["method"][0] in "lp" else ""
                    ax.annotate(tag, (r["s_per_update"], r[key]), fontsize=6, xytext=(3, 3), textcoords="offset points")
            ax.axvline(1e-3, color="r", ls="--", lw=1)
            ax.axhline(FORCE_AIM if key == "force_err_mean" else FIELD_AIM, color="g", ls=":", lw=1)
            ax.set_xlabel("compute time per update on this machine (s)")
            ax.set_ylabel(title + ", mean over peak, valley, edge")
            ax.grid(True, which="both", alpha=0.2)
        axes[1].legend(fontsize=7, loc="upper left", bbox_to_anchor=(1.01, 1.0), title="numbers: modes", title_fontsize=6)
        fig.suptitle(
            "Speed vs accuracy against the 3D compressible neo-Hookean reference (dashed: 1 ms; dotted: aim)", fontsize=10
        )
        fig.tight_layout()
        fig.savefig(out / "speed_accuracy_nonlinear.png", dpi=120)
        plt.close(fig)
    return rows


def table_ii_nonlinear(out: Path | None = OUT, progress: bool = True) -> dict:
    """Table II redone against the nonlinear reference: the paper's triangular force ramp (100 samples) at the peak
    contact, up to the largest force the 3D peak solve reached; the reference's depth per force by inverting its
    force-depth curve (monotone), the model's by inverting its static force; t-test on the maximum deformations."""
    ref = nonlinear_references(progress)["peak-3layer"]
    ramp = paper_ramp_n(float(ref.forces_n[-1]))
    ref_depth = np.interp(ramp, np.concatenate([[0.0], ref.forces_n]), np.concatenate([[0.0], ref.depths_m]))
    md = [
        "# Table II, redone against the 3D neo-Hookean reference",
        "",
        f"Ramp 0 -> {ramp.max():.3f} N -> 0 (100 samples; the deepest converged load step of the peak solve, "
        f"{ref.depths_m[-1] * 1e3:.2f} mm). Written by `skin-sim chart validation --only speed`.",
        "",
    ]
    results = {}
    for label, cfg in {"default (layered)": preset("default"), "paper form, Sneddon springs": paper_form_default()}.items():
        model = SkinModel(cfg)
        table = np.linspace(0.0, cfg.total_thickness_m, 3000)
        f = np.array([static_force_n(model, 0.0, 0.0, d) for d in table])
        idx = [np.nonzero(f >= t)[0] for t in ramp]
        d = np.array([table[i[0]] if i.size else table[int(np.argmax(f))] for i in idx])
        tab = table_ii(-ref_depth, -d)
        i_pk = int(np.argmax(ramp))
        model.reset()
        model.step((0.0, 0.0, -d[i_pk]), (0.0, 0.0, 0.0), static_dt_s(cfg))
        u_mod = model_field_m(model, ref)
        extra = {
            "samples_reached": int(sum(i.size > 0 for i in idx)),
            "model_max_force_n": float(f.max()),
            "peak_disp_error": peak_error(d[i_pk], ref_depth[i_pk]),
            "field_rms_error_rel_peak": field_error(u_mod, ref.field_down_m, ref.depths_m[-1]),
            "field_max_error_rel_peak": field_max_error(u_mod, ref.field_down_m, ref.depths_m[-1]),
        }
        results[label] = {"table": tab, **extra}
        md += [f"## FEM (neo-Hookean) vs model ({label})", "", table_markdown(tab, ("FEA", f"model, {label}")), ""]
        md += [f"- {k}: {v:.4g}" if isinstance(v, float) else f"- {k}: {v}" for k, v in extra.items()] + [""]
    text = "\n".join(md)
    print(text)
    if out is not None:
        (out / "table_ii_nonlinear.md").write_text(text + "\n")
    return results


def main(argv=None) -> int:
    """``skin-sim chart validation --only accuracy``: score the default, the paper form and ``--config`` files; the table."""
    ap = argparse.ArgumentParser(prog="skin-sim chart validation --only accuracy", description=__doc__.split("\n")[0])
    ap.add_argument("--config", action="append", default=[], help="also score this config YAML (tissue.* parameters)")
    a = ap.parse_args(argv)
    configs = {"default (layered)": preset("default"), "paper form, Sneddon springs": paper_form_default()}
    for p in a.config:
        configs[Path(p).name] = load_tissue_config(p)
    run(configs)
    return 0
