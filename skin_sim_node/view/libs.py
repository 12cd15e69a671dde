"""``skin-sim view --compare-libs``: the measurement behind the view's library choice (docs/view.md).

Each candidate pushes the same deforming 120 x 120 grid (the node's ``grid.nx`` x ``grid.ny``;
14 400 vertices, 28 322 triangles) from its own Python process, in a worker started with the
candidate installed in ``--lib-dir/NAME`` (``pip install --target DIR/NAME NAME``), while a client
is connected: headless Chromium on the candidate's own offline page (own, viser, rerun), or for
foxglove-sdk, whose viewer is not in the wheel, a protocol client that subscribes the channel.
Two runs per candidate: at the view's 30 Hz (server and browser CPU, % of one core) and flat out
(the highest push rate). Install size: what the candidate adds on top of this project's
environment (packages already in the venv are not counted).
"""

from __future__ import annotations

import argparse
import json
import os
import subprocess
import sys
import time
from pathlib import Path
from typing import TYPE_CHECKING, Any

import numpy as np

if TYPE_CHECKING:
    from .browser import Browser
    from .ws import WebSocket

N = 120  # grid.nx = grid.ny default (msgs_schema/tissue.py)
SHEET_MM = 120.0
LIBS = ("own", "own-py", "viser", "rerun-sdk", "foxglove-sdk")
"""``own-py``: the own server with a Python WebSocket client instead of the page (transport capacity, no rendering)."""


def grid_mesh(n: int = N):
    """Vertices (n*n, 3) in mm of the rest sheet and triangle indices (2 (n-1)^2, 3)."""
    xs = (np.arange(n) + 0.5) * SHEET_MM / n - SHEET_MM / 2
    X, Y = np.meshgrid(xs, xs)
    verts = np.stack([X.ravel(), Y.ravel(), np.zeros(n * n)], axis=1).astype(np.float32)
    a = (np.arange(n - 1)[:, None] * n + np.arange(n - 1)[None, :]).ravel()
    faces = np.concatenate([np.stack([a, a + 1, a + n + 1], 1), np.stack([a, a + n + 1, a + n], 1)]).astype(np.uint32)
    return verts, faces


def deform(verts: np.ndarray, t: float) -> np.ndarray:
    """A moving Gaussian dent (3 mm deep, 10 mm wide): every vertex changes every frame."""
    v = verts.copy()
    cx = 20.0 * np.sin(t)
    v[:, 2] = -3.0 * np.exp(-((v[:, 0] - cx) ** 2 + v[:, 1] ** 2) / 100.0)
    return v


class _Stub:
    """The minimal source the own server needs for this measurement (no ROS): sheet info only."""

    def hello(self):
        return [
            json.dumps(
                {
                    "type": "info",
                    "mode": "live",
                    "namespace": "bench",
                    "sheet_m": [0.12, 0.12],
                    "tool_radius_m": 0.0025,
                    "rate_hz": 30,
                }
            )
        ]

    def resend(self):
        pass

    def params(self):
        return {"ok": False, "reason": "library benchmark", "params": []}

    def set_param(self, name, text):
        return self.params()


def _worker(lib: str, port: int, rate_hz: float, duration_s: float) -> None:  # pragma: no cover - subprocess
    verts, faces = grid_mesh()
    if lib == "own":
        from .frames import encode_frame
        from .server import ViewServer

        srv = ViewServer(_Stub(), "127.0.0.1", port).start()
        url = srv.url

        def push(v, i):
            grid = np.repeat((v[:, 2] * 1e-3).reshape(N, N, 1), 3, axis=2) - np.array([0, 1e-4, 2e-3], dtype=np.float32)
            srv.broadcast_frame({}, encode_frame({"seq": i, "force": [0, 0, 0.1]}, grid))

        def ready():
            return srv.n_clients > 0
    elif lib == "viser":
        import viser

        srv = viser.ViserServer(host="127.0.0.1", port=port, verbose=False)
        handles = [srv.scene.add_mesh_simple(f"/layer{k}", verts, faces) for k in range(3)]
        url = f"http://127.0.0.1:{port}/"

        def push(v, i):
            for k, h in enumerate(handles):
                h.vertices = v - np.array([0, 0, k], dtype=np.float32)

        def ready():
            return len(srv.get_clients()) > 0
    elif lib == "rerun-sdk":
        import rerun as rr

        rr.init("skin_sim_view_bench")
        uri = rr.serve_grpc(grpc_port=port + 1)
        rr.serve_web_viewer(web_port=port, open_browser=False, connect_to=uri)
        url = f"http://127.0.0.1:{port}/?url={uri}"
        for k in range(3):
            rr.log(f"layer{k}", rr.Mesh3D(vertex_positions=verts, triangle_indices=faces), static=False)

        def push(v, i):
            rr.set_time("frame", sequence=i)
            for k in range(3):
                rr.log(f"layer{k}", rr.Mesh3D(vertex_positions=v - np.array([0, 0, k], dtype=np.float32), triangle_indices=faces))

        def ready():
            return True
    else:  # foxglove-sdk
        import foxglove
        from foxglove.channels import SceneUpdateChannel
        from foxglove.schemas import Point3, SceneEntity, SceneUpdate, TriangleListPrimitive

        state = {"subs": 0}

        listener_base: Any = foxglove.ServerListener if hasattr(foxglove, "ServerListener") else object

        class Listener(listener_base):
            def on_subscribe(self, client, channel):
                state["subs"] += 1

        server = foxglove.start_server(host="127.0.0.1", port=port, server_listener=Listener())
        chan = SceneUpdateChannel("/tissue")
        url = f"ws://127.0.0.1:{port}"
        idx = faces.ravel().tolist()

        def push(v, i):
            ents = []
            for k in range(3):
                pts = [Point3(x=float(a), y=float(b), z=float(c) - k) for a, b, c in v.tolist()]
                tri = TriangleListPrimitive(points=pts, indices=idx)
                ents.append(SceneEntity(id=f"layer{k}", frame_id="tissue", triangles=[tri]))
            chan.log(SceneUpdate(entities=ents))

        def ready():
            return state["subs"] > 0

        _ = server
    print(f"URL {url}", flush=True)
    end = time.monotonic() + 120
    while not ready() and time.monotonic() < end:
        time.sleep(0.05)
    print("CLIENT", flush=True)
    time.sleep(2.0)  # the client loads the page and the first frames
    period = 1.0 / rate_hz if rate_hz > 0 else 0.0
    c0, t0, i = time.process_time(), time.monotonic(), 0
    nxt = t0
    while time.monotonic() - t0 < duration_s:
        push(deform(verts, time.monotonic()), i)
        i += 1
        if period:
            nxt += period
            time.sleep(max(0.0, nxt - time.monotonic()))
    wall = time.monotonic() - t0
    print("RESULT " + json.dumps({"frames_per_s": i / wall, "cpu_pct": 100 * (time.process_time() - c0) / wall}), flush=True)
    time.sleep(0.5)
    os._exit(0)  # some servers keep non-daemon threads


def _reader(ws, on_text=None) -> dict:
    """Count the bytes of binary messages on ``ws`` in a thread; text messages go to ``on_text``."""
    import threading

    stats = {"bytes": 0, "msgs": 0}

    def run():
        try:
            while True:
                m = ws.recv()
                if isinstance(m, str) and on_text is not None:
                    on_text(m)
                else:
                    stats["bytes"] += len(m)
                    stats["msgs"] += 1
        except Exception:
            pass

    threading.Thread(target=run, daemon=True).start()
    return stats


def _count_client(url: str) -> tuple[WebSocket, dict]:
    """Read the own server's stream with :mod:`.ws` and count bytes (no rendering)."""
    from .ws import connect

    c = connect(url.replace("http://", "ws://") + "ws")
    return c, _reader(c)


def _foxglove_client(url: str) -> tuple[WebSocket, dict]:
    """Subscribe every advertised channel (Foxglove WebSocket protocol), as a viewer would."""
    import base64
    import socket
    from urllib.parse import urlparse

    from .ws import WebSocket

    u = urlparse(url)
    assert u.port is not None  # the worker prints ws://127.0.0.1:PORT
    sock = socket.create_connection((u.hostname, u.port), timeout=10)
    key = base64.b64encode(os.urandom(16)).decode()
    sock.sendall(
        (
            f"GET / HTTP/1.1\r\nHost: {u.hostname}:{u.port}\r\nUpgrade: websocket\r\nConnection: Upgrade\r\n"
            f"Sec-WebSocket-Key: {key}\r\nSec-WebSocket-Version: 13\r\n"
            f"Sec-WebSocket-Protocol: foxglove.sdk.v1, foxglove.websocket.v1\r\n\r\n"
        ).encode()
    )
    buf = b""
    while b"\r\n\r\n" not in buf:
        buf += sock.recv(4096)
    _, _, rest = buf.partition(b"\r\n\r\n")
    sock.settimeout(None)
    ws = WebSocket(sock, client=True, leftover=rest)

    def on_text(m: str) -> None:
        obj = json.loads(m)
        if obj.get("op") == "advertise":
            subs = [{"id": c["id"], "channelId": c["id"]} for c in obj["channels"]]
            ws.send(json.dumps({"op": "subscribe", "subscriptions": subs}))

    return ws, _reader(ws, on_text)


def measure(lib: str, lib_dir: Path, rate_hz: float, duration_s: float, port: int) -> dict:
    from .bench import _cpu_s
    from .browser import Browser

    env = dict(os.environ)
    worker = "own" if lib == "own-py" else lib
    if worker != "own":
        env["PYTHONPATH"] = str(lib_dir / lib) + os.pathsep + env.get("PYTHONPATH", "")
    code = f"from skin_sim_node.view.libs import _worker; _worker({worker!r}, {port}, {rate_hz}, {duration_s})"
    proc = subprocess.Popen([sys.executable, "-c", code], stdout=subprocess.PIPE, stderr=subprocess.STDOUT, text=True, env=env)
    client: Browser | tuple[WebSocket, dict] | None = None  # a page, or a WebSocket reader and its byte counts
    out = {"lib": lib, "target_hz": rate_hz}
    assert proc.stdout is not None  # started with stdout=PIPE
    try:
        lines = []
        for line in proc.stdout:
            lines.append(line)
            if line.startswith("URL "):
                url = line.split()[1]
                if lib == "foxglove-sdk":
                    client = _foxglove_client(url)
                elif lib == "own-py":
                    client = _count_client(url)
                else:
                    client = Browser(url)
            elif line.startswith("CLIENT"):
                time.sleep(2.0)
                pids = client.pids if isinstance(client, Browser) else []
                b0, t0 = _cpu_s(pids), time.monotonic()
                window = duration_s - 1.0
                if isinstance(client, Browser):
                    out["client_bytes_per_s"] = client.network_bytes(window) / window
                else:
                    assert client is not None  # made at the URL line, which comes first
                    n0 = client[1]["bytes"]
                    time.sleep(window)
                    out["client_bytes_per_s"] = (client[1]["bytes"] - n0) / window
            elif line.startswith("RESULT "):
                out.update(json.loads(line[7:]))
                out["client_cpu_pct"] = 100 * (_cpu_s(pids) - b0) / (time.monotonic() - t0) if pids else float("nan")
                break
        else:
            out["error"] = "".join(lines[-15:])
    finally:
        if isinstance(client, Browser):
            client.close()
        elif client is not None:
            client[0].close()
        proc.wait(timeout=30)
    return out


def install_size_mb(lib_dir: Path, lib: str) -> float:
    """MB the candidate adds: its --target folder minus distributions already in this interpreter."""
    from importlib import metadata

    have = {d.metadata["Name"].lower().replace("_", "-") for d in metadata.distributions()}
    root = lib_dir / lib
    total = 0
    for info in root.glob("*.dist-info"):
        name = info.name.rsplit("-", 1)[0].lower().replace("_", "-")
        if name in have:
            continue
        for line in (info / "RECORD").read_text().splitlines():
            f = root / line.split(",")[0]
            if f.is_file():
                total += f.stat().st_size
    return total / 1e6


def own_size_mb() -> float:
    here = Path(__file__).resolve().parent
    return sum(f.stat().st_size for f in here.rglob("*") if f.is_file() and "__pycache__" not in f.parts) / 1e6


def format_row(row: dict) -> str:
    a, m = row["at30"], row["max"]

    def g(d, k):
        return d.get(k, float("nan"))

    text = (
        f"{row['lib']:13s} install +{row['install_mb']:7.1f} MB | at 30 Hz: server CPU {g(a, 'cpu_pct'):5.1f} %, "
        f"client CPU {g(a, 'client_cpu_pct'):5.1f} %, {row['bytes_per_update'] / 1e3:5.0f} kB/update, "
        f"{g(a, 'delivered_per_s'):5.1f} updates/s delivered | flat out: {g(m, 'delivered_per_s'):5.1f} updates/s "
        f"delivered (pushed {g(m, 'frames_per_s'):5.0f}/s) at server CPU {g(m, 'cpu_pct'):5.1f} %"
    )
    err = a.get("error") or m.get("error")
    return text + (f" | error: {err}" if err else "")


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(prog="skin-sim view --compare-libs", description=__doc__.splitlines()[0])
    ap.add_argument(
        "--lib-dir",
        type=Path,
        default=Path("out/view_libs"),
        help="folder with one `pip install --target DIR/NAME NAME` per candidate",
    )
    ap.add_argument("--duration-s", type=float, default=8.0)
    ap.add_argument("--libs", nargs="*", default=list(LIBS))
    ap.add_argument("--out", type=Path, default=Path("out/view_libs/compare.json"))
    args = ap.parse_args(argv)
    print(
        f"skin-sim view --compare-libs: {', '.join(args.libs)}; 120 x 120 grid, 3 layers; {args.duration_s:.0f} s per run",
        flush=True,
    )
    rows = []
    for k, lib in enumerate(args.libs):
        if not lib.startswith("own") and not (args.lib_dir / lib).is_dir():
            print(f"  {lib}: not installed in {args.lib_dir / lib} (pip install --target {args.lib_dir / lib} {lib}); skipped")
            continue
        size = own_size_mb() if lib.startswith("own") else install_size_mb(args.lib_dir, lib)
        at30 = measure(lib, args.lib_dir, 30.0, args.duration_s, 18700 + 10 * k)
        flat = measure(lib, args.lib_dir, 0.0, args.duration_s, 18705 + 10 * k)
        # delivered updates/s = bytes into the client per second / bytes of one update (measured at 30 Hz, where the
        # server pushes every frame; the own server's newest-only slot may drop some, so its known size is used)
        per_update = at30.get("client_bytes_per_s", float("nan")) / at30.get("frames_per_s", float("nan"))
        if lib.startswith("own"):
            per_update = N * N * 3 * 4 + 100  # float32 layer heights + header (frames.py)
        at30["delivered_per_s"] = at30.get("client_bytes_per_s", float("nan")) / per_update if per_update else float("nan")
        flat["delivered_per_s"] = flat.get("client_bytes_per_s", float("nan")) / per_update if per_update else float("nan")
        row = {"lib": lib, "install_mb": size, "at30": at30, "max": flat, "bytes_per_update": per_update}
        rows.append(row)
        print("  " + format_row(row), flush=True)
    args.out.parent.mkdir(parents=True, exist_ok=True)
    args.out.write_text(json.dumps(rows, indent=1))
    print(f"written {args.out}")
    return 0
