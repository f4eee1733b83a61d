"""The client end of the wire: requests with deadlines, heartbeats and retries (docs/robot.md).

:class:`WireClient` speaks one :class:`Dialect` of the framing (a protocol name, the replies it accepts, what its
server is called in errors): :class:`RobotClient` is the brain's end of the robot protocol; the served grounder's
client (:mod:`drivenav.semantics.served`) is another. A DEALER socket speaks to the server's ROUTER
(REQ-compatible envelopes).

A request has a deadline, ``timeout_s`` from its sending, and only its own reply ends the wait. While it waits the
client sends a PING every ``heartbeat_s`` (the robot's deadman stays fed during long motions); the PONGs prove the
connection, not the request, so a server that answers heartbeats but never the request (one that holds it, or one
restarted on the same port after the request reached its predecessor) cannot keep a client waiting past the
deadline. Every reply names its server (a random id drawn when the server starts): a reply or a PONG from another
server than the one last heard fails the waiting request at once, as lost. After a deadline passes, the socket is
closed and re-created and the request re-sent under the same request id (the Lazy Pirate pattern; the robot never
executes a STEP twice), up to ``retries`` times; then the dialect's :class:`PeerUnavailableError`. An ERROR reply
raises the dialect's refusal (:class:`PeerRefusedError`), which names what the server refused.

:meth:`WireClient.request` sends and waits; :meth:`WireClient.submit` sends and returns, and
:meth:`WireClient.reply_to` waits later (the deadline still counts from the sending), so that a client works while
the server answers, with several requests out at once (a reply that comes while another is awaited is kept).
"""

from __future__ import annotations

import itertools
import logging
import math
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
    """The server did not answer a request by its deadline (after every retry), or restarted while the request
    waited: the request is lost, through no fault of the caller's (an episode it ended is run again by a resume).
    Its subclass :class:`PeerRefusedError` is a server's ERROR reply (its body in ``details``)."""

    def __init__(self, message: str, details: Mapping[str, Any] | None = None) -> None:
        super().__init__(message)
        self.details: Mapping[str, Any] = details or {}


class PeerRefusedError(PeerUnavailableError):
    """The server answered with an ERROR naming what it refused (its body in ``details``): an answer, not a loss."""


class RobotUnavailableError(PeerUnavailableError):
    """The robot did not answer a request in time (after every retry), or restarted while it waited."""


class RobotRefusedError(RobotUnavailableError, PeerRefusedError):
    """The robot answered with an ERROR (its body in ``details``)."""


@dataclass(frozen=True)
class Dialect:
    """One protocol over the framing: its ``protocol`` name, the reply types a client accepts, how its server is
    named in errors (``peer``), the option that names the client's CURVE keys, the error a lost request raises and
    the one an ERROR reply raises (``refused``)."""

    protocol: str
    replies: tuple[str, ...]
    peer: str
    keys_option: str
    error: type[PeerUnavailableError]
    refused: type[PeerRefusedError]


ROBOT = Dialect(PROTOCOL, REPLIES, "the robot", "--robot-keys", RobotUnavailableError, RobotRefusedError)


@dataclass(frozen=True)
class ClientConfig:
    """A request's deadline ``timeout_s`` after its sending, ``retries`` re-sends, a PING every ``heartbeat_s``
    while waiting; ``max_message_bytes`` is libzmq's MAXMSGSIZE for frames from the server."""

    timeout_s: float = 10.0
    retries: int = 3
    heartbeat_s: float = 0.25
    max_message_bytes: int = 64 * 2**20

    def __post_init__(self) -> None:
        for name in ("timeout_s", "heartbeat_s"):
            value = getattr(self, name)
            if not (math.isfinite(value) and value > 0.0):
                raise ValueError(f"{name} must be a finite number of seconds > 0, got {value}")
        if self.retries < 0:
            raise ValueError(f"retries must be >= 0, got {self.retries}")


@dataclass(frozen=True)
class Sent:
    """A request :meth:`WireClient.submit` sent, and when (``time.monotonic``): its deadline counts from then."""

    message: Message
    at: float


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
        self.server_id = ""
        """The id of the server last heard (empty until a reply names one)."""
        self._outstanding: set[str] = set()  # the ids of the requests submitted and not yet answered or forgotten
        self._early: dict[str, Message] = {}  # replies that came while another request's reply was awaited

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
        """Send ``message`` and return the server's reply to it. No reply by the deadline after every retry, or a
        restarted server, raises the dialect's :class:`PeerUnavailableError`; an ERROR reply its refusal (named)."""
        return self.reply_to(self.submit(message))

    def submit(self, message: Message) -> Sent:
        """Send ``message`` now and return at once: :meth:`reply_to` waits for its reply later, so that the caller
        works while the server answers. Several may be out at once; their replies are kept as they arrive, until
        each is asked for or :meth:`forget` drops it."""
        self._send(message)
        self._outstanding.add(message.request_id)
        return Sent(message, time.monotonic())

    def reply_to(self, sent: Sent) -> Message:
        """The reply to the request :meth:`submit` sent (its deadline ``timeout_s`` after its sending), as
        :meth:`request` returns it."""
        dialect, message = self.dialect, sent.message
        try:
            for attempt in range(self.config.retries + 1):
                if attempt:
                    log.warning(
                        "no reply from %s in %.1f s: reconnecting (retry %d)",
                        self.address,
                        self.config.timeout_s,
                        attempt,
                    )
                    self._socket.close(linger=0)
                    self._socket = self._connect()
                    self._send(message)
                    sent = Sent(message, time.monotonic())
                reply = self._await(message, sent.at)
                if reply is not None:
                    if reply.type == "ERROR":
                        error = reply.body.get("error", "?")
                        raise dialect.refused(f"{dialect.peer} refused {message.type}: {error}", reply.body)
                    return reply
        finally:
            self.forget(sent)
        waited = (self.config.retries + 1) * self.config.timeout_s
        raise dialect.error(f"no reply from {dialect.peer} at {self.address} to {message.type} in {waited:g} s")

    def forget(self, sent: Sent) -> None:
        """Drop a request whose reply is no longer wanted: a reply that came is dropped, one still to come will be."""
        self._outstanding.discard(sent.message.request_id)
        self._early.pop(sent.message.request_id, None)

    def _send(self, message: Message) -> None:
        """Queue ``message``; without a connection to queue it on (a refused CURVE handshake drops it), it is not
        sent and its deadline passes without a reply, which leads to a retry."""
        try:
            self._socket.send_multipart([b"", *encode(message, self.dialect.protocol)], flags=zmq.NOBLOCK, copy=False)
        except zmq.Again:
            log.debug("no connection to %s to send %s on", self.address, message.type)

    def _await(self, request: Message, sent_at: float) -> Message | None:
        """The reply to ``request``, sent at ``sent_at``, or None when ``timeout_s`` passes from then without it.
        Other frames (the PONGs of the heartbeats sent meanwhile, a late reply to an earlier request) never extend
        the wait; a reply to another request still out is kept for it."""
        early = self._early.pop(request.request_id, None)
        if early is not None:
            return early
        deadline = sent_at + self.config.timeout_s
        next_ping = time.monotonic() + self.config.heartbeat_s
        while (now := time.monotonic()) < deadline:
            wait = min(next_ping, deadline) - now
            if self._socket.poll(int(wait * 1000) + 1, zmq.POLLIN):
                reply = self._receive()
                if reply is not None:
                    own = reply.request_id == request.request_id
                    self._check_server(reply, request, own)
                    if own:
                        return reply
                    if reply.request_id in self._outstanding:
                        self._early[reply.request_id] = reply
            if time.monotonic() >= next_ping:
                self._send(Message("PING", self.next_id()))
                next_ping = time.monotonic() + self.config.heartbeat_s
        return None

    def _check_server(self, reply: Message, request: Message, own: bool) -> None:
        """Learn the server's id from ``reply``; a reply from another server than the one last heard (a server
        restarted on the same endpoint) fails ``request`` as lost, unless it is the request's own good reply (the
        new server was sent the request, and answered it)."""
        if not reply.server or reply.server == self.server_id:
            return
        known, self.server_id = self.server_id, reply.server
        if not known:
            return
        if own and reply.type != "ERROR":
            log.info("%s at %s restarted before %s reached it", self.dialect.peer, self.address, request.type)
            return
        raise self.dialect.error(
            f"{self.dialect.peer} at {self.address} restarted while {request.type} waited for its reply (another "
            "server id answers there now): the request is lost"
        )

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
