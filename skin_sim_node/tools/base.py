"""The tool seam: what the haptic session asks of a tool, and the one record a tool's step returns. No rclpy.

A tool is the rigid object the hand holds. It presses the tissue (:class:`~skin_sim_node.model.SkinModel`, which knows
the tissue only) and owns its own physics (a needle's puncture and friction; a punch has none beyond the tissue's
contact). The session (:class:`~skin_sim_node.session.HapticSession`) composes the input policy, a tool and the force
limits with no tool-specific branch: what differs between tools is declared (:class:`ToolNeeds`) or returned
(:class:`ToolStep`). It mirrors the tissue's :class:`~skin_sim_node.model.layout.Form` seam: a variant is a type, chosen
once (:func:`skin_sim_node.tools.make_tool`), not a flag tested every tick.

Adding a tool: one module under ``skin_sim_node/tools/`` with a :class:`Tool` subclass, its entry in
:data:`skin_sim_node.tools.TOOLS`, and its law in the contract (``msgs_schema``) if the device renders it.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass
from typing import Any, ClassVar

import numpy as np

from ..model import ContactTangent, Indenter, SkinModel, TissueConfig

DOWN = (0.0, 0.0, -1.0)
"""The tool axis of an identity orientation: straight down into the tissue (msgs_schema/topics.py, ``tool_pose``)."""


@dataclass(frozen=True)
class ToolPose:
    """The tool state a tick runs at (tissue frame, SI).

    Attributes
    ----------
    position_m : tuple of 3 float
        The tool's tip (m).
    velocity_m_s : tuple of 3 float
        Its velocity (m/s).
    axis : tuple of 3 float
        Its unit axis toward the tip (from the pose's orientation; :data:`DOWN` when the tool ignores it).
    dt_s : float
        Time since the previous step (s).
    restart : bool
        Contact restarts after an unknown time (a first pose, a stall past ``stall_hold_s``, a teleport).
    """

    position_m: tuple[float, float, float]
    velocity_m_s: tuple[float, float, float]
    axis: tuple[float, float, float]
    dt_s: float
    restart: bool


@dataclass(frozen=True)
class Readout:
    """A tool's own read-out topic (the needle's ``tissue/needle``): the contract topic key and its message filler.

    Attributes
    ----------
    topic : str
        Key of :data:`msgs_schema.topics.TOPICS`.
    fill : callable(msg, state, stamp_ns, frame) -> msg
        Fills a message of that topic from :meth:`Tool.readout`'s dict (a function of :mod:`msgs_schema.convert`).
    """

    topic: str
    fill: Callable[[Any, dict, int, str], Any]


@dataclass(frozen=True)
class ToolNeeds:
    """What a tool declares to the session and the node (read once, when the tool is chosen).

    Attributes
    ----------
    orientation : bool
        The tool uses the pose's orientation: a quaternion off unit norm is rejected, and :attr:`ToolPose.axis` comes
        from it (:attr:`skin_sim_node.session.InputPolicy.orientation_required`).
    rises_only : bool
        The force-rate bound limits rises only (:meth:`skin_sim_node.session.ForceLimits.apply`): a falling force the
        hand must feel within one tick (a needle's puncture drop).
    friction : bool
        The tool's force follows the tissue's friction law (the layered form's ``F_n (n - mu v_t / sqrt(|v_t|^2 +
        v_s^2))``), so the contact model carries it for the device to evaluate at its own velocity (issue 19).
    readout : Readout or None
        A topic of the tool's own, published at the display rate while read; the node creates its publisher only
        for a tool that declares one.
    """

    orientation: bool = False
    rises_only: bool = False
    friction: bool = True
    readout: Readout | None = None


@dataclass(frozen=True)
class ToolStep:
    """What one step of a tool produced: the one record the session reads (it reads nothing else of the tool).

    Attributes
    ----------
    force_n : ndarray, shape (3,)
        Reaction force on the tool (N, tissue frame): the session's limits act on its magnitude.
    tangent : ContactTangent or None
        The force's local linearisation with the device's law (``K``, ``D``, normal, contact radius, friction law,
        a tool law such as the needle's), unscaled; None out of contact (``FLAG_CONTACT`` clear).
    flags : int
        Regime flags of the step (``skin_sim_node.model.FLAG_*``).
    idle : bool
        The tissue skipped its kernel (at rest, tool off it).
    depth_m : float
        Tool depth the contact message reports (m), 0 out of contact.
    n_affected : int
        Layers engaged.
    compression_m : tuple of float
        Each layer's compression (m).
    stress_pa : float
        Contact stress on the engaged layers (Pa).
    """

    force_n: np.ndarray
    tangent: ContactTangent | None
    flags: int
    idle: bool
    depth_m: float
    n_affected: int
    compression_m: tuple[float, ...]
    stress_pa: float


def evolve(record, **changes):
    """A copy of a frozen dataclass record (:class:`ToolPose`, :class:`ToolStep`,
    :class:`~skin_sim_node.model.ContactTangent`) with ``changes``: :func:`dataclasses.replace` without its
    ``__init__`` call, which a coupled tick makes three times (issue 32; about a fifth of the cost). Valid for
    records whose fields are all init fields and that have no ``__post_init__`` (the three above); a name that is not
    a field raises, as ``replace`` does."""
    fields = type(record).__dataclass_fields__
    if not changes.keys() <= fields.keys():
        raise TypeError(f"{type(record).__name__} has no field {sorted(changes.keys() - fields.keys())[0]!r}")
    new = object.__new__(type(record))
    state = vars(new)
    state.update(vars(record))
    state.update(changes)
    return new


def tissue_step(tissue: SkinModel, force_n: np.ndarray, tangent: ContactTangent | None) -> ToolStep:
    """The :class:`ToolStep` of a tool whose contact read-outs are the tissue's last step (depth, layers, stress).

    Parameters
    ----------
    tissue : SkinModel
    force_n : ndarray, shape (3,)
    tangent : ContactTangent or None

    Returns
    -------
    ToolStep
    """
    return ToolStep(
        force_n=force_n,
        tangent=tangent,
        flags=tissue.flags,
        idle=tissue.last_tick_idle,
        depth_m=tissue.depth_m,
        n_affected=tissue.n_affected,
        compression_m=tuple(tissue.compression_m.tolist()),
        stress_pa=tissue.stress_pa,
    )


class Tool:
    """A tool pressing one tissue (module docstring). Subclasses give :meth:`step` and may extend the others.

    Parameters
    ----------
    cfg : TissueConfig
        The validated configuration (the tissue's, and the tool's own ``tool.*`` / ``needle.*`` parameters); the
        tissue is built from it, pressed by the tool's :meth:`indenter`.

    Attributes
    ----------
    tissue : SkinModel
        The tissue it presses (the display, the grid and the state hand-over read it).
    needs : ToolNeeds
        What it declares (class attribute).
    """

    needs: ClassVar[ToolNeeds] = ToolNeeds()

    def __init__(self, cfg: TissueConfig):
        self.cfg = cfg
        self.tissue = SkinModel(cfg, self.indenter(cfg))

    @classmethod
    def indenter(cls, cfg: TissueConfig) -> Indenter:
        """The rigid tip the tool presses the tissue with (its kernel's contact and modal load)."""
        raise NotImplementedError

    def step(self, pose: ToolPose) -> ToolStep:
        """Advance the tool and the tissue one tick at ``pose``; the record of what it produced."""
        raise NotImplementedError

    def release(self) -> None:
        """End contact now (a teleport, or a stall past ``stall_hold_s``): the tissue relaxes freely."""
        self.tissue.release()

    def reset(self) -> None:
        """Return to rest (the limits' non-finite reset)."""
        self.tissue.reset()

    def at_rest(self, step: ToolStep) -> ToolStep:
        """``step`` as the session reports it after :meth:`reset` in the same tick: the contact read-outs of a tissue
        at rest (no force, no contact), the step's idle kept."""
        t = self.tissue
        return ToolStep(
            np.zeros(3), None, t.flags, step.idle, t.depth_m, t.n_affected, tuple(t.compression_m.tolist()), t.stress_pa
        )

    def readout(self) -> dict | None:
        """The tool's own read-out for :attr:`ToolNeeds.readout` (None for a tool without one)."""
        return None

    def state(self) -> dict:
        """A copy of the dynamic state (the tissue's, :meth:`SkinModel.state`)."""
        return self.tissue.state()

    @classmethod
    def warm_up(cls, cfg: TissueConfig) -> None:
        """Compile (or load from numba's cache) the tool's own kernels beyond the tissue's; none by default."""
