"""The heave beside a flat contact: how one contact lowers, and raises, the skin under another (issue 32). No rclpy.

The layers' membranes on their foundation (eq 2-3) dent under a contact and decay away from it, but never rise. Skin
does rise: the tissue is nearly incompressible (Poisson's ratio 0.48, :data:`~.calibration.POISSON_RATIO`) and bonded
to a base, so the volume a punch presses down comes up around it. The project's 3D neo-Hookean reference of one flat
punch (``skin-sim two-punch``, docs/validation/two_punch.md) has the surface above rest from 5.3 mm out, lowest at
about 7.5 mm (9 % of the depth), and a second punch 6-10 mm away needs 6-7 % *more* force, where a coupling through the
membranes' own fields gives it 1-9 % less.

The thin-layer model that gives the heave, with no fitted constant:

- a membrane of tension ``T`` (the layers' tensions summed, eq 1) over a thin incompressible layer of thickness ``h``
  (the whole tissue) and shear modulus ``mu`` (the layers' Reuss mean at :data:`~.calibration.POISSON_RATIO`), bonded
  to a rigid base, its top free of shear: the layer's pressure drives a flux ``-(h^3 / (3 mu)) grad p`` (lubrication
  theory), whose divergence lowers the surface;
- with the membranes' own foundation (``patch.foundation_length_m``, ``l``) kept beside it, outside the load
  ``L^4 Lap^2 w - (L^4 / l^2) Lap w + w = 0``, ``L^4 = T h^3 / (3 mu)`` (:func:`volume_length_m`: 2.77 mm for the
  default tissue);
- a rigid flat punch of radius ``a``: ``w = depth`` on its disk, and the volume it displaces held outside it
  (:func:`combined_profile`).

Against the reference's single punch at 2 mm (w / depth, 4 / 6 / 8 / 10 mm out): +0.178 / -0.060 / -0.076 / -0.056
against +0.204 / -0.052 / -0.081 / -0.054. Beyond 12 mm it decays more slowly than the reference's (-0.005 against
-0.0004 at 20 mm): thin-layer theory wants lengths well above ``h``, and ``L`` is 0.53 ``h``.

How the coupling uses it (:class:`~skin_sim_node.tools.hands.SharedSkin`): a contact ``j`` whose own field is
``e_j`` deep at its centre lowers the surface under contact ``i`` by ``G(s) Psi_i'(e_i) Psi_j(e_j)`` (``e_j`` when the
two are in one state; :mod:`~skin_sim_node.tools.reciprocal`, the load maps that make it a potential's), ``s`` the
centres' distance and ``G`` one table for the pair, the mean of the two directions' :func:`coupling_table` (each
one's footprint profile averaged over the other's disk with the weight ``1 - r^2 / a^2``, a rigid punch's contact
pressure on a thin layer, parabolic), held with its slope eased where the footprints overlap
(``hands.overlap_hold_m``). The isotropic kernel: the flux is the bulk tissue's, and the reference it is checked
against is isotropic.
"""

from __future__ import annotations

import functools
from typing import TYPE_CHECKING

import numpy as np
from scipy import special

from .calibration import POISSON_RATIO, layer_moduli_pa

if TYPE_CHECKING:
    from .config import TissueConfig

PROFILE_STEP_M = 10e-6
"""Radial step of the tabulated profile (m): the profile is smooth outside the punch and continuous at its rim, so
linear interpolation at 10 um is accurate to the square of the step over the decay length (2 mm), below 1e-4 of the
depth."""

PROFILE_RANGE_M = 45e-3
"""Distances tabulated (m): at 45 mm the profile is 1.1e-5 of the depth (the slow root's decay length is 4.4 mm for
the default tissue), and it is taken as zero beyond."""

TABLE_STEP_M = 50e-6
"""Step of the disk-averaged coupling table over the centres' distance (m): 50 um, a fifth of the model's 0.25 mm
accuracy of position (the needle's track), and the kernel's slope (at most 0.5 per mm near the rim) moves by 1e-3 of
the depth across one step."""

MIN_LENGTH_M = 0.25e-3
"""The least ``L`` (m, :func:`volume_length_m`) for which the coupling uses the kernel: five :data:`TABLE_STEP_M`, so
the rise beside the punch (about ``2 L`` wide) is resolved by the tables. The ``paper`` form's membranes carry almost
no tension (1e-9 N/m: ``L`` = 26 um), so they carry no heave either: there the other tool's own field is read
(:func:`uses_kernel`)."""

DISK_RADIAL_NODES = 24
"""Gauss-Jacobi nodes across the receiving disk's radius (in ``t = r^2 / a^2``): against a 400 x 1600 reference the
average is within 2e-4 of the depth where the disks nearly touch (3 mm for two 2.5 mm disks, the profile's kink at the
source's rim inside the receiver) and within 1e-5 beyond."""

DISK_ANGLE_NODES = 48
"""Trapezoid nodes around the disk: periodic, so exponentially convergent for the smooth profile."""


def volume_parameters(cfg: TissueConfig, poisson: float = POISSON_RATIO) -> tuple[float, float, float]:
    """The thin layer's tension ``T`` (N/m), thickness ``h`` (m) and shear modulus ``mu`` (Pa) from ``cfg``.

    ``T``: the sum of the layers' membrane tensions (their membranes deflect together under a punch, so their
    tensions add). ``h``: the whole tissue, every layer, over the base. ``mu``: the thickness-weighted harmonic (Reuss,
    as the series chain of eq 6) mean of the layers' shear moduli ``E / (2 (1 + nu))``, ``E`` by
    :func:`~.calibration.layer_moduli_pa`, ``h / mu = sum_i h_i / mu_i``.
    """
    moduli = layer_moduli_pa(cfg, poisson)
    t = sum(la.tension_n_per_m for la in cfg.layers)
    h = sum(la.thickness_m for la in cfg.layers)
    mu = h / sum(la.thickness_m * 2 * (1 + poisson) / e for la, e in zip(cfg.layers, moduli))
    return t, h, mu


def volume_length_m(cfg: TissueConfig) -> float:
    """The length of the volume term, ``L = (T h^3 / (3 mu))^(1/4)`` (:func:`volume_parameters`).

    A membrane of tension ``T`` over a thin incompressible layer (thickness ``h``, shear modulus ``mu``, bonded to a
    rigid base, its top free of shear) loaded by ``p_load``: the layer's pressure ``p`` drives a lateral flux
    ``q = -(h^3 / (3 mu)) grad p`` (lubrication / thin-layer theory), whose divergence lowers the surface,
    ``w = -(h^3 / (3 mu)) Lap p``; the membrane's balance is ``p = p_load + T Lap w``. Outside the load

    ``L^4 Lap^2 w + w = 0``, ``L^4 = T h^3 / (3 mu)``,

    whose decaying axisymmetric solutions are the Kelvin functions ``ker(r / L)``, ``kei(r / L)``: they cross zero,
    so the surface rises beside the load (the heave), and the volume lowered under the load comes up around it.
    """
    t, h, mu = volume_parameters(cfg)
    return float((t * h**3 / (3 * mu)) ** 0.25)


def combined_profile(radius_m, length_m: float, foundation_length_m: float, punch_radius_m: float) -> np.ndarray:
    """Surface lowering over the depth of one rigid flat punch on the volume term *and* a Winkler term of length ``l``.

    The layer carries ``p = p_load + T Lap w - (T / l^2) w``; outside the load
    ``L^4 Lap^2 w - (L^4 / l^2) Lap w + w = 0``, so ``w = A K_0(lambda_1 r) + B K_0(lambda_2 r)``, ``lambda_i^2`` the
    roots of ``L^4 s^2 - (L^4 / l^2) s + 1 = 0`` (a complex-conjugate pair, and then ``A``, ``B`` too, when
    ``l > L / sqrt(2)``: the decay oscillates). Two conditions: ``w(a) = depth`` (the punch) and the volume the punch
    displaces held outside it, ``int_a^inf w 2 pi r dr = -pi a^2 depth`` (``int_a^inf K_0(lambda r) r dr =
    a K_1(lambda a) / lambda``): incompressibility blocks the ``k = 0`` mode, so the two decaying modes have opposite
    signs and their sum crosses zero, whatever ``l``. With ``l -> inf`` it is the volume term alone,
    ``A ker(r / L) + B kei(r / L)``.

    Parameters
    ----------
    radius_m : array_like
        Distances from the punch's axis (m).
    length_m : float
        The volume term's ``L`` (m, :func:`volume_length_m`).
    foundation_length_m : float
        The Winkler length ``l`` (m), the model's ``patch.foundation_length_m``.
    punch_radius_m : float
        The punch's radius ``a`` (m).

    Returns
    -------
    numpy.ndarray
        ``w / depth`` (+ lowered, - raised).
    """
    r = np.asarray(radius_m, float)
    a, ell, lf = punch_radius_m, length_m, foundation_length_m
    lam = np.sqrt(np.roots([ell**4, -(ell**4) / lf**2, 1.0]).astype(complex))  # principal roots: Re > 0, decaying
    mat = np.array(
        [
            [special.kv(0, lam[0] * a), special.kv(0, lam[1] * a)],
            [a * special.kv(1, lam[0] * a) / lam[0], a * special.kv(1, lam[1] * a) / lam[1]],
        ]
    )
    c = np.linalg.solve(mat, np.array([1.0, -(a**2) / 2], complex))
    ro = np.maximum(r, a)
    outside = (c[0] * special.kv(0, lam[0] * ro) + c[1] * special.kv(0, lam[1] * ro)).real
    return np.where(r <= a, 1.0, outside)


def disk_average(field, centre_m: tuple[float, float], radius_m: float, alpha: float, radial: int, angular: int) -> float:
    """Average of ``field(x, y)`` over a disk, weighted by ``(1 - s^2 / a^2)^alpha``.

    ``<f> = int_disk f W dA / int_disk W dA`` with ``W = (1 - s^2 / a^2)^alpha`` and ``s`` the distance from the disk's
    centre: in ``t = s^2 / a^2`` (``dA = a^2 / 2 dt dtheta``) the radial integral is Gauss-Jacobi with weight
    ``(1 - t)^alpha`` (``radial`` nodes), the angular one the trapezoid rule (``angular`` nodes).

    Parameters
    ----------
    field : callable
        Vectorised ``field(x_m, y_m)`` (arrays of one shape).
    centre_m : tuple of float
        The disk's centre (m).
    radius_m : float
        Its radius ``a`` (m).
    alpha : float
        Exponent of the weight, ``> -1``.
    radial, angular : int
        Nodes of the two rules.

    Returns
    -------
    float
        The weighted average.
    """
    x, w = special.roots_jacobi(radial, alpha, 0.0)  # weight (1 - x)^alpha on [-1, 1]; t = (1 + x) / 2
    s = radius_m * np.sqrt((1 + x) / 2)
    th = 2 * np.pi * np.arange(angular) / angular
    vals = field(centre_m[0] + s[:, None] * np.cos(th), centre_m[1] + s[:, None] * np.sin(th))
    return float((w @ np.mean(vals, axis=1)) / w.sum())


def uses_kernel(cfg: TissueConfig) -> bool:
    """Whether a flat tool of ``cfg`` couples through the kernel: ``L`` at least :data:`MIN_LENGTH_M`."""
    return volume_length_m(cfg) >= MIN_LENGTH_M


def coupling_table(cfg: TissueConfig, source_radius_m: float, receiver_radius_m: float) -> tuple[np.ndarray, np.ndarray]:
    """How far a flat contact lowers the surface under another, by the distance of their centres.

    ``G(s)``: the lowering under the receiver over the source's own depth, :func:`combined_profile` of the source
    (radius ``source_radius_m``) averaged over the receiver's disk (radius ``receiver_radius_m``) with the weight
    ``1 - r^2 / a^2`` (a rigid flat punch's pressure on a thin layer is parabolic: it is the layer's pressure under
    the punch, ``p = (a^2 - r^2) depth / (4 D)`` for the flux coefficient ``D``); a receiver of radius 0 (a needle, a
    sphere's point of contact) reads the profile at its centre.

    Parameters
    ----------
    cfg : TissueConfig
        The tissue (``L`` by :func:`volume_length_m`, ``l`` its foundation length).
    source_radius_m, receiver_radius_m : float
        The two contacts' radii (m).

    Returns
    -------
    distances_m, lowering : numpy.ndarray
        ``s`` every :data:`TABLE_STEP_M` from 0 to :data:`PROFILE_RANGE_M`, and ``G(s)`` (dimensionless; + lowered,
        - raised); zero beyond the last distance.
    """
    lf = cfg.foundation_length_m
    return _coupling_table(volume_length_m(cfg), lf if lf > 0 else NO_FOUNDATION_M, source_radius_m, receiver_radius_m)


NO_FOUNDATION_M = 1e3
"""The Winkler length (m) standing for no foundation (``patch.foundation_length_m`` 0): ``l -> inf``, the volume term
alone; at 1 km its ``1 / l^2`` is 1e-12 of the volume term's ``1 / L^2`` for any L below a metre."""


@functools.lru_cache(maxsize=32)
def _coupling_table(length_m: float, foundation_length_m: float, source_radius_m: float, receiver_radius_m: float):
    """:func:`coupling_table` of the thin layer's two lengths (read-only arrays, shared: every
    :class:`~skin_sim_node.tools.hands.SharedSkin` of one tissue and one pair of radii builds the same table, 0.1 s
    each, and a study builds dozens)."""
    r = np.arange(0.0, PROFILE_RANGE_M + PROFILE_STEP_M / 2, PROFILE_STEP_M)
    prof = combined_profile(r, length_m, foundation_length_m, source_radius_m)
    prof[-1] = 0.0

    def field(x, y):
        return np.interp(np.hypot(x, y), r, prof, right=0.0)

    s = np.arange(0.0, PROFILE_RANGE_M + TABLE_STEP_M / 2, TABLE_STEP_M)
    if receiver_radius_m <= 0:
        g = field(s, 0.0)
    else:
        g = np.array(
            [disk_average(field, (float(d), 0.0), receiver_radius_m, 1.0, DISK_RADIAL_NODES, DISK_ANGLE_NODES) for d in s]
        )
        g[-1] = 0.0
    s.setflags(write=False)
    g.setflags(write=False)
    return s, g
