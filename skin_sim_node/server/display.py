"""Display worker: builds and publishes the height maps and the mesh in its own process.

The haptic process only copies the modal state (a few kB per hand) into shared memory at display
rate; this process rebuilds the grid from it (with two hands, the sum of each tool's field: one tissue,
:mod:`skin_sim_node.tools.hands`) and publishes ``tissue/height_map``,
``tissue/layer_heights`` and ``tissue/mesh``. Measured on 2 cores: with the display in the
haptic process, its large publishes and the per-vertex Python work of the mesh held the
GIL long enough to make 5-10 % of 1 kHz ticks late; in its own process they cost nothing.

Shared state is a seqlock: the writer makes ``seq`` odd, writes, makes it even; the reader
retries until it reads the same even ``seq`` before and after copying.
"""

from __future__ import annotations

import math
import multiprocessing as mp
import os
import time
from multiprocessing import shared_memory

import numpy as np

from msgs_schema.tissue import LAYER_NAMES

from ..model import SkinModel, TissueConfig
from ..model.grid import assemble_heights
from ..model.skin_model import Grid
from ..tools import tissue

MAX_LAYERS = len(LAYER_NAMES)
MAX_MODES = 31 * 31  # odd-odd modes of the 61 x 61 parameter bound
_HEADER = 4  # int64: seq, n_layers, n_modes, config version


class SnapshotBuffer:
    """Shared-memory snapshot of ``q`` (L, K), patch ``centre`` (L, 2), and per layer driven, mode level, active."""

    def __init__(self, name: str | None = None):
        size = 8 * (_HEADER + MAX_LAYERS * MAX_MODES + MAX_LAYERS * 2 + 3 * MAX_LAYERS)
        self.shm = shared_memory.SharedMemory(name=name, create=name is None, size=size)
        buf = self.shm.buf
        self.header = np.ndarray((_HEADER,), dtype=np.int64, buffer=buf)
        off = 8 * _HEADER
        self.q = np.ndarray((MAX_LAYERS * MAX_MODES,), dtype=np.float64, buffer=buf, offset=off)
        off += 8 * MAX_LAYERS * MAX_MODES
        self.centre = np.ndarray((MAX_LAYERS * 2,), dtype=np.float64, buffer=buf, offset=off)
        off += 8 * MAX_LAYERS * 2
        self.driven = np.ndarray((MAX_LAYERS,), dtype=np.float64, buffer=buf, offset=off)
        off += 8 * MAX_LAYERS
        self.level = np.ndarray((MAX_LAYERS,), dtype=np.float64, buffer=buf, offset=off)
        off += 8 * MAX_LAYERS
        self.active = np.ndarray((MAX_LAYERS,), dtype=np.float64, buffer=buf, offset=off)
        if name is None:
            self.header[:] = 0

    def write(self, q, centre, driven, version: int, level=None, active=None) -> None:
        """Publish a snapshot (seqlock: the sequence is odd while writing); ``level``/``active`` default to -1 and 1."""
        n_l, k = q.shape
        self.header[0] += 1  # odd: writing
        self.q[: n_l * k] = q.ravel()
        self.centre[: n_l * 2] = centre.ravel()
        self.driven[:n_l] = driven
        self.level[:n_l] = -1 if level is None else level
        self.active[:n_l] = 1 if active is None else active
        self.header[1], self.header[2], self.header[3] = n_l, k, version
        self.header[0] += 1  # even: consistent

    def read(self, q_out: np.ndarray, centre_out: np.ndarray, level_out=None, active_out=None) -> tuple[int, int, bool]:
        """Copy a consistent snapshot; returns (seq, config version, any layer driven).

        ``level_out``/``active_out`` (optional) receive each layer's mode level and active flag.
        """
        for _ in range(100_000):  # a writer that died mid-write must not hang the reader
            s0 = int(self.header[0])
            if s0 % 2:
                time.sleep(1e-5)
                continue
            n_l, k, version = int(self.header[1]), int(self.header[2]), int(self.header[3])
            if q_out.shape == (n_l, k):
                q_out[...] = self.q[: n_l * k].reshape(n_l, k)
                centre_out[...] = self.centre[: n_l * 2].reshape(n_l, 2)
                if level_out is not None and self.level[0] >= 0:
                    level_out[...] = self.level[:n_l]
                if active_out is not None:
                    active_out[...] = self.active[:n_l]
            driven = bool(self.driven[:n_l].any())
            if int(self.header[0]) == s0:
                return s0, version, driven
        return -1, -1, False  # no consistent snapshot: the caller skips this frame

    def close(self, unlink: bool = False) -> None:
        """Drop the array views and close the shared memory; ``unlink``: the owner also removes it."""
        for name in ("header", "q", "centre", "driven", "level", "active"):
            setattr(self, name, None)
        self.shm.close()
        if unlink:
            self.shm.unlink()


def _moved(model: SkinModel, last_q, last_centre, last_active) -> bool:
    """Whether the grid would differ from the last build by more than ``lod.tolerance_m`` anywhere.

    ``sum |dq|`` bounds the change of a layer's field where its patch did not move (``|sin| <= 1``);
    a moved patch centre or a layer becoming active or inactive counts as a change.
    """
    if last_q is None or last_q.shape != model.q.shape:
        return True
    if np.any(model.active != last_active) or np.any((model.centre != last_centre).any(axis=1) & (model.active > 0)):
        return True
    return float(np.abs(model.q - last_q).sum()) > model.cfg.lod.tolerance_m


DISPLAY_NICE = 10
"""Niceness of every thread of the display worker process (CFS weight 110 against a default thread's 1024): on a
machine with fewer free cores than busy threads its grid builds and large publishes yield most of a contended CPU
to the haptic process (at most about a tenth goes to it). Not 19 (weight 15) nor ``SCHED_IDLE`` (as before): with
two busy processes beside the node (a browser and a build) those starved the view of every frame for 20-30 s.
Set after the worker's start-up, before rclpy starts, so its DDS threads inherit it."""


def lower_priority(nice: int = DISPLAY_NICE) -> int:
    """Raise the niceness of every thread of this process to ``nice`` (per thread on Linux: the BLAS threads
    that importing NumPy started already exist; threads started later inherit it). Returns the niceness."""
    try:
        tids = [int(t) for t in os.listdir("/proc/self/task")]
    except OSError:
        tids = [0]
    for tid in tids:
        try:
            os.setpriority(os.PRIO_PROCESS, tid, max(nice, os.getpriority(os.PRIO_PROCESS, tid)))
        except OSError:
            pass
    return os.getpriority(os.PRIO_PROCESS, 0)


def mesh_due(now_s: float, last_mesh_s: float, mesh_rate_hz: float, joined: bool) -> bool:
    """Whether the mesh goes out now: ``mesh_rate_hz`` by the clock from the newest grid, or at once for a reader
    that joined. A count of grid builds is no clock: builds happen only on change, so every n-th build gave ~1 mesh/s
    under a slow press instead of 5."""
    return mesh_rate_hz > 0 and (now_s - last_mesh_s >= 1.0 / mesh_rate_hz or joined)


def build_grid(models: list[SkinModel]) -> Grid:
    """The grid of one tissue pressed by each model's tool: one model's own, or the sum of every model's layer
    displacements (linear membranes, :mod:`skin_sim_node.tools.hands`) assembled into heights.

    Parameters
    ----------
    models : list of SkinModel
        Each hand's field (same sheet, grid and layers).

    Returns
    -------
    Grid
    """
    if len(models) == 1:
        return models[0].build_grid()
    grids = [m.build_grid() for m in models]
    disp = grids[0].displacement_m.copy()
    for g in grids[1:]:
        disp += g.displacement_m
    heights = np.empty_like(grids[0].heights_m)
    assemble_heights(disp, models[0]._rest_tops, heights)  # the rest heights every field shares
    return Grid(grids[0].xs_m, grids[0].ys_m, disp, heights)


def _worker(shm_names, cfgs, display, ros_args, namespace, conn, parent_pid):  # pragma: no cover - child process
    # start-up at normal priority: loading the numba kernels at niceness 19 beside a busy haptic process took the
    # worker over 15 s (no frame within the browser's and the tests' waits); the model and a first grid first
    models = [tissue(c) for c in cfgs]  # the configs the node validated and built, pressed as each tool presses it
    build_grid(models)
    lower_priority()  # then every thread, and all that rclpy and DDS start below, at DISPLAY_NICE
    import rclpy
    from geometry_msgs.msg import Point
    from sensor_msgs.msg import Image
    from std_msgs.msg import ColorRGBA
    from visualization_msgs.msg import Marker

    from msgs_schema import convert as cv
    from msgs_schema.qos import publisher
    from msgs_schema.topics import FRAMES

    rclpy.init(args=ros_args)
    node = rclpy.create_node("skin_sim_display", namespace=namespace)
    pubs = {k: publisher(node, k) for k in ("height_map", "layer_heights", "mesh")}
    image, layers_image, marker = Image(), Image(), Marker()
    snaps = [SnapshotBuffer(n) for n in shm_names]
    version = 0
    frame = FRAMES["tissue"]
    last_seq: tuple[int, ...] = ()
    last_pub, last_mesh = 0.0, -math.inf
    mesh_grid = None  # the newest grid not yet sent as a mesh (the mesh runs below the display rate)
    last: list[tuple | None] = [None] * len(models)  # each field's (q, centre, active) at the last build
    last_readers: dict[str, int] = {}
    try:
        while rclpy.ok() and os.getppid() == parent_pid:
            while conn.poll():
                msg = conn.recv()
                if msg is None:
                    return
                kind, payload = msg
                if kind == "tissue":
                    version, models = payload[0], [tissue(c) for c in payload[1]]
                    last = [None] * len(models)  # new rest heights: the next frame rebuilds
                    mesh_grid = None  # a pending mesh of the old tissue is not sent
                elif kind == "display":
                    display = payload
            period = 1.0 / display["display_rate_hz"] if display["display_rate_hz"] > 0 else 0.5
            t0 = time.monotonic()
            # lazy, as image_transport: no reader of any display topic, no grid built; a topic whose reader
            # count grew (a first or a further reader) gets a frame at once
            readers = {k: p.get_subscription_count() for k, p in pubs.items()}
            watched = {k: n > 0 for k, n in readers.items()}
            joined = {k for k, n in readers.items() if n > last_readers.get(k, 0)}
            last_readers = readers
            if display["display_rate_hz"] > 0 and any(watched.values()):
                reads = [sn.read(m.q, m.centre, m.level, m.active) for sn, m in zip(snaps, models)]
                seq = tuple(r[0] for r in reads)
                current = all(r[1] == version for r in reads)
                if joined:
                    build = current
                elif display.get("on_change", True):
                    # lod: rebuild only when a snapshot moved by more than the tolerance (or once a second)
                    moved = any(_moved(m, *(lst or (None, None, None))) for m, lst in zip(models, last))
                    build = current and ((seq != last_seq and moved) or t0 - last_pub > 1.0)
                else:
                    build = current
                if build:
                    last_seq, last_pub = seq, t0
                    last = [(m.q.copy(), m.centre.copy(), m.active.copy()) for m in models]
                    g = build_grid(models)
                    stamp = node.get_clock().now().nanoseconds
                    if watched["height_map"]:
                        pubs["height_map"].publish(cv.fill_image(image, stamp, frame, g.heights_m[0]))
                    if watched["layer_heights"]:
                        pubs["layer_heights"].publish(cv.fill_image(layers_image, stamp, frame, np.moveaxis(g.heights_m, 0, -1)))
                    mesh_grid = (g, stamp)
                # a grid that changed between two meshes is sent once the interval has passed: the last shape arrives
                due = mesh_due(t0, last_mesh, display["mesh_rate_hz"], "mesh" in joined)
                if mesh_grid is not None and display["publish_mesh"] and watched["mesh"] and due:
                    (g, stamp), mesh_grid, last_mesh = mesh_grid, None, t0
                    affected = g.displacement_m > 1e-6  # deeper than 1 um: visibly deformed
                    n_l = affected.shape[0]
                    deepest = np.where(affected.any(axis=0), n_l - 1 - np.argmax(affected[::-1], axis=0), -1)
                    verts, cols = cv.mesh_arrays(g.xs_m, g.ys_m, g.heights_m[0], deepest, display["mesh_stride"])
                    pubs["mesh"].publish(cv.fill_mesh_marker(marker, Point, ColorRGBA, stamp, frame, verts, cols))
            time.sleep(max(0.0, period - (time.monotonic() - t0)))
    except KeyboardInterrupt:
        pass
    finally:
        for sn in snaps:
            sn.close()
        node.destroy_node()
        rclpy.try_shutdown()


def restore_priority(pid: int) -> None:
    """Undo :func:`lower_priority` for every thread of process ``pid`` (``SCHED_OTHER``, niceness 0), best effort:
    lowering the niceness needs ``CAP_SYS_NICE`` (root); without it the worker keeps DISPLAY_NICE."""
    try:
        tids = [int(t) for t in os.listdir(f"/proc/{pid}/task")]
    except OSError:
        return
    for tid in tids:
        try:
            os.sched_setscheduler(tid, os.SCHED_OTHER, os.sched_param(0))
        except (OSError, AttributeError):
            pass
        try:
            os.setpriority(os.PRIO_PROCESS, tid, 0)
        except OSError:
            pass


CLOSE_WAIT_S = 0.5
"""How long the owner waits for the worker to leave on its own at shutdown before it kills it. A quiet worker
leaves within one display period (17 ms at 60 Hz); under load, at a raised niceness (:data:`DISPLAY_NICE`; it ran
SCHED_IDLE before), two busy processes starved it for seconds, which kept the node 5-30 s in its shutdown, past
the 5 s its launchers allowed. The worker holds nothing to save: it only publishes."""


class DisplayProcess:
    """Owner side: the shared snapshot, the pipe, and the worker process.

    Parameters
    ----------
    cfgs : list of TissueConfig
        The tissue the worker starts with, as each hand's tool presses it (pickled to it; it validates nothing).
    display : dict
        The display settings (``display_rate_hz``, ``mesh_rate_hz``, ``publish_mesh``, ``mesh_stride``, ``on_change``).
    ros_args : list of str
        The node's ROS arguments (without its ``__node:=`` remap).
    namespace : str
        The node's namespace.
    """

    def __init__(self, cfgs: list[TissueConfig], display: dict, ros_args: list[str], namespace: str):
        self.snaps = [SnapshotBuffer() for _ in cfgs]
        ctx = mp.get_context("spawn")  # never fork a process that runs DDS threads
        self._conn, child = ctx.Pipe()
        self.version = 0
        self.proc = ctx.Process(
            target=_worker,
            args=([sn.shm.name for sn in self.snaps], cfgs, display, ros_args, namespace, child, os.getpid()),
            name="skin_sim_display",
            daemon=True,
        )
        self.proc.start()

    def write(self, states: list[dict]) -> None:
        """Copy each hand's modal state (:meth:`HapticSession.display_state`) into shared memory."""
        for sn, st in zip(self.snaps, states):
            sn.write(st["q"], st["centre"], st["driven"], self.version, st["level"], st["active"])

    def set_tissue(self, cfgs: list[TissueConfig]) -> None:
        """Send the worker a new tissue: the configs the node validated and built, one per hand (no validation here).

        Parameters
        ----------
        cfgs : list of TissueConfig
        """
        self.version += 1
        self._conn.send(("tissue", (self.version, cfgs)))

    def set_display(self, display: dict) -> None:
        """Send the worker new display settings (the dict :class:`DisplayProcess` takes)."""
        self._conn.send(("display", display))

    def close(self) -> None:
        """Ask the worker to stop; kill it if it has not within :data:`CLOSE_WAIT_S` (the owner unlinks the memory)."""
        if self.proc.pid is not None:
            restore_priority(self.proc.pid)  # it must get a CPU to leave, even the kernel's exit path
        try:
            self._conn.send(None)
        except (BrokenPipeError, OSError):
            pass
        self.proc.join(timeout=CLOSE_WAIT_S)
        if self.proc.is_alive():
            self.proc.kill()  # SIGKILL: no handler to run
            self.proc.join(timeout=2.0)
        for sn in self.snaps:
            sn.close(unlink=True)
