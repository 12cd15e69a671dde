"""The haptic session's tick: input policy -> tool step -> force limits -> one :class:`TickResult`. No rclpy.

The live node and the offline replay both drive a tool (:mod:`skin_sim_node.tools`) through :class:`HapticSession`,
so they apply the same input checks (:mod:`.inputs`), velocity estimate and force limits (:mod:`.limits`). The session
knows no tool: what a tool needs it declares (:class:`~skin_sim_node.tools.ToolNeeds`), what its step produced it
returns in one record (:class:`~skin_sim_node.tools.ToolStep`). Times are integer nanoseconds: message stamps for
inputs, the caller's clock for ``now_ns``.
"""

from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import dataclass, replace

import numpy as np

from msgs_schema.parameters import SessionParams

from ..model import (
    FLAG_BOTTOMED,
    FLAG_CONTACT,
    FLAG_LAYER_BOUND,
    FLAG_OFF_SHEET,
    FLAG_SEPARATED,
    ContactTangent,
    SkinModel,
    normal_tangent,
)
from ..tools import Tool, ToolPose, ToolStep
from .events import (
    CONTACT_SEPARATED,
    DEGENERATE_WAVE_SPEED,
    PATCH_CLIPPED,
    REUSS_BOUND,
    TOOL_BELOW_TISSUE,
    TOOL_OFF_SHEET,
    EventLog,
)
from .inputs import InputPolicy, TickInput
from .limits import ForceLimits

NO_CONTACT = normal_tangent(0.0, 0.0, 0.0, 0.0)
"""The tangent out of contact (no force, no stiffness), shared: :meth:`SkinModel.tangent` builds its arrays
anew on each call (8 us of a 1 ms tick), so a tool builds its tangent only while it is in contact."""

STATE_CHECK_TICKS = 64
"""Every this many ticks the force limits also ask whether the model's energy is finite (a NaN can hide in
a layer that does not touch the force)."""


MAX_SUBSTEPS = 64
"""Most parts one tick steps a long interval in (:func:`substeps`): 6.4 s at the default ``max_dt_s``, past the default
``stall_hold_s`` (2 s, 20 parts); a longer interval (a raised ``stall_hold_s``) takes longer parts, which the
backward-Euler chain and the modal membranes integrate stably (a stated bound on one tick's work: 64 steps of the
costliest tool are about 2 ms)."""


def substeps(dt_s: float, max_dt_s: float) -> int:
    """How many parts an interval ``dt_s`` is stepped in: each at most ``max_dt_s``, at most :data:`MAX_SUBSTEPS`.

    Parameters
    ----------
    dt_s, max_dt_s : float
        The interval and the longest part (s); ``max_dt_s`` 0 steps in one.

    Returns
    -------
    int
    """
    if max_dt_s <= 0.0 or dt_s <= max_dt_s:
        return 1
    return min(math.ceil(dt_s / max_dt_s - 1e-9), MAX_SUBSTEPS)


@dataclass(frozen=True)
class TickResult:
    """What one haptic tick produced: the one output path (node, offline replay and benchmarks read only this).

    :func:`msgs_schema.convert.fill_wrench_from_tick` and :func:`msgs_schema.convert.fill_contact_from_tick`
    turn it into the ``tool/wrench`` and ``tissue/contact`` messages.

    Attributes
    ----------
    seq : int
        Tick sequence number, increasing by one per tick of this session (from 1).
    stamp_ns : int
        Stamp of the pose the model ran at (the last accepted pose; 0 before any).
    answered : bool
        This tick consumed a newly accepted pose (it answers that pose).
    x0_m : tuple of 3 float
        Tool position the model ran at (tissue frame, m): when stale the last pose, held through a stall, or lifted
        to ``z = 1 m`` once the stall outlasted ``stall_hold_s``.
    velocity_m_s : tuple of 3 float
        Tool velocity the model ran at (m/s).
    force_n : tuple of 3 float
        Published reaction force vector on the tool (N, tissue frame): the model's whole force (along the deformed
        surface's normal, plus friction) scaled by the session's clamp, rate bound and watchdog, which act on its
        magnitude.
    depth_m : float
        Tool depth of the Reuss split (eq 6), 0 out of contact.
    n_affected : int
        Layers engaged by the contact (the deepest reached).
    compression_m, compression_rate_m_s, stress_pa : tuple of float, one per layer
        Reuss compression of each layer, its rate (the normal speed shared in proportion to the
        compression), and the common Reuss stress on the engaged layers (0 on the others).
    flags : int
        Model regime flags of the step (``skin_sim_node.model.FLAG_*``).
    events : tuple of str
        Rejection, safety and regime event kinds raised since the previous tick (each occurrence).
    stale : bool
        The input watchdog fired: the published force is zero (the tissue keeps its state through a stall of up to
        ``stall_hold_s``, the tool held at its last pose).
    idle : bool
        The model skipped the kernel (tissue at rest, tool off it).
    tangent : ContactTangent
        The local linearisation of the published force at ``x0_m``, for the local contact model: ``f0 = force_n``,
        and the tool's ``K``, ``D`` (:attr:`ToolStep.tangent`) scaled as the force was.
    """

    seq: int
    stamp_ns: int
    answered: bool
    x0_m: tuple[float, float, float]
    velocity_m_s: tuple[float, float, float]
    force_n: tuple[float, float, float]
    depth_m: float
    n_affected: int
    compression_m: tuple[float, ...]
    compression_rate_m_s: tuple[float, ...]
    stress_pa: tuple[float, ...]
    flags: int
    events: tuple[str, ...]
    stale: bool
    idle: bool
    tangent: ContactTangent

    @property
    def force_z_n(self) -> float:
        """The published force's component along the sheet's normal ``+z`` (N)."""
        return self.force_n[2]


def _part(part: str, name: str, doc: str) -> property:
    """A read-only attribute of the session that is attribute ``name`` of its part ``part``.

    Parameters
    ----------
    part : str
        ``"inputs"``, ``"limits"`` or ``"_event"``.
    name : str
    doc : str

    Returns
    -------
    property
    """
    return property(lambda self: getattr(getattr(self, part), name), doc=doc)


class HapticSession:
    """Owns a :class:`~skin_sim_node.tools.Tool` (and the tissue it presses) and turns input samples into force ticks.

    Composes the :class:`~.inputs.InputPolicy` (which samples are accepted, what a tick runs at), the tool's
    step and the :class:`~.limits.ForceLimits` (what is published of its force), and builds the tick's
    :class:`TickResult`.

    Parameters
    ----------
    tool : Tool
        :func:`skin_sim_node.tools.make_tool` of the configuration.
    params : SessionParams
    log : callable(kind, message), optional
        Called once per event kind (the first occurrence); every occurrence is counted
        in :attr:`counts` (rejections, safety actions) or :attr:`regime_counts` (:data:`REGIME_EVENTS`).

    Attributes
    ----------
    tool : Tool
        The tool it runs (:meth:`set_tool` swaps it); :attr:`model` is the tissue it presses.
    inputs : InputPolicy
        The input and stamp policy (its state: :attr:`pose`, :attr:`stale`, ... read through the session).
    limits : ForceLimits
        The force limits (:attr:`force_n`).
    velocity : tuple of 3 float
        The tool velocity the last tick ran at (m/s).
    last : TickResult or None
        The last tick's result.
    """

    def __init__(self, tool: Tool, params: SessionParams, log: Callable[[str, str], None] | None = None):
        self.tool: Tool = tool  # set_tool below also logs its tissue's degenerate layers
        self._event = EventLog(log)
        self.inputs = InputPolicy(params, self._event)
        self.limits = ForceLimits(params, self._event)
        self._params = params
        self._ticks = 0
        self.velocity = (0.0, 0.0, 0.0)
        self._seq = 0
        self.last: TickResult | None = None  # the last tick's result
        self.set_tool(tool)

    # --- parameters, and the parts' state as attributes of the session (read-only) -----------------------
    @property
    def params(self) -> SessionParams:
        """The session's parameters; setting them (a live parameter change) applies from the next call."""
        return self._params

    @params.setter
    def params(self, params: SessionParams) -> None:
        self._params = self.inputs.params = self.limits.params = params

    counts = _part("_event", "counts", "Occurrences of each rejection and safety event (``collections.Counter``).")
    regime_counts = _part("_event", "regime_counts", "Occurrences of each model-regime event (:data:`REGIME_EVENTS`).")
    force_n = _part("limits", "force_n", "The magnitude of the last published force (N).")
    stale = _part("inputs", "stale", "The input watchdog fired at the last tick (published force zero).")
    pose_rx_ns = _part("inputs", "pose_rx_ns", "Caller-clock arrival time of the last accepted pose (None before any).")
    pose_stamp_ns = _part("inputs", "pose_stamp_ns", "Stamp of the last accepted pose (None before any).")
    pose = _part("inputs", "pose", "The last accepted tool position (m).")
    twist_stamp_ns = _part("inputs", "twist_stamp_ns", "Stamp of the last accepted twist (None before any).")
    twist = _part("inputs", "twist", "The last accepted tool velocity (m/s).")
    answered_stamp_ns = _part("inputs", "answered_stamp_ns", "Stamp of the last pose a tick answered (0 before any).")

    @property
    def model(self) -> SkinModel:
        """The tissue the tool presses (its state, grid and energy)."""
        return self.tool.tissue

    def set_tool(self, tool: Tool) -> None:
        """Swap in a new tool and tissue (a live tissue parameter change); the tissue restarts at rest.

        Parameters
        ----------
        tool : Tool
        """
        self.tool = tool
        model = tool.tissue
        if model.degenerate_layers:  # the model releases them from rest itself
            self._event(
                DEGENERATE_WAVE_SPEED,
                f"degenerate wave speed: {', '.join(model.degenerate_layers)} take {model.slowest_return_s:.3g} s to "
                f"return (c = {min(la.wave_speed_m_per_s for la in model.cfg.layers):.3g} m/s); released from rest",
            )
        cfg = model.cfg
        needs = tool.needs
        self.inputs.orientation_required = needs.orientation
        self._rises_only = needs.rises_only
        # the presliding friction the tool's force follows (issue 30), carried in the local contact model with its
        # anchor so the device renders it from its own positions; the paper form's force has none (its tangent's
        # friction_coefficient is 0), a tool that declares no friction publishes none
        self._friction = needs.friction
        self._patch_free = (0.5 * (cfg.sheet_size_m[0] - cfg.patch_size_m[0]), 0.5 * (cfg.sheet_size_m[1] - cfg.patch_size_m[1]))

    # --- inputs (the policy's) --------------------------------------------------------------
    def on_pose(
        self, stamp_ns: int, frame: str, xyz, now_ns: int | None = None, rx_ns: int | None = None, quat=None
    ) -> str | None:
        """Validate and store a tool pose: :meth:`.inputs.InputPolicy.on_pose` (its parameters and return; ``quat``
        the orientation ``(x, y, z, w)``, used by a tool that declares it, :attr:`ToolNeeds.orientation`).

        Returns
        -------
        str or None
            None if accepted, else the rejection kind.
        """
        return self.inputs.on_pose(stamp_ns, frame, xyz, now_ns, rx_ns, quat)

    def on_twist(self, stamp_ns: int, frame: str, linear) -> str | None:
        """Validate and store a tool twist: :meth:`.inputs.InputPolicy.on_twist` (its parameters and return).

        Returns
        -------
        str or None
            None if accepted, else the rejection kind.
        """
        return self.inputs.on_twist(stamp_ns, frame, linear)

    # --- the tick ---------------------------------------------------------------------
    def tick(self, now_ns: int, elapsed_ns: int) -> TickResult:
        """One haptic tick: the input policy's sample, the tool's step, the force limits.

        If a new pose arrived, the model advances by the pose stamps' difference (less
        the time already advanced by pose-less ticks); otherwise by ``elapsed_ns`` with the
        last pose held.

        Parameters
        ----------
        now_ns : int
            The caller's clock (the watchdog's).
        elapsed_ns : int
            Caller-clock time since the previous tick.

        Returns
        -------
        TickResult
            Also kept in :attr:`last`; its force's magnitude (N) is also :attr:`force_n`.
        """
        tool = self.tool
        ti = self.inputs.take(now_ns, elapsed_ns)
        if ti.hold and self.last is not None:  # no new pose: model, force and local model held (model time = stamps)
            self._seq += 1
            if ti.stale:  # a stall: the tissue keeps its state, unstepped; the published force is zero, at once
                self.limits.apply(0.0, ti.rate_dt_ns, True)
                zero = (0.0, 0.0, 0.0)
                self.velocity = zero
                self.last = replace(
                    self.last, seq=self._seq, answered=False, events=self._event.take(), force_n=zero, velocity_m_s=zero,
                    stale=True, tangent=NO_CONTACT,
                )  # fmt: skip
            else:
                self.last = replace(self.last, seq=self._seq, answered=False, events=self._event.take())
            return self.last
        self.velocity = ti.velocity
        if ti.release:
            tool.release()
        step = self._step(tool, ti)
        self._ticks += 1
        self._regime_events(ti.pos, step.flags)
        # the whole vector (normal along the deformed surface plus friction): the limits act on its magnitude and
        # scale it, so the wrench, the contact model's f0 and its K, D all describe the one published force
        raw = step.force_n
        magnitude = math.sqrt(float(raw @ raw))
        check = self._state_finite if self._ticks % STATE_CHECK_TICKS == 0 else None
        published, reset = self.limits.apply(magnitude, ti.rate_dt_ns, ti.stale, check, rises_only=self._rises_only)
        if reset:
            tool.reset()
            step = tool.at_rest(step)
        return self._result(step, ti.answered, ti.pos, ti.velocity, *self._published_vector(raw, magnitude, published), ti.stale)

    def _step(self, tool: Tool, ti: TickInput) -> ToolStep:
        """The tool's step over ``ti``: one step, or, for an interval over ``max_dt_s`` that continues contact (a gap
        in the poses, or the rest of a stall), :func:`substeps` of it along the line from where the model last ran
        the tool (:attr:`TickInput.from_pos`) to the new pose, each at most ``max_dt_s`` (the model continues as if
        stepped over the gap; the record is the last part's)."""
        a = ti.from_pos
        n = substeps(ti.dt_s, self._params.max_dt_s) if a is not None else 1
        if a is None or n == 1:
            return tool.step(ToolPose(ti.pos, ti.velocity, ti.axis, ti.dt_s, ti.restart))
        b, dt = ti.pos, ti.dt_s / n
        for k in range(1, n):
            s = k / n
            pos = (a[0] + s * (b[0] - a[0]), a[1] + s * (b[1] - a[1]), a[2] + s * (b[2] - a[2]))
            tool.step(ToolPose(pos, ti.velocity, ti.axis, dt, False))
        return tool.step(ToolPose(ti.pos, ti.velocity, ti.axis, dt, False))

    def _published_vector(self, raw: np.ndarray, magnitude: float, published: float) -> tuple[np.ndarray, float]:
        """The published force vector of magnitude ``published`` and the scale it applies to the model's ``raw``.

        Along ``raw``; when the model's force is gone but the rate bound still ramps the published one down (the tool
        left the tissue faster than the bound allows), along the last published force, with scale 0 (no tangent).
        """
        if published <= 0.0:
            return np.zeros(3), 0.0
        if magnitude > 0.0:
            direction, scale = raw / magnitude, published / magnitude
        else:
            last = np.asarray(self.last.force_n if self.last is not None else (0.0, 0.0, 1.0), dtype=float)
            n = math.sqrt(float(last @ last))
            direction, scale = (last / n if n > 0.0 else np.array([0.0, 0.0, 1.0])), 0.0
        vec = direction * published
        while math.sqrt(float(vec @ vec)) > published:  # never an ulp above the limit the magnitude met
            vec = np.nextafter(vec, 0.0)
        return vec, scale

    def _state_finite(self) -> bool:
        """Whether the model's energy (hence its whole state) is finite."""
        return math.isfinite(self.model.energy())

    def _result(self, step: ToolStep, answered: bool, pos, v, force: np.ndarray, scale: float, stale: bool) -> TickResult:
        """The frozen record of this tick (the contact message's per-layer rate and stress included).

        ``force`` is the published vector, the tool's scaled by ``scale`` (the limits' share of it); the tangent is
        that of the published force: ``f0 = force`` and the tool's ``K``, ``D`` scaled alike.
        """
        n = step.n_affected
        depth = step.depth_m
        comp = step.compression_m
        nl = len(comp)
        k = -v[2] / depth if depth > 0 else 0.0  # the normal speed, shared in proportion to each layer's compression
        rate = tuple([k * c for c in comp])
        stress = (step.stress_pa,) * n + (0.0,) * (nl - n)
        self._seq += 1
        events = self._event.take()
        flags = step.flags
        tangent = NO_CONTACT
        t = step.tangent
        if scale == 0.0 and force.any():  # ramping down out of contact: f0 is the published force, no stiffness
            tangent = ContactTangent(force.copy(), np.zeros((3, 3)), np.zeros((3, 3)), NO_CONTACT.normal, 0.0)
        elif t is not None and scale > 0.0:
            tangent = t.published(force, scale, self._friction)
        self.last = TickResult(
            seq=self._seq,
            stamp_ns=self.inputs.answered_stamp_ns,
            answered=answered,
            x0_m=tuple(pos),
            velocity_m_s=tuple(v),
            force_n=(float(force[0]), float(force[1]), float(force[2])),
            depth_m=depth,
            n_affected=n,
            compression_m=comp,
            compression_rate_m_s=rate,
            stress_pa=stress,
            flags=flags,
            events=events,
            stale=stale,
            idle=step.idle,
            tangent=tangent,
        )
        return self.last

    # --- read-outs for the node's diagnostics, display and logs (no caller reads the model) ---------------------
    @property
    def kernel_calls(self) -> int:
        """Model kernel invocations so far (idle ticks make none)."""
        return self.model.kernel_calls

    @property
    def modes_per_axis(self) -> tuple[int, ...]:
        """Modes per axis each layer uses now (adaptive: its current level; else the fixed count)."""
        return tuple(int(k) for k in self.model.modes_per_axis())

    @property
    def idle_ticks(self) -> int:
        return self.model.idle_ticks

    @property
    def state_key(self) -> tuple[int, int]:
        """Changes whenever the deformation may have changed (a kernel call, a reset or a new model)."""
        return id(self.model), self.model.version

    def display_state(self) -> dict:
        """Live views of the modal state the display rebuilds the grid from (copy them before the next tick)."""
        m = self.model
        return {"q": m.q, "centre": m.centre, "driven": m.driven, "level": m.level, "active": m.active}

    def build_grid(self):
        """The display grid of the current deformation (:meth:`SkinModel.build_grid`)."""
        return self.model.build_grid()

    def readout(self) -> dict | None:
        """The tool's own read-out (:attr:`ToolNeeds.readout`'s topic fields), None for a tool without one."""
        return self.tool.readout()

    def state(self) -> dict:
        """A copy of the tool's dynamic state (see :meth:`SkinModel.state`), e.g. at peak force."""
        return self.tool.state()

    def describe_modes(self) -> str:
        """The mode counts the model really runs: adaptive levels, or the fixed ``modes.m x modes.n``."""
        cfg, b = self.model.cfg, self.model.basis
        if cfg.lod.adaptive_modes:
            top = int(b.level_modes[-1])
            return (
                f"adaptive modes on (tissue.lod.adaptive_modes): each layer uses 1x1 to {top}x{top} modes per axis "
                f"({b.n_modes} odd modes at most) to keep the truncation within tissue.lod.tolerance_m = "
                f"{cfg.lod.tolerance_m:g} m; tissue.modes.m x n = {cfg.modes[0]}x{cfg.modes[1]} applies only with it off"
            )
        return f"fixed modes: {cfg.modes[0]}x{cfg.modes[1]} per axis ({b.n_modes} odd modes), adaptive modes off"

    # --- model regime ---------------------------------------------------------------------
    def _regime_events(self, pos, f: int) -> None:
        """Log (once each) the model-regime flags ``f`` of the last step; the kernel already bounded them."""
        if f & FLAG_BOTTOMED:
            self._event(TOOL_BELOW_TISSUE, f"tool {-pos[2] * 1e3:.2f} mm deep, below the tissue: depth clamped at the bottom")
        if f & FLAG_LAYER_BOUND:
            self._event(
                REUSS_BOUND,
                "a layer's Reuss compression left [0, thickness] (fast press or retraction, or a "
                "saturated layer): held at the bound, the rest of the depth split over the others",
            )
        if f & FLAG_SEPARATED:
            self._event(CONTACT_SEPARATED, "tool retracted faster than the tissue follows (Reuss stress <= 0): contact released")
        if f & FLAG_OFF_SHEET and pos[2] < 0.0:
            self._event(TOOL_OFF_SHEET, f"tool at ({pos[0] * 1e3:.1f}, {pos[1] * 1e3:.1f}) mm is off the sheet: no contact")
        if f & FLAG_CONTACT and (abs(pos[0]) > self._patch_free[0] or abs(pos[1]) > self._patch_free[1]):
            self._event(
                PATCH_CLIPPED,
                f"contact at ({pos[0] * 1e3:.1f}, {pos[1] * 1e3:.1f}) mm: the deformation patch "
                "passes the sheet edge and is clipped there (the paper's incomplete deformation)",
            )
