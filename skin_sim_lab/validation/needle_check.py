"""The needle against its data (issue 22): force against depth per gauge, puncture sites, speed, friction, energy.

``python -m skin_sim_lab.validation.needle_check [--figures DIR]`` runs the needle through the session (1 ms ticks,
the published force) and prints, with the data each figure meets (docs/data/needle/):

1. per gauge (18, 21, 25 G, vertical at the origin, 5 mm/s): the skin's peak (the dermis's rupture), the tip travel
   at it, the epidermis's event, and the fat's peak as a share of the skin's;
2. the skin peak at 1 and 10 mm/s (21 G);
3. the puncture sites: at a peak, a valley and a saddle of the dermis/fat egg carton, vertical and at 30 and 60
   degrees, the axis length where the track meets each interface, against a dense-sampling reference of the
   egg-carton geometry (2 um steps, then bisection of the sampled bracket), and the tip travel at each rupture;
4. the shaft friction against the inserted length, in and out (Dahl's hysteresis), and the work the tissue does on
   the needle over an insert-retract cycle, each force booked over the next move (the causal sum a device sees).

Exits 1 when a check fails; ``--figures`` writes needle_force_depth.png and needle_friction.png there. Deterministic:
the numbers are figures.
"""

from __future__ import annotations

import argparse
import math
import sys
from pathlib import Path

import numpy as np

from msgs_schema.parameters import SessionParams
from skin_sim_node.device.trajectories import needle_orientation
from skin_sim_node.model import preset
from skin_sim_node.model.interfaces import interface_depths_m
from skin_sim_node.model.needle import GAUGE_OUTER_DIAMETER_M, NeedleModel, NeedleParams
from skin_sim_node.session.haptic import HapticSession
from skin_sim_node.tools import make_tool

GAUGES = (18, 21, 25)
CADAVER_BAND_N = (2.75, 2.80)
"""J Endourol 2016 (doi 10.1089/end.2016.0342): average maximum skin puncture force, human cadaver, percutaneous
access needle (the model's calibration point, at an assumed 18 G)."""
LIVING_SKIN_BAND_N = (0.1, 3.0)
"""Davis et al. 2004 (doi 10.1016/j.jbiomech.2003.12.010): insertion force into living skin, 0.1-3 N."""
SUTURE_BAND_N = (0.48, 1.00)
"""Maloney et al.: mean skin puncture force of taper suture needles 5-0 to 3-0 (body diameters not given)."""
FAT_SHARE_MAX = 0.20
SPEED_BAND = (0.8, 1.2)
"""The issue's bound on peak(10 mm/s) / peak(1 mm/s); Schneider 1978 and Frick 2001 found no rate effect."""
SITE_TOLERANCE_M = 0.1e-3
DT_NS = 1_000_000


def _cfg(gauge: int, **extra):
    return preset("needle").replace(**{"needle.outer_diameter_m": GAUGE_OUTER_DIAMETER_M[gauge], **extra})


def insertion(
    gauge: int, speed_m_s: float, depth_m: float = 4.5e-3, elevation_deg: float = 90.0, entry=(0.0, 0.0), dry: bool = False
):
    """Insert from 0.5 mm above the surface to ``depth_m`` below it at constant ``speed_m_s`` along the axis, then
    withdraw at the same speed, through the session; returns tips (n, 3), published forces (n, 3) and the needle's
    per-tick parts (insertion, dimple, cutting, friction, ruptured)."""
    e = math.radians(elevation_deg)
    u = np.array([math.cos(e), 0.0, -math.sin(e)])
    q = needle_orientation(e)
    cfg = _cfg(gauge, **({"needle.lubricated": False} if dry else {}))
    s = HapticSession(make_tool(cfg), SessionParams(max_stamp_age_s=0.0))
    step = speed_m_s * DT_NS * 1e-9
    travel = np.arange(-0.5e-3 / math.sin(e), depth_m / math.sin(e), step)
    path = np.concatenate([travel, travel[::-1]])
    tips, forces, parts = [], [], []
    for k, a in enumerate(path):
        p = np.array([entry[0], entry[1], 0.0]) + a * u
        s.on_pose((k + 1) * DT_NS, "tissue", tuple(p), quat=q)
        r = s.tick((k + 1) * DT_NS, DT_NS)
        t = s.tool.last_needle
        tips.append(p)
        forces.append(r.force_n)
        parts.append((t.insertion_m, t.dimple_m, t.cutting_n, t.friction_n, t.ruptured))
    return np.array(tips), np.array(forces), np.array(parts)


def gauge_row(gauge: int, speed_m_s: float = 5e-3, dry: bool = False) -> dict:
    """The skin peak (N), the tip travel at it (m), the epidermis's event and the fat's peak share for ``gauge``."""
    tips, f, parts = insertion(gauge, speed_m_s, depth_m=5.25e-3 if dry else 4.5e-3, dry=dry)
    n = len(tips) // 2
    mag = np.linalg.norm(f[:n], axis=1)
    rup = parts[:n, 4]
    i_skin = int(np.flatnonzero(rup >= 2)[0]) - 1
    i_epi = int(np.flatnonzero(rup >= 1)[0]) - 1
    travel = -tips[:n, 2]
    after = slice(i_skin + 1, n)
    fat_peak = float(mag[after].max()) if n > i_skin + 1 else 0.0
    return {
        "gauge": gauge,
        "diameter_m": GAUGE_OUTER_DIAMETER_M[gauge],
        "skin_peak_n": float(mag[i_skin]),
        "skin_travel_m": float(travel[i_skin]),
        "epidermis_n": float(mag[i_epi]),
        "epidermis_travel_m": float(travel[i_epi]),
        "fat_share": fat_peak / float(mag[i_skin]),
        "depth_m": travel,
        "force_n": mag,
    }


def crossing_reference(cfg, entry, u, layer: int) -> float:
    """Axis length (m) from ``entry`` where the axis meets the top of ``layer`` (>= 1): first sign change of
    ``depth(s) - D(x(s), y(s))`` on 2 um steps, then bisection; independent of the model's scan."""
    s = np.arange(0.0, 12e-3, 2e-6)
    q = np.asarray(entry)[None, :] + s[:, None] * np.asarray(u)[None, :]
    g = -q[:, 2] - interface_depths_m(cfg, q[:, 0], q[:, 1])[layer - 1]
    i = int(np.flatnonzero(g >= 0.0)[0])
    lo, hi = s[i - 1], s[i]
    for _ in range(60):
        mid = 0.5 * (lo + hi)
        qm = np.asarray(entry) + mid * np.asarray(u)
        gm = -qm[2] - float(interface_depths_m(cfg, qm[0], qm[1])[layer - 1])
        lo, hi = (mid, hi) if gm < 0.0 else (lo, mid)
    return 0.5 * (lo + hi)


def sites(gauge: int = 21) -> list[dict]:
    """Puncture sites: entries at a peak, a valley and a saddle of the dermis/fat interface, at 90, 60 and 30 deg."""
    cfg = _cfg(gauge)
    wl = cfg.interfaces[1].wavelength_x_m
    rows = []
    for site, x in (("peak", 0.0), ("valley", 0.5 * wl), ("saddle", 0.25 * wl)):
        for deg in (90.0, 60.0, 30.0):
            e = math.radians(deg)
            u = np.array([math.cos(e), 0.0, -math.sin(e)])
            nm = NeedleModel(cfg, NeedleParams(outer_diameter_m=cfg.needle_outer_diameter_m))
            entry = np.array([x, 0.0, 0.0])
            travel_at = {}
            tent = {}
            for a in np.arange(-0.5e-3, 12e-3, 1e-6):
                if nm.inserted and nm.ruptured < len(cfg.layers) and nm.ruptured not in tent:
                    tent[nm.ruptured] = _tent_m(nm, nm.ruptured)
                t = nm.step(entry + a * u, u)
                for k in t.punctured:
                    travel_at[k] = a
                if nm.ruptured == len(cfg.layers):
                    break
            for layer in (1, 2):
                ref = crossing_reference(cfg, entry, u, layer)
                # the skin's (dermis's) rupture is not a cascade: the tip is at the crossing plus the tent's dimple at
                # the threshold; the fat ruptures in the same tick (its own tent would end earlier)
                predicted = ref + tent.get(layer, math.nan)
                rows.append(
                    {
                        "site": site,
                        "elevation_deg": deg,
                        "interface": layer,
                        "reference_m": ref,
                        "model_m": float(nm.crossings[layer]),
                        "tip_travel_at_rupture_m": travel_at.get(layer, math.nan),
                        "predicted_travel_m": predicted,
                    }
                )
    return rows


def _tent_m(nm: NeedleModel, layer: int) -> float:
    """The dimple (m, along the axis) at which ``layer``'s dimple force reaches its threshold: bisection of
    :meth:`NeedleModel.dimple_force_n` (the tent the tip travels past the crossing before that layer ruptures)."""
    fp = nm.params.puncture_force_n(layer)
    lo, hi = 0.0, 1e-4
    while nm.dimple_force_n(layer, hi) < fp and hi < 0.1:
        hi *= 2.0
    for _ in range(60):
        mid = 0.5 * (lo + hi)
        lo, hi = (mid, hi) if nm.dimple_force_n(layer, mid) < fp else (lo, mid)
    return hi


def cycle_work_j(gauge: int = 21, speed_m_s: float = 5e-3) -> tuple[float, np.ndarray]:
    """Work (J) the tissue does on the needle over an insert-retract cycle, each force booked over the next move, and
    the per-tick (insertion, friction) pairs."""
    tips, f, parts = insertion(gauge, speed_m_s)
    work = float(np.sum(np.einsum("ij,ij->i", f[:-1], np.diff(tips, axis=0))))
    return work, parts[:, [0, 3]]


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(prog="skin_sim_lab.validation.needle_check", description=__doc__.splitlines()[0])
    ap.add_argument("--figures", type=Path, help="write needle_force_depth.png and needle_friction.png here")
    a = ap.parse_args(argv)
    fails: list[str] = []
    print("1. skin puncture per gauge (vertical, 5 mm/s; the published force through the session)")
    print("   gauge  d (mm)  skin peak (N)  at travel (mm)  epidermis (N @ mm)  fat peak / skin  band")
    rows = [gauge_row(g) for g in GAUGES]
    for r in rows:
        band = CADAVER_BAND_N if r["gauge"] == 18 else SUTURE_BAND_N
        print(
            f"   {r['gauge']:5d}  {r['diameter_m'] * 1e3:6.3f}  {r['skin_peak_n']:13.3f}  {r['skin_travel_m'] * 1e3:14.2f}  "
            f"{r['epidermis_n']:8.3f} @ {r['epidermis_travel_m'] * 1e3:5.2f}  {r['fat_share']:15.1%}  "
            f"{band[0]:.2f}-{band[1]:.2f} N{' (calibration)' if r['gauge'] == 18 else ' (suture needles, d unknown)'}"
        )
        if r["fat_share"] >= FAT_SHARE_MAX:
            fails.append(f"{r['gauge']} G: fat peak {r['fat_share']:.1%} of the skin's (>= 20 %)")
    if not CADAVER_BAND_N[0] <= rows[0]["skin_peak_n"] <= CADAVER_BAND_N[1]:
        fails.append(f"18 G skin peak {rows[0]['skin_peak_n']:.3f} N outside the cadaver band")
    for r in rows:
        if not LIVING_SKIN_BAND_N[0] <= r["skin_peak_n"] <= LIVING_SKIN_BAND_N[1]:
            fails.append(f"{r['gauge']} G skin peak {r['skin_peak_n']:.3f} N outside the living-skin band")
    print(
        f"   living skin (Davis 2004): {LIVING_SKIN_BAND_N[0]}-{LIVING_SKIN_BAND_N[1]} N, checked for every gauge; "
        "Maloney's suture-needle band is shown, not checked: their body diameters were not read (at 0.3-0.6 mm, "
        "unverified, the model would give 0.66-1.32 N, about 1.3 x theirs)"
    )
    for g in (18, 21):
        dry = gauge_row(g, dry=True)
        print(
            f"   dry {g} G: skin peak {dry['skin_peak_n']:.3f} N at {dry['skin_travel_m'] * 1e3:.2f} mm of tip travel "
            f"(the stack is {_cfg(g).total_thickness_m * 1e3:.3f} mm: a dry needle tents it nearly to its bottom)"
        )
        if not dry["skin_travel_m"] < _cfg(g).total_thickness_m:
            fails.append(f"dry {g} G does not puncture the skin inside the stack")
    per_d = [r["skin_peak_n"] / r["diameter_m"] for r in rows]
    print(f"   peak / diameter: {', '.join(f'{v / 1e3:.3f}' for v in per_d)} kN/m (linear in d: Maloney, Roemgens trend)")
    if max(per_d) > 1.01 * min(per_d):
        fails.append("skin peak not linear in the diameter")
    p1, p10 = gauge_row(21, 1e-3)["skin_peak_n"], gauge_row(21, 10e-3)["skin_peak_n"]
    ratio = p10 / p1
    print(f"\n2. speed, 21 G: skin peak {p1:.3f} N at 1 mm/s, {p10:.3f} N at 10 mm/s: ratio {ratio:.3f} (band 0.8-1.2)")
    if not SPEED_BAND[0] <= ratio <= SPEED_BAND[1]:
        fails.append(f"speed ratio {ratio:.3f} outside {SPEED_BAND}")
    print(
        "\n3. puncture sites, 21 G, entries at a peak, a valley and a saddle of the dermis/fat egg carton: where the track"
        "\n   meets each interface (the layer's rupture site in the tissue), the kernel's against a dense sampling of the"
        "\n   egg carton (aim 0.1 mm), and the tip's travel when the layer below ruptures: past the crossing by the"
        "\n   tent, so the issue's 'puncture depth = crossing within 0.1 mm' holds for the site in the tissue, NOT for"
        "\n   the tip; the skin's rupture lands at the crossing plus the tent's dimple at the threshold (bisection of"
        "\n   the dimple law) within 5 um"
    )
    print("   site    angle  interface        crossing ref (mm)  model (mm)  |diff| (um)  tip at rupture (mm)  predicted (mm)")
    worst = worst_tip = 0.0
    for r in sites():
        d = abs(r["model_m"] - r["reference_m"])
        worst = max(worst, d)
        name = ("epidermis/dermis", "dermis/fat")[r["interface"] - 1]
        cascade = "" if r["interface"] == 1 else " (cascade with the dermis)"
        if r["interface"] == 1:
            worst_tip = max(worst_tip, abs(r["tip_travel_at_rupture_m"] - r["predicted_travel_m"]))
        print(
            f"   {r['site']:7s} {r['elevation_deg']:5.0f}  {name:16s} {r['reference_m'] * 1e3:17.4f}  "
            f"{r['model_m'] * 1e3:10.4f}  {d * 1e6:11.2f}  {r['tip_travel_at_rupture_m'] * 1e3:19.3f}  "
            f"{r['predicted_travel_m'] * 1e3:14.3f}{cascade}"
        )
    if worst > SITE_TOLERANCE_M:
        fails.append(f"puncture site off by {worst * 1e3:.3f} mm")
    if not worst_tip <= 5e-6:
        fails.append(f"the skin's rupture {worst_tip * 1e6:.1f} um off the crossing plus the tent")
    work, fric = cycle_work_j()
    n = len(fric) // 2
    f_in, f_out = fric[:n, 1], fric[n:, 1]
    print(
        f"\n4. friction, 21 G: {f_in.max():.3f} N inserting at full depth, {f_out.min():.3f} N withdrawing (sign: against"
        f" the motion); work by the tissue over the insert-retract cycle {work * 1e6:+.1f} uJ (aim <= 0)"
    )
    if not (f_in.max() > 0 > f_out.min()):
        fails.append("friction does not reverse on retraction")
    if work > 0.0:
        fails.append(f"the cycle gives the hand {work * 1e6:.1f} uJ")
    if a.figures:
        _figures(a.figures, rows, fric)
    for f in fails:
        print(f"FAIL {f}")
    print(f"needle_check FAIL: {len(fails)} of 9 checks failed" if fails else "needle_check PASS: 9 checks")
    return 1 if fails else 0


def _figures(out: Path, rows: list[dict], fric: np.ndarray) -> None:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    out.mkdir(parents=True, exist_ok=True)
    fig, ax = plt.subplots(figsize=(7, 4.2))
    for r in rows:
        n = len(r["depth_m"])
        ax.plot(r["depth_m"][:n] * 1e3, r["force_n"][:n], label=f"{r['gauge']} G ({r['diameter_m'] * 1e3:.3f} mm)")
    ax.axhspan(*CADAVER_BAND_N, color="C0", alpha=0.25, label="cadaver skin peak, J Endourol 2016 (18 G assumed)")
    ax.axhspan(*SUTURE_BAND_N, color="grey", alpha=0.2, label="suture needles 5-0 to 3-0, Maloney")
    ax.set_xlabel("tip depth below the rest surface (mm), inserting")
    ax.set_ylabel("published force magnitude (N)")
    ax.set_title("Needle into the default skin, vertical, 5 mm/s")
    ax.legend(fontsize=7)
    fig.tight_layout()
    fig.savefig(out / "needle_force_depth.png", dpi=120)
    plt.close(fig)
    fig, ax = plt.subplots(figsize=(6, 4))
    n = len(fric) // 2
    ax.plot(fric[:n, 0] * 1e3, fric[:n, 1], label="inserting")
    ax.plot(fric[n:, 0] * 1e3, fric[n:, 1], label="withdrawing")
    ax.set_xlabel("insertion along the track (mm)")
    ax.set_ylabel("shaft friction, + resists insertion (N)")
    ax.set_title("21 G shaft friction (Dahl): hysteresis on retraction")
    ax.legend()
    fig.tight_layout()
    fig.savefig(out / "needle_friction.png", dpi=120)
    plt.close(fig)
    print(f"figures: {out / 'needle_force_depth.png'}, {out / 'needle_friction.png'}")


if __name__ == "__main__":
    sys.exit(main())
