"""Error metrics against the FEM reference (issue 5, part 2)."""

from __future__ import annotations

import numpy as np


def force_depth_error(force_n, reference_n) -> float:
    """Relative RMS error over a force-depth curve: ``rms(F - F_ref) / rms(F_ref)``."""
    f, r = np.asarray(force_n, float), np.asarray(reference_n, float)
    return float(np.sqrt(np.mean((f - r) ** 2)) / np.sqrt(np.mean(r**2)))


def field_error(field_m, reference_m, peak_depth_m: float) -> float:
    """RMS of the surface-displacement difference over the sampled patch, relative to the peak depth."""
    d = np.asarray(field_m, float) - np.asarray(reference_m, float)
    return float(np.sqrt(np.mean(d**2)) / peak_depth_m)


def field_max_error(field_m, reference_m, peak_depth_m: float) -> float:
    """Largest surface-displacement difference over the sampled patch, relative to the peak depth."""
    return float(np.max(np.abs(np.asarray(field_m, float) - np.asarray(reference_m, float))) / peak_depth_m)


def peak_error(peak_m, reference_peak_m) -> float:
    """Relative error of a peak displacement."""
    return float(abs(peak_m - reference_peak_m) / abs(reference_peak_m))
