"""The server end of the wire: a bound ZMQ ROUTER socket, shared by the robot's server (:mod:`drivenav.robot`) and
the served grounder (:mod:`drivenav.semantics.grounder_server`).

:class:`RouterSocket` refuses a non-loopback address without CURVE keys (:func:`~drivenav.wire.security.check_bind`),
sets libzmq's per-frame size limit, admits only the allow-listed keys when given some, and watches its connections
(a monitor socket). It receives one request with the client's identity, its envelope's empty delimiter removed
(REQ and our DEALER clients send one), and answers an identity. Every reply it encodes (:meth:`RouterSocket.frames`)
names :attr:`RouterSocket.server_id`, drawn at random when the socket is made: a client waiting on a request tells
a restarted server (another id) from the one it sent the request to. A request that failed to decode is answered
with :func:`error_reply`, under the id its header still says (:func:`loose_id`).
"""

from __future__ import annotations

import contextlib
import json
import logging
import threading
import uuid
from collections.abc import Iterator
from dataclasses import replace
from pathlib import Path
from typing import Any, Protocol

import zmq
from zmq.utils.monitor import recv_monitor_message

from drivenav.errors import InputError
from drivenav.wire.protocol import MAX_HEADER_BYTES, PROTOCOL, Message, encode
from drivenav.wire.security import check_bind, secure_server

log = logging.getLogger(__name__)

Frames = list[bytes | memoryview]


class RouterSocket:
    """A ROUTER socket bound at ``bind`` (CURVE with ``keys``), frames of at most ``max_message_bytes``.

    ``bind`` may name port ``*`` (a free port; :attr:`endpoint` says which). An address already in use, or one this
    machine does not have, is an :class:`~drivenav.errors.InputError` on ``--bind``.
    """

    def __init__(self, bind: str, keys: Path | None, max_message_bytes: int) -> None:
        check_bind(bind, keys)
        self.context: zmq.Context[Any] = zmq.Context()
        self.socket = self.context.socket(zmq.ROUTER)
        self.socket.setsockopt(zmq.LINGER, 0)
        self.socket.setsockopt(zmq.MAXMSGSIZE, max_message_bytes)
        self.curve = keys is not None
        self._auth = secure_server(self.context, self.socket, keys) if keys is not None else None
        self.monitor = self.socket.get_monitor_socket()
        try:
            self.socket.bind(bind)
        except zmq.ZMQError as error:  # in use, or a host this machine does not have
            self.close()
            raise InputError("command line", "--bind", "an address free to serve on", f"{bind}: {error}") from None
        self.endpoint = str(self.socket.getsockopt_string(zmq.LAST_ENDPOINT))
        self.server_id = uuid.uuid4().hex[:16]

    def receive(self) -> tuple[bytes, list[Any]]:
        """The next message: the client's identity and its frames (``zmq.Frame``), the empty delimiter removed."""
        frames = self.socket.recv_multipart(copy=False)
        body = frames[1:]
        if body and len(body[0]) == 0:
            body = body[1:]
        return frames[0].bytes, body

    def frames(self, reply: Message, protocol: str = PROTOCOL) -> Frames:
        """The frames of ``reply`` in ``protocol``, naming this server (:attr:`server_id`)."""
        return encode(replace(reply, server=self.server_id), protocol)

    def send(self, identity: bytes, frames: Frames) -> None:
        """Send ``frames`` to the client ``identity`` (with an empty delimiter, as REQ-style envelopes want)."""
        self.socket.send_multipart([identity, b"", *frames], copy=False)

    def connection_event(self) -> int:
        """The next event of the monitor socket (``zmq.EVENT_*``); a failed CURVE handshake is logged here, for
        every server alike."""
        kind = int(recv_monitor_message(self.monitor)["event"])
        if kind in (zmq.EVENT_HANDSHAKE_FAILED_AUTH, zmq.EVENT_HANDSHAKE_FAILED_PROTOCOL):
            log.warning("a connection failed its CURVE handshake (a key not in the allow-list?)")
        return kind

    def close(self) -> None:
        self.socket.disable_monitor()
        self.monitor.close(linger=0)
        self.socket.close(linger=0)
        if self._auth is not None:
            self._auth.stop()
        self.context.term()


def error_reply(request_id: str, error: str) -> Message:
    """An ERROR reply naming what was wrong."""
    return Message("ERROR", request_id or "?", status="error", body={"error": error})


def loose_id(frames: list[Any]) -> str:
    """The request id of a message that failed to decode, where its header still says one (a short string)."""
    if not frames or len(frames[0]) > MAX_HEADER_BYTES:
        return "?"
    try:
        header = json.loads(bytes(frames[0].buffer))
    except (ValueError, UnicodeDecodeError, RecursionError):
        return "?"
    value = header.get("id") if isinstance(header, dict) else None
    return value if isinstance(value, str) and 0 < len(value) <= 128 else "?"


class Serving(Protocol):
    """A server on a :class:`RouterSocket`: it serves until ``stop`` is set, then closes."""

    @property
    def endpoint(self) -> str: ...

    def serve(self, stop: threading.Event | None = None) -> None: ...

    def close(self) -> None: ...


@contextlib.contextmanager
def in_background(server: Serving, name: str) -> Iterator[str]:
    """``server`` served from a daemon thread called ``name`` for the duration; yields its endpoint, stops the
    thread and closes the server after."""
    stop = threading.Event()
    thread = threading.Thread(target=server.serve, args=(stop,), daemon=True, name=name)
    thread.start()
    try:
        yield server.endpoint
    finally:
        stop.set()
        thread.join()
        server.close()
