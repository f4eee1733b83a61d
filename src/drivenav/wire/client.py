"""The client end of the wire: requests with timeouts, heartbeats and retries (docs/robot.md).

:class:`WireClient` speaks one :class:`Dialect` of the framing (a protocol name, the replies it accepts, what its
server is called in errors): :class:`RobotClient` is the brain's end of the robot protocol; the served grounder's
client (:mod:`drivenav.semantics.served`) is another. A DEALER socket speaks to the server's ROUTER
(REQ-compatible envelopes). While a reply is awaited the client sends
a PING every ``heartbeat_s`` (the robot's deadman stays fed during long motions; its PONGs show it is alive). When
nothing at all comes back for ``timeout_s``, the socket is closed and re-created and the request re-sent under the
same request id (the Lazy Pirate pattern; the robot never executes a STEP twice), up to ``retries`` times; then
:class:`RobotUnavailableError`.
"""

from __future__ import annotations

import itertools
import logging
import time
import uuid
from collections.abc import Mapping
from dataclasses import dataclass
from pathlib import Path
from typing import Any, ClassVar

import zmq

from drivenav.wire.protocol import PROTOCOL, REPLIES, Message, ProtocolError, decode, encode
from drivenav.wire.security import secure_client

log = logging.getLogger(__name__)


class PeerUnavailableError(RuntimeError):
    """The server did not answer (after every retry) or answered with an ERROR (its body in ``details``)."""

    def __init__(self, message: str, details: Mapping[str, Any] | None = None) -> None:
        super().__init__(message)
        self.details: Mapping[str, Any] = details or {}


class RobotUnavailableError(PeerUnavailableError):
    """The robot did not answer (after every retry) or answered with an ERROR (its body in ``details``)."""


@dataclass(frozen=True)
class Dialect:
    """One protocol over the framing: its ``protocol`` name, the reply types a client accepts, how its server is
    named in errors (``peer``), the option that names the client's CURVE keys and the error a failure raises."""

    protocol: str
    replies: tuple[str, ...]
    peer: str
    keys_option: str
    error: type[PeerUnavailableError]


ROBOT = Dialect(PROTOCOL, REPLIES, "the robot", "--robot-keys", RobotUnavailableError)


@dataclass(frozen=True)
class ClientConfig:
    """``timeout_s`` of silence before a retry, ``retries`` re-sends, a PING every ``heartbeat_s`` while waiting;
    ``max_message_bytes`` is libzmq's MAXMSGSIZE for frames from the robot."""

    timeout_s: float = 10.0
    retries: int = 3
    heartbeat_s: float = 0.25
    max_message_bytes: int = 64 * 2**20


class WireClient:
    """Requests to the server at ``address`` (CURVE with the keys in ``keys``) in the class's :attr:`dialect`."""

    dialect: ClassVar[Dialect]

    def __init__(self, address: str, keys: Path | None = None, config: ClientConfig | None = None) -> None:
        self.address = address
        self.keys = keys
        self.config = config or ClientConfig()
        self._context: zmq.Context[Any] = zmq.Context()
        self._socket = self._connect()
        self._session = uuid.uuid4().hex[:8]
        self._counter = itertools.count(1)

    def _connect(self) -> zmq.Socket[Any]:
        sock: zmq.Socket[Any] = self._context.socket(zmq.DEALER)
        sock.setsockopt(zmq.LINGER, 0)
        sock.setsockopt(zmq.MAXMSGSIZE, self.config.max_message_bytes)
        if self.keys is not None:
            secure_client(sock, self.keys, self.dialect.keys_option)
        sock.connect(self.address)
        return sock

    def next_id(self) -> str:
        """A request id unique to this client."""
        return f"{self._session}-{next(self._counter)}"

    def request(self, message: Message) -> Message:
        """Send ``message`` and return the server's reply to it; silence after every retry, or an ERROR reply (named),
        raises the dialect's :class:`PeerUnavailableError`."""
        dialect = self.dialect
        for attempt in range(self.config.retries + 1):
            if attempt:
                log.warning(
                    "no reply from %s for %.1f s: reconnecting (retry %d)", self.address, self.config.timeout_s, attempt
                )
                self._socket.close(linger=0)
                self._socket = self._connect()
            self._send(message)
            reply = self._await(message.request_id)
            if reply is not None:
                if reply.type == "ERROR":
                    error = reply.body.get("error", "?")
                    raise dialect.error(f"{dialect.peer} refused {message.type}: {error}", reply.body)
                return reply
        waited = (self.config.retries + 1) * self.config.timeout_s
        raise dialect.error(f"no reply from {dialect.peer} at {self.address} to {message.type} in {waited:g} s")

    def _send(self, message: Message) -> None:
        """Queue ``message``; without a connection to queue it on (a refused CURVE handshake drops it), it is not
        sent and the silence that follows leads to a retry."""
        try:
            self._socket.send_multipart([b"", *encode(message, self.dialect.protocol)], flags=zmq.NOBLOCK, copy=False)
        except zmq.Again:
            log.debug("no connection to %s to send %s on", self.address, message.type)

    def _await(self, request_id: str) -> Message | None:
        """The reply to ``request_id``, or None after ``timeout_s`` without a frame from the server."""
        heard = time.monotonic()
        next_ping = heard + self.config.heartbeat_s
        while time.monotonic() - heard < self.config.timeout_s:
            wait = max(0.0, min(next_ping, heard + self.config.timeout_s) - time.monotonic())
            if self._socket.poll(int(wait * 1000) + 1, zmq.POLLIN):
                heard = time.monotonic()
                reply = self._receive()
                if reply is not None and reply.request_id == request_id:
                    return reply
            if time.monotonic() >= next_ping:
                self._send(Message("PING", self.next_id()))
                next_ping = time.monotonic() + self.config.heartbeat_s
        return None

    def _receive(self) -> Message | None:
        frames = self._socket.recv_multipart(copy=False)
        if frames and len(frames[0]) == 0:
            frames = frames[1:]
        try:
            return decode([f.buffer for f in frames], self.dialect.replies, self.dialect.protocol)
        except ProtocolError as error:
            log.warning("ignored a malformed reply from %s: %s", self.dialect.peer, error)
            return None

    def close(self) -> None:
        self._socket.close(linger=0)
        self._context.term()


class RobotClient(WireClient):
    """Requests to the robot at ``address`` (CURVE with the keys in ``keys``): the brain's end."""

    dialect = ROBOT
