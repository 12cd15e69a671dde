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
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from msgs_schema import convert as cv
from msgs_schema.parameters import session_params
from msgs_schema.tissue import LAYER_NAMES
from msgs_schema.topics import TOPICS

from .. import tools
from ..configure import configure
from ..model import SkinModel, TissueConfig
from ..model.config import load_yaml
from ..rate import AnswerThrottle
from ..scenes import DEFAULT_PARAMS
from ..session import HapticSession
from ..tools import make_tool
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
    """Run the model over ``inputs``; write outputs to ``writer`` if given.

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
    session = HapticSession(make_tool(cfg), sp)
    throttle = answer_throttle(params)
    frame = sp.tissue_frame
    out = _Out()
    grid_ns = int(round(1e9 / grid_rate_hz)) if grid_rate_hz > 0 else 0
    next_grid = None
    stamps, forces, vectors, n_aff, depths, xyzs = [], [], [], [], [], []
    peak_f, peak_i, peak_state = -1.0, 0, None
    prev = None
    n_grids = 0
    wq, cq = qos_profiles("tool_wrench"), qos_profiles("contact")
    for stamp, rank, fr, xyz, quat in inputs.events:
        if rank != POSE:
            session.on_twist(stamp, fr, xyz)
            continue
        if session.on_pose(stamp, fr, xyz, quat=quat) is not None:
            continue
        if throttle is not None and not throttle.due(stamp):
            continue  # as the node: kept, and the next answered pose steps the model over both stamps
        r = session.tick(stamp, 0 if prev is None else stamp - prev)
        prev = stamp
        force = math.hypot(*r.force_n)
        stamps.append(stamp)
        forces.append(force)
        vectors.append(r.force_n)
        n_aff.append(r.n_affected)
        depths.append(r.depth_m)
        xyzs.append(r.x0_m)
        if force > peak_f:
            peak_f, peak_i = force, len(forces) - 1
            peak_state = session.state()
        if writer is None:
            continue
        writer.write(
            bag_topic("tool_wrench"), TOPICS["tool_wrench"].type, stamp, cv.fill_wrench_from_tick(out.wrench, r, stamp, frame), wq
        )
        msg = cv.fill_contact_from_tick(out.contact, r, stamp, frame)
        msg.position, msg.velocity, msg.effort = (
            np.asarray(a, dtype=np.float64) for a in (msg.position, msg.velocity, msg.effort)
        )
        writer.write(bag_topic("contact"), TOPICS["contact"].type, stamp, msg, cq)
        if grid_ns:
            if next_grid is None:
                next_grid = stamp
            if stamp >= next_grid:
                g = session.build_grid()
                _write_image(writer, out, "height_map", stamp, frame, g.heights_m[0])
                _write_image(writer, out, "layer_heights", stamp, frame, np.moveaxis(g.heights_m, 0, -1))
                n_grids += 1
                next_grid += grid_ns * ((stamp - next_grid) // grid_ns + 1)
    return ReplayResult(
        np.array(stamps, dtype=np.int64),
        np.array(forces),
        np.array(n_aff, dtype=int),
        np.array(depths),
        np.array(xyzs).reshape(-1, 3),
        dict(session.counts),
        inputs.n_poses,
        inputs.n_twists,
        n_grids,
        peak_i,
        peak_state,
        cfg,
        tuple(LAYER_NAMES),
        frame,
        np.array(vectors, dtype=float).reshape(-1, 3),
    )


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
