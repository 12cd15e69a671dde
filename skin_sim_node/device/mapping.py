"""Device <-> tissue frame mapping and the bridge's conventions and defaults. Pure: no ROS.

The bridge node itself is :mod:`skin_sim_node.device.bridge`; what it does:

Device side, under the ``device_ns`` parameter (relative, default ``device``):

- ``convention:=crtk`` (jhu-saw sawSensablePhantom): reads ``measured_cp`` (PoseStamped) and
  ``measured_cv`` (TwistStamped), writes ``servo_cf`` (WrenchStamped).
- ``convention:=omni`` (omni_common family, e.g. AleBarte Geomagic_Touch_ROS2_Drivers): reads
  ``phantom/pose`` (PoseStamped), writes ``phantom/force_feedback`` (WrenchStamped). No twist:
  the node differentiates the poses. Remap the names to match a given driver.

Node side (under ``node_ns`` if given, else the process namespace): publishes ``tool/pose`` and ``tool/twist`` in
the tissue frame; renders the node's ``tool/contact_model`` every device tick (:mod:`skin_sim_node.device.render`).
"""

from __future__ import annotations

import argparse
import math
import re
from collections.abc import Sequence
from dataclasses import dataclass, field

from msgs_schema.spec import ConfigError

Vec3 = tuple[float, float, float]
Mat3 = tuple[Vec3, Vec3, Vec3]
Quat = tuple[float, float, float, float]

TOUCH_PEAK_FORCE_N = 3.3
"""Peak force of a Geomagic Touch (3D Systems spec sheet: max exertable force 3.3 N at nominal position)."""

TOUCH_MAX_STIFFNESS_N_PER_M = 1020.0
"""Largest stiffness rendered on a Touch (N/m): the spec sheet's lowest axis figure (3D Systems Touch:
stiffness X > 1.26 N/mm, Y > 2.31 N/mm, Z > 1.02 N/mm), so the cap holds in every direction."""

TOUCH_MAX_DAMPING_N_S_PER_M = 5.0
"""Largest damping rendered on a Touch (N s/m, spectral norm, so in every direction). The 3D Systems spec sheet
gives no damping figure; this is the largest damping jhu-saw sawSensablePhantom runs on the device: its position
servo's ``servo_cp_d_gain`` is 3 N s/m by default and 5 N s/m in ``share/sawSensablePhantomDefault.json``
(``core/components/code/mtsSensableHD.cpp``), and its ``ros/scripts/cartesian_impedance.py`` example renders
5 N s/m beside 200 N/m. Check: a sampled damper acting two 1 ms ticks late on the 45 g stylus
(:data:`skin_sim_node.device.render.PASSIVITY_DELAY_TICKS`) is stable below ``m / (3 dt)`` = 15 N s/m, 3x above."""

DEFAULT_OFFSET_M: Vec3 = (0.0, 0.0, 0.05)
"""Tissue-frame position of the device origin (m). Matches :mod:`skin_sim_node.device.stylus`,
whose origin sits 50 mm above the rest surface: about a Touch's usable workspace half-height
(workspace 160 x 120 x 70 mm), so the stylus reaches the tissue from mid-workspace."""


def vec3(v: Sequence[float]) -> Vec3:
    """Three floats from a sequence of exactly three numbers (``ValueError`` otherwise)."""
    x, y, z = v
    return (float(x), float(y), float(z))


def axes_matrix(axes: str) -> Mat3:
    """Signed permutation matrix ``R`` (rows = tissue x, y, z) from a string like ``"x-zy"``.

    Each of the three tokens, an optional ``-`` and a device axis letter, says which device
    axis (with sign) the tissue axis is: ``"x-zy"`` means tissue x = device x, tissue y =
    -device z, tissue z = device y (a Touch's frame has y up and z towards the user).

    Raises
    ------
    ValueError
        If the string is not three signed, distinct axes.
    """
    tokens, sign = [], 1.0
    for ch in axes.replace(" ", "").lower():
        if ch in "+-":
            sign = -1.0 if ch == "-" else 1.0
            continue
        if ch not in "xyz":
            raise ConfigError(f"axes {axes!r}: unexpected character {ch!r}")
        tokens.append((sign, "xyz".index(ch)))
        sign = 1.0
    if len(tokens) != 3 or sorted(j for _, j in tokens) != [0, 1, 2]:
        raise ConfigError(f"axes {axes!r}: need each of x, y, z exactly once, e.g. 'xyz' or 'x-zy'")
    rows = []
    for s, j in tokens:
        row = [0.0, 0.0, 0.0]
        row[j] = s
        rows.append(vec3(row))
    return (rows[0], rows[1], rows[2])


def _mat_vec(R: Mat3, v: Sequence[float]) -> Vec3:
    return (
        R[0][0] * v[0] + R[0][1] * v[1] + R[0][2] * v[2],
        R[1][0] * v[0] + R[1][1] * v[1] + R[1][2] * v[2],
        R[2][0] * v[0] + R[2][1] * v[1] + R[2][2] * v[2],
    )


def _mat_t_vec(R: Mat3, v: Sequence[float]) -> Vec3:
    return (
        R[0][0] * v[0] + R[1][0] * v[1] + R[2][0] * v[2],
        R[0][1] * v[0] + R[1][1] * v[1] + R[2][1] * v[2],
        R[0][2] * v[0] + R[1][2] * v[1] + R[2][2] * v[2],
    )


def _det(R: Mat3) -> float:
    return (
        R[0][0] * (R[1][1] * R[2][2] - R[1][2] * R[2][1])
        - R[0][1] * (R[1][0] * R[2][2] - R[1][2] * R[2][0])
        + R[0][2] * (R[1][0] * R[2][1] - R[1][1] * R[2][0])
    )


def _quat_from_rot(R: Mat3) -> Quat:
    """(x, y, z, w) of a proper rotation matrix (Shepperd's method)."""
    tr = R[0][0] + R[1][1] + R[2][2]
    if tr > 0:
        s = 2.0 * math.sqrt(tr + 1.0)
        return ((R[2][1] - R[1][2]) / s, (R[0][2] - R[2][0]) / s, (R[1][0] - R[0][1]) / s, 0.25 * s)
    i = max(range(3), key=lambda k: R[k][k])
    j, k = (i + 1) % 3, (i + 2) % 3
    s = 2.0 * math.sqrt(max(1.0 + R[i][i] - R[j][j] - R[k][k], 0.0))
    q = [0.0, 0.0, 0.0, 0.0]
    q[i] = 0.25 * s
    q[j] = (R[j][i] + R[i][j]) / s
    q[k] = (R[k][i] + R[i][k]) / s
    q[3] = (R[k][j] - R[j][k]) / s
    return (q[0], q[1], q[2], q[3])


def _quat_mul(a: Sequence[float], b: Sequence[float]) -> Quat:
    ax, ay, az, aw = a
    bx, by, bz, bw = b
    return (
        aw * bx + ax * bw + ay * bz - az * by,
        aw * by - ax * bz + ay * bw + az * bx,
        aw * bz + ax * by - ay * bx + az * bw,
        aw * bw - ax * bx - ay * by - az * bz,
    )


def _finite(v: Sequence[float]) -> bool:
    return all(math.isfinite(c) for c in v)


@dataclass(frozen=True)
class DeviceMapping:
    """Device frame <-> tissue frame: ``p_tissue = scale * R p_device + offset_m``.

    Parameters
    ----------
    offset_m : tuple of float
        Tissue-frame position of the device origin (m). Default: :data:`DEFAULT_OFFSET_M`.
    scale : float
        Motion scale (tissue metres per device metre), > 0.
    axes : str
        Axis convention, see :func:`axes_matrix`.
    force_scale : float
        ``F_device = force_scale * R^T F_tissue`` before the clamp, >= 0.
    max_force_n : float
        Clamp of the device force magnitude (direction kept). Default: a Touch's peak force.
    """

    offset_m: Vec3 = DEFAULT_OFFSET_M
    scale: float = 1.0
    axes: str = "xyz"
    force_scale: float = 1.0
    max_force_n: float = TOUCH_PEAK_FORCE_N
    R: Mat3 = field(init=False, repr=False, compare=False)
    """Signed permutation ``R`` of :func:`axes_matrix` (rows = tissue x, y, z), from ``axes``."""
    _q: Quat | None = field(init=False, repr=False, compare=False)

    def __post_init__(self) -> None:
        object.__setattr__(self, "offset_m", tuple(float(c) for c in self.offset_m))
        if len(self.offset_m) != 3 or not _finite(self.offset_m):
            raise ConfigError(f"offset_m must be 3 finite numbers, got {self.offset_m}")
        if not (math.isfinite(self.scale) and self.scale > 0):
            raise ConfigError(f"scale must be finite and > 0, got {self.scale}")
        if not (math.isfinite(self.force_scale) and self.force_scale >= 0):
            raise ConfigError(f"force_scale must be finite and >= 0, got {self.force_scale}")
        if not (math.isfinite(self.max_force_n) and self.max_force_n >= 0):
            raise ConfigError(f"max_force_n must be finite and >= 0, got {self.max_force_n}")
        R = axes_matrix(self.axes)
        object.__setattr__(self, "R", R)
        object.__setattr__(self, "_q", _quat_from_rot(R) if _det(R) > 0 else None)

    @property
    def proper(self) -> bool:
        """True if ``R`` is a rotation (det +1); an improper convention cannot map orientations."""
        return self._q is not None

    def to_tissue(self, p_device: Sequence[float]) -> Vec3:
        """Device position (m) -> tissue position (m)."""
        r, o, k = _mat_vec(self.R, p_device), self.offset_m, self.scale
        return (k * r[0] + o[0], k * r[1] + o[1], k * r[2] + o[2])

    def to_device(self, p_tissue: Sequence[float]) -> Vec3:
        """Tissue position (m) -> device position (m); inverse of :meth:`to_tissue`."""
        o, k = self.offset_m, self.scale
        return _mat_t_vec(self.R, ((p_tissue[0] - o[0]) / k, (p_tissue[1] - o[1]) / k, (p_tissue[2] - o[2]) / k))

    def velocity_to_tissue(self, v_device: Sequence[float]) -> Vec3:
        """Device velocity (m/s) -> tissue velocity (m/s): ``scale * R v``."""
        r, k = _mat_vec(self.R, v_device), self.scale
        return (k * r[0], k * r[1], k * r[2])

    def velocity_to_device(self, v_tissue: Sequence[float]) -> Vec3:
        """Tissue velocity (m/s) -> device velocity (m/s); inverse of :meth:`velocity_to_tissue`."""
        d, k = _mat_t_vec(self.R, v_tissue), self.scale
        return (d[0] / k, d[1] / k, d[2] / k)

    def orientation_to_tissue(self, q_device: Sequence[float]) -> Quat:
        """Device orientation quaternion (x, y, z, w) -> tissue; identity for an improper ``R``."""
        if self._q is None or not _finite(q_device):
            return (0.0, 0.0, 0.0, 1.0)
        return _quat_mul(self._q, q_device)

    def orientation_to_device(self, q_tissue: Sequence[float]) -> Quat:
        """Tissue orientation quaternion (x, y, z, w) -> device; inverse of :meth:`orientation_to_tissue` (identity for
        an improper ``R``)."""
        if self._q is None or not _finite(q_tissue):
            return (0.0, 0.0, 0.0, 1.0)
        qx, qy, qz, qw = self._q
        return _quat_mul((-qx, -qy, -qz, qw), q_tissue)

    def force_to_device(self, f_tissue: Sequence[float]) -> Vec3:
        """Tissue force (N) -> device force command (N): ``force_scale * R^T f``, magnitude clamped.

        A non-finite input gives zero force.
        """
        if not _finite(f_tissue):
            return (0.0, 0.0, 0.0)
        d, k = _mat_t_vec(self.R, f_tissue), self.force_scale
        return clamp_magnitude((k * d[0], k * d[1], k * d[2]), self.max_force_n)


def force_to_tissue(mapping: DeviceMapping, f_device: Sequence[float]) -> Vec3:
    """Device force (N) -> tissue force (N): the inverse of :meth:`DeviceMapping.force_to_device` before its clamp."""
    if mapping.force_scale <= 0 or not _finite(f_device):
        return (0.0, 0.0, 0.0)
    r, k = _mat_vec(mapping.R, f_device), mapping.force_scale
    return (r[0] / k, r[1] / k, r[2] / k)


def clamp_magnitude(f: Sequence[float], max_n: float) -> Vec3:
    """``f`` scaled down to magnitude ``max_n`` if longer (direction kept); non-finite -> zero."""
    if not _finite(f):
        return (0.0, 0.0, 0.0)
    mag = math.sqrt(f[0] * f[0] + f[1] * f[1] + f[2] * f[2])
    if mag > max_n:
        k = max_n / mag
        return (f[0] * k, f[1] * k, f[2] * k)
    return (float(f[0]), float(f[1]), float(f[2]))


DEFAULTS = {
    "convention": "crtk",
    "device_ns": "device",
    "node_ns": "",  # namespace of the node's topics (tool/pose, tool/contact_model, ...); '': the process's
    "offset_m": list(DEFAULT_OFFSET_M),
    "scale": 1.0,
    "axes": "xyz",  # the simulated device's axes; a real Touch in its base frame: "x-zy"
    "force_scale": 1.0,
    "max_force_n": TOUCH_PEAK_FORCE_N,
    "watchdog_s": 0.05,  # as the node's watchdog: 50 ticks at 1 kHz, past DDS jitter, under hand reaction time
    "watchdog_rate_hz": 200.0,  # checks every 5 ms: a stale input is caught within 0.1 * watchdog_s
    "device_frame": "",  # frame_id of force commands; empty: the device pose's frame_id
    "restamp": False,  # stamp tool/pose with the bridge's clock instead of the driver's
}
DEVICE_PRESETS: dict[str, dict[str, str]] = {
    "sim": {"axes": "xyz"},
    "touch": {"convention": "crtk", "axes": "x-zy"},
}
"""The bridge's ``device`` presets: the parameters each sets unless they are given explicitly.

- ``sim``: ``skin-sim device`` (and the benchmark's CRTK emulator), whose frame is the tissue's (``xyz``).
- ``touch``: a Geomagic / Phantom Touch under jhu-saw sawSensablePhantom (CRTK topics). The Touch's base frame has
  y up and z towards the user (OpenHaptics' device frame), so tissue x, y, z are device x, -z, y: ``x-zy``
  (docs/devices.md, "With a real Touch"). Not run on hardware here: the mapping is checked against that frame only.
"""
MEASURED_FORCE = {"crtk": "crtk_measured_cf", "omni": None}
"""Topic of the force the device reports it applied, per convention (None: the bridge assumes its own commands)."""
CONVENTIONS = {
    # convention: (pose key, twist key or None, force key)
    "crtk": ("crtk_measured_cp", "crtk_measured_cv", "crtk_servo_cf"),
    "omni": ("omni_pose", None, "omni_force"),
}


_NS_TOKEN = re.compile(r"[A-Za-z_][A-Za-z0-9_]*")
_NS_REMAP = re.compile(r"^([A-Za-z0-9_/]*:)?__ns:=")


def normalize_namespace(ns: str) -> str:
    """A ROS namespace as given on the command line -> absolute (``skin1`` -> ``/skin1``); ``''`` stays ``''``.

    Raises
    ------
    ValueError
        One line naming the token that is not a ROS name (letters, digits, ``_``; not starting with a digit).
    """
    text = ns.strip()
    if text in ("", "/"):
        return ""
    tokens = text.strip("/").split("/")
    for tok in tokens:
        if not _NS_TOKEN.fullmatch(tok):
            raise ValueError(f"namespace {ns!r}: {tok!r} is not a ROS name (letters, digits and '_', not starting with a digit)")
    return "/" + "/".join(tokens)


def without_namespace_remap(ros_args: list[str]) -> list[str]:
    """``ros_args`` without its ``-r __ns:=...`` / ``--remap node:__ns:=...`` remaps (the rest kept in order).

    The bridge's node-side participant takes its namespace from ``node_ns`` when that is given, so a process-wide
    ``__ns`` remap (which moves the device topics too) must not override it there.
    """
    out: list[str] = []
    i = 0
    while i < len(ros_args):
        a = ros_args[i]
        if a in ("-r", "--remap") and i + 1 < len(ros_args) and _NS_REMAP.match(ros_args[i + 1]):
            i += 2
            continue
        out.append(a)
        i += 1
    return out


def parse_vec3(text: str) -> list[float]:
    """``argparse`` type: ``"x y z"`` or ``"x,y,z"`` -> three floats."""
    v = [float(c) for c in text.replace(",", " ").split()]
    if len(v) != 3:
        raise argparse.ArgumentTypeError(f"expected 3 numbers, got {text!r}")
    return v
