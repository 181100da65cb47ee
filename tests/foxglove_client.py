"""A minimal client of Foxglove's WebSocket protocol (``foxglove.sdk.v1``), standard library
only: the RFC 6455 handshake and frames, ``subscribe``, ``fetchAsset`` and the binary
message-data and asset replies, for tests of ``--live``."""

from __future__ import annotations

import base64
import json
import os
import socket
import struct
import time

SUBPROTOCOL = "foxglove.sdk.v1"
MESSAGE_DATA = 0x01  # binary opcodes from the server
FETCH_ASSET_RESPONSE = 0x04


class FoxgloveClient:
    """One connection to a Foxglove WebSocket server at ``host``:``port``."""

    def __init__(self, host: str, port: int, timeout_s: float = 10.0) -> None:
        self.sock = socket.create_connection((host, port), timeout=timeout_s)
        key = base64.b64encode(os.urandom(16)).decode()
        self.sock.sendall((f"GET / HTTP/1.1\r\nHost: {host}:{port}\r\nUpgrade: websocket\r\n"
                           f"Connection: Upgrade\r\nSec-WebSocket-Key: {key}\r\n"
                           f"Sec-WebSocket-Version: 13\r\n"
                           f"Sec-WebSocket-Protocol: {SUBPROTOCOL}\r\n\r\n").encode())
        head = b""
        while b"\r\n\r\n" not in head:
            chunk = self.sock.recv(4096)
            if not chunk:
                raise ConnectionError("the server closed the connection in the handshake")
            head += chunk
        head, self._buffer = head.split(b"\r\n\r\n", 1)
        self.handshake = head.decode("latin-1")
        if not self.handshake.startswith("HTTP/1.1 101"):
            raise ConnectionError(f"no WebSocket upgrade: {self.handshake.splitlines()[0]}")
        self.channels: dict[int, dict] = {}  # advertised, by id
        self.server_info: dict = {}

    def close(self) -> None:
        try:
            self._send(0x8, b"")
        except OSError:
            pass
        self.sock.close()

    def _send(self, opcode: int, payload: bytes) -> None:
        mask = os.urandom(4)
        n = len(payload)
        if n < 126:
            header = struct.pack("!BB", 0x80 | opcode, 0x80 | n)
        elif n < 65536:
            header = struct.pack("!BBH", 0x80 | opcode, 0x80 | 126, n)
        else:
            header = struct.pack("!BBQ", 0x80 | opcode, 0x80 | 127, n)
        masked = bytes(b ^ mask[i % 4] for i, b in enumerate(payload))
        self.sock.sendall(header + mask + masked)

    def send_json(self, message: dict) -> None:
        self._send(0x1, json.dumps(message).encode())

    def _read(self, n: int) -> bytes:
        while len(self._buffer) < n:
            chunk = self.sock.recv(65536)
            if not chunk:
                raise ConnectionError("the server closed the connection")
            self._buffer += chunk
        out, self._buffer = self._buffer[:n], self._buffer[n:]
        return out

    def receive(self) -> tuple[int, bytes]:
        """The next whole message: (opcode, payload); pings are answered, fragments joined."""
        parts, first_opcode = [], None
        while True:
            b0, b1 = self._read(2)
            opcode, n = b0 & 0x0F, b1 & 0x7F
            if n == 126:
                (n,) = struct.unpack("!H", self._read(2))
            elif n == 127:
                (n,) = struct.unpack("!Q", self._read(8))
            mask = self._read(4) if b1 & 0x80 else None
            payload = self._read(n)
            if mask:
                payload = bytes(b ^ mask[i % 4] for i, b in enumerate(payload))
            if opcode == 0x9:
                self._send(0xA, payload)
                continue
            if opcode == 0x8:
                raise ConnectionError("the server closed the connection")
            if opcode in (0x1, 0x2):
                first_opcode = opcode
            parts.append(payload)
            if b0 & 0x80:
                return first_opcode, b"".join(parts)

    def next_event(self) -> tuple[str, object]:
        """The next message, decoded: ("json", dict) for a text message (advertisements are
        remembered), ("message", (subscription id, log time ns, payload)) or ("asset",
        (request id, ok, error, data))."""
        opcode, payload = self.receive()
        if opcode == 0x1:
            message = json.loads(payload)
            if message.get("op") == "advertise":
                self.channels.update({c["id"]: c for c in message["channels"]})
            elif message.get("op") == "serverInfo":
                self.server_info = message
            return "json", message
        if payload[0] == MESSAGE_DATA:
            subscription, log_time = struct.unpack_from("<IQ", payload, 1)
            return "message", (subscription, log_time, payload[13:])
        if payload[0] == FETCH_ASSET_RESPONSE:
            request, status, error_length = struct.unpack_from("<IBI", payload, 1)
            error = payload[10:10 + error_length].decode()
            return "asset", (request, status == 0, error, payload[10 + error_length:])
        return "binary", payload

    def wait_for(self, predicate, timeout_s: float = 10.0):
        """Read events until ``predicate(kind, value)`` is true; return that event."""
        deadline = time.monotonic() + timeout_s
        while time.monotonic() < deadline:
            kind, value = self.next_event()
            if predicate(kind, value):
                return kind, value
        raise TimeoutError("no such message in time")


def protobuf_fields(data: bytes) -> list[tuple[int, object]]:
    """The (field number, value) pairs of a protobuf message, in order: varints as ints,
    fixed 64/32-bit fields as bytes, length-delimited ones (strings, nested messages, packed
    lists) as bytes, to be parsed again by the caller who knows the schema."""
    out, i = [], 0
    while i < len(data):
        key, i = _varint(data, i)
        number, wire = key >> 3, key & 7
        if wire == 0:
            value, i = _varint(data, i)
        elif wire == 1:
            value, i = data[i:i + 8], i + 8
        elif wire == 2:
            n, i = _varint(data, i)
            value, i = data[i:i + n], i + n
        elif wire == 5:
            value, i = data[i:i + 4], i + 4
        else:
            raise ValueError(f"protobuf wire type {wire} not handled")
        out.append((number, value))
    return out


def _varint(data: bytes, i: int) -> tuple[int, int]:
    value = shift = 0
    while True:
        byte = data[i]
        i += 1
        value |= (byte & 0x7F) << shift
        shift += 7
        if not byte & 0x80:
            return value, i
