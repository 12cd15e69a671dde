"""The view's HTTP + WebSocket server (standard library): static page, frame broadcast, small JSON API.

Routes: ``GET /`` the page, ``GET /static/...`` its files (three.js vendored), ``GET /ws`` the frame
stream, ``GET /api/params`` the node's tunable parameters, ``POST /api/param`` set one
(``{"name", "value"}``: the node's answer, with its rejection reason), ``POST /api/seek`` and
``POST /api/play`` (bag timeline), ``GET /api/state`` the newest frame header (tests, benchmark).

Each page connection has its own sender thread with a newest-only slot for frames: a slow
browser drops frames, it never blocks the source loop (which never blocks the node anyway,
being another process).
"""

from __future__ import annotations

import json
import mimetypes
import threading
from http.server import BaseHTTPRequestHandler, ThreadingHTTPServer
from pathlib import Path

from .ws import WebSocket, WebSocketClosedError, accept_key

STATIC = Path(__file__).resolve().parent / "static"


class _Client:
    """One page connection: newest binary frame plus a queue of text messages, sent by its own thread."""

    def __init__(self, ws: WebSocket):
        self.ws = ws
        self.cond = threading.Condition()
        self.frame: bytes | None = None
        self.texts: list[str] = []
        self.alive = True
        self.sent = 0
        self.dropped = 0

    def put_frame(self, data: bytes) -> None:
        with self.cond:
            self.dropped += self.frame is not None
            self.frame = data
            self.cond.notify()

    def put_text(self, text: str) -> None:
        with self.cond:
            self.texts.append(text)
            self.cond.notify()

    def run(self) -> None:
        try:
            while self.alive:
                with self.cond:
                    while self.alive and self.frame is None and not self.texts:
                        self.cond.wait(0.5)
                    texts, self.texts = self.texts, []
                    frame, self.frame = self.frame, None
                for t in texts:
                    self.ws.send(t)
                if frame is not None:
                    self.ws.send(frame)
                    self.sent += 1
        except WebSocketClosedError:
            pass
        finally:
            self.alive = False

    def stop(self) -> None:
        with self.cond:
            self.alive = False
            self.cond.notify()


class ViewServer:
    """Serves the page and broadcasts frames; ``source`` answers the parameter and timeline calls.

    ``source`` provides ``hello() -> list[str]`` (text messages for a new page), ``resend()`` (put the grid in
    the next frame), ``params() -> dict``,
    ``set_param(name, text) -> dict`` and, for bags, ``seek(t_s)`` and ``play(on)``.
    """

    def __init__(self, source, host: str = "127.0.0.1", port: int = 8642):
        self.source = source
        self.clients: list[_Client] = []
        self._lock = threading.Lock()
        self.last_header: dict = {}
        view = self

        class Handler(BaseHTTPRequestHandler):
            protocol_version = "HTTP/1.1"

            def log_message(self, *_args):  # quiet: the view prints its own status lines
                pass

            def _json(self, obj, code: int = 200) -> None:
                body = json.dumps(obj).encode()
                self.send_response(code)
                self.send_header("Content-Type", "application/json")
                self.send_header("Content-Length", str(len(body)))
                self.send_header("Cache-Control", "no-store")
                self.end_headers()
                self.wfile.write(body)

            def do_GET(self):
                path = self.path.split("?", 1)[0]
                if path == "/ws":
                    return view._upgrade(self)
                if path == "/api/params":
                    return self._json(view.source.params())
                if path == "/api/state":
                    return self._json(view.last_header)
                if path == "/":
                    path = "/static/index.html"
                if not path.startswith("/static/"):
                    return self._json({"error": f"no such path {path}"}, 404)
                f = (STATIC / path[len("/static/") :]).resolve()
                if STATIC not in f.parents or not f.is_file():
                    return self._json({"error": f"no such file {path}"}, 404)
                body = f.read_bytes()
                ctype = "text/javascript" if f.suffix == ".js" else mimetypes.guess_type(f.name)[0] or "text/plain"
                self.send_response(200)
                self.send_header("Content-Type", ctype)
                self.send_header("Content-Length", str(len(body)))
                self.end_headers()
                self.wfile.write(body)

            def do_POST(self):
                n = int(self.headers.get("Content-Length") or 0)
                try:
                    req = json.loads(self.rfile.read(n) or b"{}")
                except json.JSONDecodeError as exc:
                    return self._json({"ok": False, "reason": f"bad JSON: {exc}"}, 400)
                if self.path == "/api/param":
                    return self._json(view.source.set_param(str(req.get("name", "")), str(req.get("value", ""))))
                if self.path == "/api/seek" and hasattr(view.source, "seek"):
                    return self._json(view.source.seek(float(req.get("t_s", 0.0))))
                if self.path == "/api/play" and hasattr(view.source, "play"):
                    return self._json(view.source.play(bool(req.get("on", True))))
                return self._json({"ok": False, "reason": f"no such call {self.path}"}, 404)

        self.httpd = ThreadingHTTPServer((host, port), Handler)
        self.httpd.daemon_threads = True
        self.port = self.httpd.server_address[1]
        self.url = f"http://{host}:{self.port}/"
        self._thread = threading.Thread(target=self.httpd.serve_forever, name="view-http", daemon=True)

    def start(self) -> ViewServer:
        self._thread.start()
        return self

    def _upgrade(self, h: BaseHTTPRequestHandler) -> None:
        key = h.headers.get("Sec-WebSocket-Key")
        if not key or "websocket" not in h.headers.get("Upgrade", "").lower():
            h.send_response(400)
            h.send_header("Content-Length", "0")
            h.end_headers()
            return
        h.send_response(101)
        h.send_header("Upgrade", "websocket")
        h.send_header("Connection", "Upgrade")
        h.send_header("Sec-WebSocket-Accept", accept_key(key))
        h.end_headers()
        h.wfile.flush()
        client = _Client(WebSocket(h.connection, client=False))
        for text in self.source.hello():
            client.put_text(text)
        with self._lock:
            self.clients.append(client)
        self.source.resend()  # after registering: the next frame carries the grid, and this page gets it
        sender = threading.Thread(target=client.run, name="view-ws-send", daemon=True)
        sender.start()
        try:
            while client.alive:  # read until the page goes away (it sends nothing else)
                client.ws.recv()
        except (WebSocketClosedError, OSError):
            pass
        finally:
            client.stop()
            with self._lock:
                self.clients.remove(client)
            h.close_connection = True

    @property
    def n_clients(self) -> int:
        with self._lock:
            return len(self.clients)

    def broadcast_frame(self, header: dict, data: bytes) -> None:
        self.last_header = header
        with self._lock:
            clients = list(self.clients)
        for c in clients:
            c.put_frame(data)

    def broadcast_text(self, obj: dict) -> None:
        text = json.dumps(obj)
        with self._lock:
            clients = list(self.clients)
        for c in clients:
            c.put_text(text)

    def close(self) -> None:
        with self._lock:
            clients = list(self.clients)
        for c in clients:
            c.stop()
            c.ws.close()
        self.httpd.shutdown()
        self.httpd.server_close()
