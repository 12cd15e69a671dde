"""Headless Chromium driven over the Chrome DevTools Protocol (standard library plus :mod:`.ws`).

Used by the browser test, the benchmark (a real page connected while the node runs) and the demo's
screenshot. Debian's ``chromium`` package; no browser download. The flags keep it off the network
and out of the user's profile: a new empty ``--user-data-dir`` each time, no sync, no component
updates, no QUIC. ``--enable-unsafe-swiftshader`` lets WebGL run on the CPU under ``--disable-gpu``
(Chromium no longer falls back to SwiftShader by itself).
"""

from __future__ import annotations

import base64
import itertools
import json
import shutil
import subprocess
import tempfile
import time
import urllib.request
from pathlib import Path

from .ws import connect

FLAGS = (
    "--headless", "--no-sandbox", "--disable-gpu", "--enable-unsafe-swiftshader", "--disable-quic", "--no-first-run",
    "--disable-background-networking", "--disable-component-update", "--disable-sync", "--disable-extensions",
    "--disable-default-apps", "--mute-audio", "--remote-debugging-address=127.0.0.1", "--remote-debugging-port=0",
)  # fmt: skip
CANDIDATES = ("chromium", "chromium-browser", "google-chrome", "chrome")


def find_browser() -> str | None:
    """Path of a Chromium-family browser on PATH, or None."""
    return next((p for p in map(shutil.which, CANDIDATES) if p), None)


class Browser:
    """One headless Chromium showing ``url``; :meth:`evaluate` and :meth:`screenshot` over CDP."""

    def __init__(self, url: str, width: int = 1280, height: int = 800, timeout_s: float = 30.0):
        exe = find_browser()
        if exe is None:
            raise FileNotFoundError("no Chromium on PATH (Debian: apt-get install chromium)")
        self.profile = Path(tempfile.mkdtemp(prefix="skin_sim_view_chromium_"))
        argv = [exe, *FLAGS, f"--user-data-dir={self.profile}", f"--window-size={width},{height}", url]
        self.proc = subprocess.Popen(argv, stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
        port_file = self.profile / "DevToolsActivePort"
        end = time.monotonic() + timeout_s
        while not port_file.exists() or not port_file.read_text().strip():
            if self.proc.poll() is not None or time.monotonic() > end:
                self.close()
                raise RuntimeError(f"{exe} did not open its DevTools port within {timeout_s} s")
            time.sleep(0.05)
        port = int(port_file.read_text().split()[0])
        page = None
        while page is None:
            with urllib.request.urlopen(f"http://127.0.0.1:{port}/json/list", timeout=5) as r:
                page = next((t for t in json.load(r) if t.get("type") == "page"), None)
            if page is None:
                if time.monotonic() > end:
                    self.close()
                    raise RuntimeError("no page target in the browser")
                time.sleep(0.05)
        self.ws = connect(page["webSocketDebuggerUrl"])
        self._ids = itertools.count(1)
        self._attached: list[dict] = []

    @property
    def pids(self) -> list[int]:
        """The browser and its children (renderer, GPU process): for CPU accounting."""
        import psutil

        try:
            p = psutil.Process(self.proc.pid)
            return [p.pid] + [c.pid for c in p.children(recursive=True)]
        except psutil.NoSuchProcess:
            return []

    def call(self, method: str, **params) -> dict:
        i = next(self._ids)
        self.ws.send(json.dumps({"id": i, "method": method, "params": params}))
        while True:
            msg = json.loads(self.ws.recv())
            if msg.get("id") == i:
                if "error" in msg:
                    raise RuntimeError(f"CDP {method}: {msg['error']}")
                return msg.get("result", {})
            if msg.get("method") == "Target.attachedToTarget":
                self._attached.append(msg)  # network_bytes enables the worker's Network domain

    def network_bytes(self, duration_s: float) -> int:
        """Bytes the page and its workers receive over ``duration_s`` (HTTP bodies, fetch streams, WebSocket
        frames), summed from CDP Network events; workers (a WebSocket in a Web Worker) are auto-attached."""

        self.call("Network.enable")
        self.call("Target.setAutoAttach", autoAttach=True, waitForDebuggerOnStart=False, flatten=True)
        total, end = 0, time.monotonic() + duration_s
        self.ws.sock.settimeout(0.2)
        try:
            while time.monotonic() < end:
                try:
                    msg = self._attached.pop() if self._attached else json.loads(self.ws.recv())
                except TimeoutError:
                    continue
                method, p = msg.get("method"), msg.get("params", {})
                if method == "Target.attachedToTarget":
                    sid = p["sessionId"]
                    self.ws.send(json.dumps({"id": next(self._ids), "sessionId": sid, "method": "Network.enable", "params": {}}))
                elif method == "Network.dataReceived":
                    total += int(p.get("dataLength", 0))
                elif method == "Network.webSocketFrameReceived":
                    r = p["response"]
                    n = len(r.get("payloadData", ""))
                    total += n * 3 // 4 if r.get("opcode") == 2 else n  # binary payloads arrive base64-encoded
        finally:
            self.ws.sock.settimeout(None)
        self.call("Network.disable")
        return total

    def evaluate(self, expression: str):
        """Value of a JavaScript expression in the page (promises awaited)."""
        r = self.call("Runtime.evaluate", expression=expression, awaitPromise=True, returnByValue=True)
        if "exceptionDetails" in r:
            raise RuntimeError(
                f"page error in {expression!r}: {r['exceptionDetails'].get('text')} "
                f"{r['exceptionDetails'].get('exception', {}).get('description', '')}"
            )
        return r.get("result", {}).get("value")

    def wait_for(self, expression: str, timeout_s: float = 30.0, what: str = ""):
        end = time.monotonic() + timeout_s
        while True:
            try:
                v = self.evaluate(expression)
            except RuntimeError:  # the page's module has not run yet
                v = None
            if v:
                return v
            if time.monotonic() > end:
                raise TimeoutError(f"page: {what or expression} not true within {timeout_s} s")
            time.sleep(0.1)

    def hold_when(self, condition: str, timeout_s: float = 30.0, what: str = "") -> None:
        """Wait until ``condition`` (JS over ``window.skinView``) holds, and in the same evaluation hold the page:
        it then takes no new frame, so a screenshot shows the frame the condition was true for. :meth:`release`
        lets frames in again."""
        self.wait_for(
            f"(() => {{ if ({condition}) {{ window.skinView.hold = true; return true; }} return false; }})()",
            timeout_s,
            what or condition,
        )

    def release(self) -> None:
        """Let the page take frames again after :meth:`hold_when`; the frames that came meanwhile are applied in order."""
        self.evaluate("window.skinViewRelease()")

    def screenshot(self, path: Path) -> Path:
        data = self.call("Page.captureScreenshot", format="png")["data"]
        path = Path(path)
        path.parent.mkdir(parents=True, exist_ok=True)
        path.write_bytes(base64.b64decode(data))
        return path

    def close(self) -> None:
        if getattr(self, "ws", None) is not None:
            self.ws.close()
        if self.proc.poll() is None:
            self.proc.terminate()
            try:
                self.proc.wait(timeout=5)
            except subprocess.TimeoutExpired:
                self.proc.kill()
                self.proc.wait()
        shutil.rmtree(self.profile, ignore_errors=True)

    def __enter__(self) -> Browser:
        return self

    def __exit__(self, *exc) -> None:
        self.close()
