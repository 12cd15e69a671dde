"""Offline replay core: a bag's tool inputs through :class:`HapticSession` in stamp order.

No DDS and no wall clock. Each accepted pose is answered as the live node answers it in
``input`` loop mode: one session tick, a ``tool/wrench`` and a ``tissue/contact`` stamped
with the pose's stamp. The tick is driven exactly as the ROS integration test's offline
reference does it: ``on_pose(stamp, frame, xyz)`` with no clock (no stamp-age check),
``on_twist``, ``tick(stamp, stamp - previous stamp)``. Display grids are built with
:meth:`SkinModel.build_grid` every ``1 / grid_rate_hz`` of stamp time. Every output's bag
timestamp is its header stamp, so two runs write identical message bytes.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from msgs_schema import convert as cv
from msgs_schema.parameters import session_params
from msgs_schema.tissue import LAYER_NAMES
from msgs_schema.topics import TOPICS, hand_topic

from .. import tools
from ..configure import configure
from ..configure import hand_configs as configure_hands
from ..model import SkinModel, TissueConfig
from ..model.config import load_yaml
from ..rate import AnswerThrottle
from ..scenes import DEFAULT_PARAMS
from ..session import HapticSession
from ..tools import make_tool, make_tools
from .inputs import POSE, Inputs
from .io import BagWriter, new_message, qos_profiles

OUTPUT_KEYS = ("tool_wrench", "contact", "height_map", "layer_heights")


def bag_topic(key: str) -> str:
    """Absolute bag topic name of a contract topic, as ``ros2 bag record`` writes it."""
    return "/" + TOPICS[key].name


def load_params(path=DEFAULT_PARAMS):
    """(SessionParams with the stamp-age check off, TissueConfig) from a node parameter file."""
    node_params, cfg = configure(load_yaml(path))  # the node's way (skin_sim_node.configure)
    # offline: stamps are not compared with any clock
    return session_params(node_params, max_stamp_age_s=0.0), cfg


def answer_throttle(path=DEFAULT_PARAMS) -> AnswerThrottle | None:
    """The node's answer throttle of a parameter file, as the node applies it on the pose stamps (input mode): the
    replay answers the poses a node with these parameters answers, so a node run with ``rate_hz`` below 1 kHz (with
    ``rate_policy: fixed``, or a deep input queue) replays bit for bit (issue 28 item 4). None in timer mode (the
    node's clock picks the poses; offline answers each). The follow policy's rate changes depend on the machine, not
    the poses: its replay answers at ``rate_hz``, and a bridge that forwards only the poses the node answers (the
    default) records exactly those."""
    node_params, _ = configure(load_yaml(path))
    return AnswerThrottle(node_params.rate_hz) if node_params.loop_mode == "input" else None


@dataclass
class ReplayResult:
    """What an offline replay produced (all times are stamps, ns)."""

    stamps_ns: np.ndarray
    force_n: np.ndarray  # magnitude of the published force (N), one per answered pose
    n_affected: np.ndarray
    depth_m: np.ndarray
    tool_xyz_m: np.ndarray
    counts: dict[str, int]
    n_poses: int
    n_twists: int
    n_grids: int
    peak_index: int
    peak_state: dict | None = None  # the model's dynamic state at peak force (SkinModel.state)
    cfg: TissueConfig | None = None
    layer_names: tuple[str, ...] = field(default_factory=tuple)
    tissue_frame: str = "tissue"  # the frame_id the replayed poses had to carry
    force_vec_n: np.ndarray = field(default_factory=lambda: np.zeros((0, 3)))  # the published vectors (N), (n, 3)
    hand: str = ""  # the hand's namespace ('' : the single-tool names)

    def forces_by_stamp(self) -> dict[int, np.ndarray]:
        """``{stamp_ns: force vector}`` of every answered pose: what a live node's wrenches are held against."""
        return dict(zip(self.stamps_ns.tolist(), self.force_vec_n))

    @property
    def peak_force_n(self) -> float:
        """Largest normal force of the replay (N); 0 without answered poses."""
        return float(self.force_n[self.peak_index]) if self.force_n.size else 0.0

    @property
    def layers_reached(self) -> list[str]:
        """Names of the layers the tool reached (the most layers moved by any tick)."""
        n = int(self.n_affected.max(initial=0))
        return list(self.layer_names[:n])

    def model_at_peak(self) -> SkinModel:
        """A model holding the deformation at peak force: the whole dynamic state copied at that tick
        (modal amplitudes, patch centres, mode levels and the active layer set)."""
        assert self.cfg is not None, "a replay result without its configuration"
        m = tools.tissue(self.cfg)  # as the replayed tool pressed it
        if self.peak_state is not None:
            m.set_state(self.peak_state)
        return m

    def summary(self) -> dict:
        """The replay's figures as a JSON-ready dict (counts, peak force and its stamp, layers reached)."""
        i = self.peak_index
        return {
            "poses": self.n_poses,
            "twists": self.n_twists,
            "answered": int(self.stamps_ns.size),
            "rejected": {k: v for k, v in sorted(self.counts.items())},
            "peak_force_n": self.peak_force_n,
            "peak_stamp_ns": int(self.stamps_ns[i]) if self.stamps_ns.size else None,
            "peak_tool_xyz_m": [float(c) for c in self.tool_xyz_m[i]] if self.stamps_ns.size else None,
            "layers_reached": self.layers_reached,
            "duration_s": float((self.stamps_ns[-1] - self.stamps_ns[0]) * 1e-9) if self.stamps_ns.size > 1 else 0.0,
            "grid_frames": self.n_grids,
        }


class _Out:
    """Preallocated rosbags messages of the outputs."""

    def __init__(self):
        self.wrench = new_message(TOPICS["tool_wrench"].type)
        self.contact = new_message(TOPICS["contact"].type)
        self.image = new_message(TOPICS["height_map"].type)


def _write_image(writer: BagWriter, out: _Out, key: str, stamp: int, frame: str, data: np.ndarray) -> None:
    msg = cv.fill_image(out.image, stamp, frame, data)
    msg.data = np.frombuffer(msg.data, dtype=np.uint8)
    writer.write(bag_topic(key), TOPICS[key].type, stamp, msg, qos_profiles(key))


def replay(inputs: Inputs, params=DEFAULT_PARAMS, writer: BagWriter | None = None, grid_rate_hz: float = 60.0) -> ReplayResult:
    """Run the model over ``inputs`` (one tool: the parameter file's first hand); write outputs to ``writer`` if given.

    Parameters
    ----------
    inputs : Inputs
        From :func:`skin_sim_node.bags.inputs.read_inputs`.
    params : path
        Node parameter file (tissue model and session limits).
    writer : BagWriter, optional
    grid_rate_hz : float
        Display grids (``tissue/height_map``, ``tissue/layer_heights``) per second of stamp
        time; 0 writes none.
    """
    sp, cfg = load_params(params)
    return _replay([inputs], [""], [make_tool(cfg)], sp, cfg, params, writer, grid_rate_hz)[0]


def hands_of(params=DEFAULT_PARAMS) -> tuple[str, ...]:
    """The hands of a node with parameter file ``params``: ``(hand_ns,)``, or ``(hand_ns, second_hand_ns)`` (issue 32).

    Parameters
    ----------
    params : path
        Node parameter file.

    Returns
    -------
    tuple of str
        Each hand's namespace ('' : the single-tool topic names).
    """
    node_params, _ = configure(load_yaml(params))
    return (node_params.hand_ns,) + ((node_params.second_hand_ns,) if node_params.second_hand_ns else ())


def hand_configs(params=DEFAULT_PARAMS) -> list[TissueConfig]:
    """Each hand's tool configuration of a parameter file, as the node builds them (:func:`skin_sim_node.configure.hand_configs`):
    the tissue with ``tissue.tool.*``, and with a second hand the same tissue with ``second_tool_shape`` and
    ``second_tool_radius_m``.

    Parameters
    ----------
    params : path
        Node parameter file.

    Returns
    -------
    list of TissueConfig
    """
    flat = load_yaml(params)
    return configure_hands(flat, configure(flat)[1])


def replay_hands(
    inputs: Sequence[Inputs], params=DEFAULT_PARAMS, writer: BagWriter | None = None, grid_rate_hz: float = 60.0
) -> list[ReplayResult]:
    """Run the parameter file's hands (:func:`hands_of`) over their inputs on one tissue; write outputs to ``writer``.

    Every hand's poses and twists are taken in stamp order across the hands, each to its hand's session (the tools of
    :func:`skin_sim_node.tools.make_tools`, one tissue), as the node takes them in the order they arrive; at equal
    stamps the first hand goes first, and a twist before the pose of its hand with the same stamp. Each hand's answers
    go to its own topics (``<hand_ns>/tool/wrench``, ``<hand_ns>/tissue/contact``), the grids of the one tissue (every
    tool's field) to ``tissue/height_map`` and ``tissue/layer_heights``.

    Parameters
    ----------
    inputs : sequence of Inputs
        Each hand's inputs, in the order of :func:`hands_of`.
    params : path
        Node parameter file with the hands (``hand_ns``, ``second_hand_ns``, ``second_tool_*``).
    writer : BagWriter, optional
    grid_rate_hz : float
        Display grids per second of stamp time; 0 writes none.

    Returns
    -------
    list of ReplayResult
        One per hand, in the order of :func:`hands_of`.
    """
    hands = hands_of(params)
    if len(inputs) != len(hands):
        raise ValueError(f"{len(inputs)} hands' inputs for the {len(hands)} hands of {params}")
    sp, cfg = load_params(params)
    return _replay(list(inputs), list(hands), make_tools(hand_configs(params)), sp, cfg, params, writer, grid_rate_hz)


def merged_events(inputs: Sequence[Inputs]) -> list[tuple]:
    """Every hand's events in the order the replay takes them: ``(stamp_ns, hand index, rank, frame, xyz, quat)``.

    Stamp order across the hands; at equal stamps the first hand first, and within a hand a twist before the pose with
    the same stamp. The offline replay (:func:`replay_hands`) and the live replay's publisher
    (:mod:`skin_sim_node.bags.live_source`) take this one order. One hand's events are in (stamp, rank) order already.
    """
    events = [(e[0], i, *e[1:]) for i, inp in enumerate(inputs) for e in inp.events]
    if len(inputs) > 1:
        events.sort(key=lambda e: (e[0], e[1], e[2]))
    return events


@dataclass
class _HandRun:
    """One hand's session and what it answered, in an offline replay."""

    ns: str
    session: HapticSession
    throttle: AnswerThrottle | None
    wrench_topic: str
    contact_topic: str
    prev: int | None = None
    stamps: list = field(default_factory=list)
    forces: list = field(default_factory=list)
    vectors: list = field(default_factory=list)
    n_aff: list = field(default_factory=list)
    depths: list = field(default_factory=list)
    xyzs: list = field(default_factory=list)
    peak_f: float = -1.0
    peak_i: int = 0
    peak_state: dict | None = None


def _replay(inputs, hands, tool_list, sp, cfg, params, writer, grid_rate_hz) -> list[ReplayResult]:
    """The replay core: ``tool_list[i]`` answers ``inputs[i]`` under namespace ``hands[i]``, all in stamp order."""
    frame = sp.tissue_frame
    runs = [
        _HandRun(
            ns,
            HapticSession(tool, sp),
            answer_throttle(params),
            "/" + hand_topic("tool_wrench", ns),
            "/" + hand_topic("contact", ns),
        )
        for ns, tool in zip(hands, tool_list)
    ]
    shared = tool_list[0].skin if len(tool_list) > 1 else None  # the one tissue under several tools (SharedSkin)
    out = _Out()
    grid_ns = int(round(1e9 / grid_rate_hz)) if grid_rate_hz > 0 else 0
    next_grid = None
    n_grids = 0
    wq, cq = qos_profiles("tool_wrench"), qos_profiles("contact")
    for stamp, hand, rank, fr, xyz, quat in merged_events(inputs):
        h = runs[hand]
        session = h.session
        if rank != POSE:
            session.on_twist(stamp, fr, xyz)
            continue
        if session.on_pose(stamp, fr, xyz, quat=quat) is not None:
            continue
        if h.throttle is not None and not h.throttle.due(stamp):
            continue  # as the node: kept, and the next answered pose steps the model over both stamps
        r = session.tick(stamp, 0 if h.prev is None else stamp - h.prev)
        h.prev = stamp
        force = math.hypot(*r.force_n)
        h.stamps.append(stamp)
        h.forces.append(force)
        h.vectors.append(r.force_n)
        h.n_aff.append(r.n_affected)
        h.depths.append(r.depth_m)
        h.xyzs.append(r.x0_m)
        if force > h.peak_f:
            h.peak_f, h.peak_i = force, len(h.forces) - 1
            h.peak_state = session.state()
        if writer is None:
            continue
        writer.write(h.wrench_topic, TOPICS["tool_wrench"].type, stamp, cv.fill_wrench_from_tick(out.wrench, r, stamp, frame), wq)
        msg = cv.fill_contact_from_tick(out.contact, r, stamp, frame)
        msg.position, msg.velocity, msg.effort = (
            np.asarray(a, dtype=np.float64) for a in (msg.position, msg.velocity, msg.effort)
        )
        writer.write(h.contact_topic, TOPICS["contact"].type, stamp, msg, cq)
        if grid_ns:
            if next_grid is None:
                next_grid = stamp
            if stamp >= next_grid:
                heights = shared.heights_m() if shared is not None else session.build_grid().heights_m
                _write_image(writer, out, "height_map", stamp, frame, heights[0])
                _write_image(writer, out, "layer_heights", stamp, frame, np.moveaxis(heights, 0, -1))
                n_grids += 1
                next_grid += grid_ns * ((stamp - next_grid) // grid_ns + 1)
    return [
        ReplayResult(
            np.array(h.stamps, dtype=np.int64),
            np.array(h.forces),
            np.array(h.n_aff, dtype=int),
            np.array(h.depths),
            np.array(h.xyzs).reshape(-1, 3),
            dict(h.session.counts),
            inp.n_poses,
            inp.n_twists,
            n_grids,
            h.peak_i,
            h.peak_state,
            h.session.tool.cfg,
            tuple(LAYER_NAMES),
            frame,
            np.array(h.vectors, dtype=float).reshape(-1, 3),
            h.ns,
        )
        for h, inp in zip(runs, inputs)
    ]


def replay_hands_to_bag(
    inputs: Sequence[Inputs],
    out_bag: Path,
    params=DEFAULT_PARAMS,
    storage: str = "mcap",
    grid_rate_hz: float = 60.0,
    compress: bool = False,
) -> list[ReplayResult]:
    """:func:`replay_hands` writing a new output bag at ``out_bag`` (replaced if it is a bag)."""
    custom = {
        "skin_sim.source": str(inputs[0].bag.name),
        "skin_sim.params": Path(params).name,
        "skin_sim.grid_rate_hz": f"{grid_rate_hz:g}",
        "skin_sim.hands": ",".join(hands_of(params)),
    }
    with BagWriter(out_bag, storage, compress=compress, custom_data=custom, overwrite=True) as w:
        return replay_hands(inputs, params, w, grid_rate_hz)


def replay_to_bag(
    inputs: Inputs,
    out_bag: Path,
    params=DEFAULT_PARAMS,
    storage: str = "mcap",
    grid_rate_hz: float = 60.0,
    compress: bool = False,
) -> ReplayResult:
    """:func:`replay` writing a new output bag at ``out_bag`` (replaced if it is a bag)."""
    custom = {
        "skin_sim.source": str(inputs.bag.name),
        "skin_sim.params": Path(params).name,
        "skin_sim.grid_rate_hz": f"{grid_rate_hz:g}",
    }
    with BagWriter(out_bag, storage, compress=compress, custom_data=custom, overwrite=True) as w:
        return replay(inputs, params, w, grid_rate_hz)
