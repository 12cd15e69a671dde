"""A minimal RFC 6455 WebSocket (server side for the page, client side for the DevTools protocol).

Standard library only: the view serves one page to a handful of local browsers, so a small
blocking implementation (one thread per connection) is enough and adds no dependency.
Supports text and binary frames, ping/pong and close; no extensions, no fragmented sends.
"""

from __future__ import annotations

import base64
import hashlib
import os
import socket
import struct
import threading
from urllib.parse import urlparse

GUID = "258EAFA5-E914-47DA-95CA-C5AB0DC85B11"  # RFC 6455 section 1.3
OP_CONT, OP_TEXT, OP_BINARY, OP_CLOSE, OP_PING, OP_PONG = 0x0, 0x1, 0x2, 0x8, 0x9, 0xA


class WebSocketClosedError(ConnectionError):
    """The peer closed the connection (or it broke)."""


def accept_key(key: str) -> str:
    """``Sec-WebSocket-Accept`` for a client's ``Sec-WebSocket-Key`` (RFC 6455 section 4.2.2)."""
    return base64.b64encode(hashlib.sha1((key + GUID).encode()).digest()).decode()


def encode_frame(payload: bytes, opcode: int, mask: bool = False) -> bytes:
    """One final frame; clients must mask (section 5.3), servers must not."""
    n = len(payload)
    head = bytearray([0x80 | opcode])
    mbit = 0x80 if mask else 0
    if n < 126:
        head.append(mbit | n)
    elif n < 1 << 16:
        head.append(mbit | 126)
        head += struct.pack(">H", n)
    else:
        head.append(mbit | 127)
        head += struct.pack(">Q", n)
    if not mask:
        return bytes(head) + payload
    key = os.urandom(4)
    return bytes(head) + key + apply_mask(payload, key)


def apply_mask(data: bytes, key: bytes) -> bytes:
    """XOR ``data`` with the 4-byte masking key, vectorised through int.from_bytes."""
    n = len(data)
    if n == 0:
        return b""
    rep = (key * (n // 4 + 1))[:n]
    return (int.from_bytes(data, "little") ^ int.from_bytes(rep, "little")).to_bytes(n, "little")


def _recv_exact(sock: socket.socket, n: int) -> bytes:
    buf = bytearray()
    while len(buf) < n:
        chunk = sock.recv(n - len(buf))
        if not chunk:
            raise WebSocketClosedError("connection closed")
        buf += chunk
    return bytes(buf)


class WebSocket:
    """One open WebSocket over a connected socket; ``send`` is thread-safe."""

    def __init__(self, sock: socket.socket, client: bool, leftover: bytes = b""):
        self.sock = sock
        self.client = client
        self._send_lock = threading.Lock()
        self._pending = leftover
        self.closed = False

    def _recv(self, n: int) -> bytes:
        if self._pending:
            take, self._pending = self._pending[:n], self._pending[n:]
            return take + (_recv_exact(self.sock, n - len(take)) if len(take) < n else b"")
        return _recv_exact(self.sock, n)

    def send(self, data: bytes | str) -> None:
        opcode = OP_TEXT if isinstance(data, str) else OP_BINARY
        payload = data.encode() if isinstance(data, str) else bytes(data)
        self._send_raw(payload, opcode)

    def _send_raw(self, payload: bytes, opcode: int) -> None:
        frame = encode_frame(payload, opcode, mask=self.client)
        with self._send_lock:
            if self.closed:
                raise WebSocketClosedError("already closed")
            try:
                self.sock.sendall(frame)
            except OSError as exc:
                self.closed = True
                raise WebSocketClosedError(str(exc)) from exc

    def recv(self) -> bytes | str:
        """The next complete text (str) or binary (bytes) message; answers pings; raises on close."""
        parts, first_op = [], None
        while True:
            b0, b1 = self._recv(2)
            opcode, fin = b0 & 0x0F, b0 & 0x80
            n = b1 & 0x7F
            if n == 126:
                n = struct.unpack(">H", self._recv(2))[0]
            elif n == 127:
                n = struct.unpack(">Q", self._recv(8))[0]
            key = self._recv(4) if b1 & 0x80 else None
            payload = self._recv(n)
            if key is not None:
                payload = apply_mask(payload, key)
            if opcode == OP_CLOSE:
                try:
                    self._send_raw(payload[:2], OP_CLOSE)
                except WebSocketClosedError:
                    pass
                self.closed = True
                raise WebSocketClosedError("peer sent close")
            if opcode == OP_PING:
                self._send_raw(payload, OP_PONG)
                continue
            if opcode == OP_PONG:
                continue
            if opcode != OP_CONT:
                first_op = opcode
            parts.append(payload)
            if fin:
                data = b"".join(parts)
                return data.decode() if first_op == OP_TEXT else data

    def close(self) -> None:
        try:
            self._send_raw(struct.pack(">H", 1000), OP_CLOSE)
        except WebSocketClosedError:
            pass
        self.closed = True
        try:
            self.sock.close()
        except OSError:
            pass


def connect(url: str, timeout_s: float = 10.0) -> WebSocket:
    """Open a client WebSocket to ``ws://host:port/path`` (the DevTools endpoint)."""
    u = urlparse(url)
    sock = socket.create_connection((u.hostname, u.port or 80), timeout=timeout_s)
    key = base64.b64encode(os.urandom(16)).decode()
    path = u.path + (f"?{u.query}" if u.query else "")
    req = (
        f"GET {path or '/'} HTTP/1.1\r\nHost: {u.hostname}:{u.port}\r\nUpgrade: websocket\r\nConnection: Upgrade\r\n"
        f"Sec-WebSocket-Key: {key}\r\nSec-WebSocket-Version: 13\r\n\r\n"
    )
    sock.sendall(req.encode())
    buf = b""
    while b"\r\n\r\n" not in buf:
        chunk = sock.recv(4096)
        if not chunk:
            raise WebSocketClosedError(f"{url}: connection closed during the handshake")
        buf += chunk
    head, _, rest = buf.partition(b"\r\n\r\n")
    status = head.split(b"\r\n", 1)[0]
    if b" 101 " not in status + b" ":
        raise WebSocketClosedError(f"{url}: handshake refused: {status.decode(errors='replace')}")
    if accept_key(key).encode() not in head:
        raise WebSocketClosedError(f"{url}: bad Sec-WebSocket-Accept")
    sock.settimeout(None)
    return WebSocket(sock, client=True, leftover=rest)
