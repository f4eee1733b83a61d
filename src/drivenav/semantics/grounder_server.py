"""``drivenav serve grounder``: one grounder copy answering every worker, with dynamic batching (issue 37).

:class:`GrounderServer` puts a grounder behind a ROUTER socket (:class:`~drivenav.wire.router.RouterSocket`:
loopback unless CURVE keys are given) and speaks :mod:`drivenav.semantics.served`'s protocol. SEGMENT requests
wait in a queue until ``batch`` of them are there or the oldest has waited ``batch_ms``, whichever comes first;
HELLO, BEGIN and PING are answered at once, between batches.

A grounder that reads images (SAM3, OWLv2, Grounding DINO) is one shared copy, a
:class:`~drivenav.semantics.serve_pipeline.RowGrounder` that takes every phrase at once: a batch's frames are
grouped by size only, a frame a client sent for several phrases (one step's) is kept once, and each group is one
:meth:`~drivenav.semantics.hf_common.TransformersGrounder.segment_rows` forward whose vision encoder runs once a
frame and whose rest runs once a request, each with its own phrase (workers looking for different objects share a
forward; the text features of a phrase are encoded once for every worker, and after ``phrases`` distinct phrases
the cache is emptied). Another shared grounder (a plug-in's) has its batch grouped by phrase and frame size, each
group one ``segment_batch`` forward where it has one.

A stand-in that reads ground-truth labels (the embedded detector, the ground-truth one) is one instance per
episode, begun by BEGIN with the episode's truth and seed as in process; what the episodes hold is bounded per
client and in all (:class:`~drivenav.semantics.serve_config.ServeConfig`: labels a BEGIN, episodes and bytes kept),
the least recently used forgotten past a bound.

Nothing a client sends stops the server: a malformed or unknown request, or a grounder failing on one, is an ERROR
reply naming it, and the server goes on.
"""

from __future__ import annotations

import contextlib
import logging
import math
import threading
import time
from collections import Counter, OrderedDict
from collections.abc import Callable, Iterator, Mapping, Sequence
from dataclasses import dataclass, replace
from pathlib import Path

import numpy as np
import zmq

from drivenav.errors import InputError, one_line
from drivenav.semantics.checked import DetectionCheck
from drivenav.semantics.model_spec import ModelSpec
from drivenav.semantics.protocols import Detection, Grounder
from drivenav.semantics.registry import BOX_DETECTORS, GROUNDER_BACKENDS
from drivenav.semantics.serve_config import DEFAULT_BIND, ENTRY_BYTES, LABEL_BYTES, ServeConfig
from drivenav.semantics.serve_pipeline import (
    DeviceStreams,
    JoinsPixels,
    ModelPool,
    RowGrounder,
    ServerTimes,
    Steady,
    SteadyRate,
    Work,
    grounded_replies,
    grounding_failed,
)
from drivenav.semantics.served import (
    GROUNDER_PROTOCOL,
    REQUESTS,
    SegmentRequest,
    ServedInfo,
    TableVocabulary,
    read_begin,
    read_segment,
)
from drivenav.types import Observation
from drivenav.wire.protocol import MAX_ARRAY_BYTES, Message, ProtocolError, decode
from drivenav.wire.router import RouterSocket, error_reply, in_background, loose_id

log = logging.getLogger(__name__)


Frame = tuple[bytes, str, int]
"""A client's step (:attr:`_Pending.frame`): the client, the episode, the step."""


@dataclass
class _Pending:
    identity: bytes
    request: SegmentRequest
    arrived: float

    @property
    def frame(self) -> Frame:
        """Its frame: the client, the episode, the step (a frame's phrases are one frame of a batch)."""
        return self.identity, self.request.episode, self.request.observation.step


class _Queue:
    """The SEGMENT requests waiting for a batch, in arrival order, taken a frame at a time (every phrase of it)."""

    def __init__(self) -> None:
        self.pending: list[_Pending] = []

    def frames(self) -> list[Frame]:
        """The frames queued, in arrival order."""
        return list(self.arrivals())

    def arrivals(self) -> dict[Frame, float]:
        """The frames queued, in arrival order, each with its first request's arrival."""
        first: dict[Frame, float] = {}
        for pending in self.pending:
            first.setdefault(pending.frame, pending.arrived)
        return first

    def take(self, frames: Sequence[Frame]) -> list[_Pending]:
        """Every request of ``frames``, out of the queue."""
        chosen = set(frames)
        taken = [pending for pending in self.pending if pending.frame in chosen]
        self.pending = [pending for pending in self.pending if pending.frame not in chosen]
        return taken


@dataclass
class _Session:
    """A stand-in's episode: its grounder, the vocabulary each SEGMENT's phrase extends (``phrases`` added so far),
    the client that began it and the bytes it is charged (:class:`~drivenav.semantics.serve_config.ServeConfig`)."""

    grounder: Grounder
    vocabulary: TableVocabulary | None
    client: bytes
    charged: int
    phrases: int = 0


class _Episodes:
    """The stand-in's episodes kept, least recently used first, within ``config``'s bounds per client and in all."""

    def __init__(self, config: ServeConfig) -> None:
        self.config = config
        self._kept: OrderedDict[str, _Session] = OrderedDict()
        self._held = 0
        self._client_held: Counter[bytes] = Counter()
        self._client_kept: Counter[bytes] = Counter()

    def __len__(self) -> int:
        return len(self._kept)

    @property
    def held(self) -> int:
        """The bytes charged to the episodes kept."""
        return self._held

    def begin(self, episode: str, session: _Session) -> None:
        """Keep ``session`` as ``episode`` (one begun again replaces it), forgetting others past the bounds."""
        if episode in self._kept:
            self._forget(episode)
        self._kept[episode] = session
        self._held += session.charged
        self._client_held[session.client] += session.charged
        self._client_kept[session.client] += 1
        self._bound(session)

    def get(self, episode: str) -> _Session:
        """The session of ``episode`` (now the most recently used); one never begun, or forgotten, is refused."""
        session = self._kept.get(episode)
        if session is None:
            expected = (
                "an episode begun on this server (BEGIN first; a restarted server forgets its episodes, and one past "
                "its limits forgets the least recently used)"
            )
            raise ProtocolError("body.episode", expected, episode)
        self._kept.move_to_end(episode)
        return session

    def charge(self, session: _Session, size: int) -> None:
        """``size`` more bytes held by ``session`` (its vocabulary grew)."""
        session.charged += size
        self._held += size
        self._client_held[session.client] += size
        self._bound(session)

    def _bound(self, keep: _Session) -> None:
        """Forget the least recently used episodes but ``keep`` until its client's and the total bounds hold."""
        config, client = self.config, keep.client
        while self._client_kept[client] > config.client_episodes or self._client_held[client] > config.client_bytes:
            if not self._forget_oldest(keep, client):
                break
        while len(self._kept) > config.episodes or self._held > config.held_bytes:
            if not self._forget_oldest(keep, None):
                break

    def _forget_oldest(self, keep: _Session, client: bytes | None) -> bool:
        for episode, session in self._kept.items():
            if session is not keep and (client is None or session.client == client):
                self._forget(episode)
                log.debug("forgot episode %s (the server's limits)", episode)
                return True
        return False

    def _forget(self, episode: str) -> None:
        session = self._kept.pop(episode)
        self._held -= session.charged
        self._client_held[session.client] -= session.charged
        self._client_kept[session.client] -= 1
        if not self._client_kept[session.client]:
            del self._client_held[session.client], self._client_kept[session.client]


class _Clients:
    """The clients grounding now: each seen sending a SEGMENT within the last ``active_s`` seconds, how many of each
    one's frames the model threads hold, and how many of the SEGMENTs it sent of its last frame at once
    (``together``) have come. A client sends a frame's SEGMENTs together and waits for their replies before its next
    frame, so when every such client has a frame queued, all of its SEGMENTs in, or in the model, no frame can come
    that a batch would wait for."""

    def __init__(self, active_s: float) -> None:
        self.active_s = active_s
        self._seen: dict[bytes, float] = {}
        self._held: Counter[bytes] = Counter()
        self._frames: dict[bytes, tuple[tuple[str, int], int, int]] = {}  # the last frame: its key, expected, come
        self.rate = SteadyRate(time.monotonic())

    def saw(self, identity: bytes, request: SegmentRequest) -> None:
        """``request`` of ``identity``'s come (a new frame's first counted by :attr:`rate`). A SEGMENT of a frame whose
        SEGMENTs sent at once have all come begins another burst of it (phrases asked later of the same frame: a
        second prefetch, a prompt-enrichment round), whose ``together`` counts from there."""
        now = self._seen[identity] = time.monotonic()
        frame = (request.episode, request.observation.step)
        known = self._frames.get(identity)
        if known is not None and known[0] == frame:
            _, expected, come = known
        else:  # a new frame: its first SEGMENT
            self.rate.arrived(identity, now)
            expected, come = 0, 0
        if come >= expected:
            expected = come + request.together
        self._frames[identity] = (frame, expected, come + 1)

    def hold(self, identities: list[bytes]) -> None:
        self._held.update(identities)

    def release(self, identity: bytes) -> None:
        self._held[identity] -= 1
        if self._held[identity] <= 0:
            del self._held[identity]

    def all_waiting(self, queued: set[Frame]) -> bool:
        """Whether every client grounding now has a frame ``queued`` (every SEGMENT it sent of it at once come) or
        held by the model."""
        since = time.monotonic() - self.active_s
        for identity in [i for i, seen in self._seen.items() if seen < since]:
            del self._seen[identity]
            self._frames.pop(identity, None)
        if not self._seen.keys() <= {identity for identity, _, _ in queued} | self._held.keys():
            return False
        return all(self.complete(frame) for frame in queued)

    def complete(self, frame: Frame) -> bool:
        """Whether every SEGMENT its client sent of ``frame`` at once has come (so has every one of an earlier frame
        of the client's, or of a client no longer known)."""
        identity, episode, step = frame
        last, expected, come = self._frames.get(identity, (("", -1), 0, 0))
        return last != (episode, step) or come >= expected


class GrounderServer:
    """``factory``'s grounder served at ``bind`` (CURVE with ``keys``) as ``info`` describes it: one shared
    instance, or one per episode for a stand-in that reads labels (``info.labels``).

    A shared model runs in ``config.copies`` model threads
    (:class:`~drivenav.semantics.serve_pipeline.ModelPool`) while this thread receives, decodes and preprocesses the
    next batch. ``batch_sizes`` counts the batches run by their size, :attr:`times` says where a frame's time went.
    """

    def __init__(
        self,
        factory: Callable[[], Grounder],
        info: ServedInfo,
        bind: str = DEFAULT_BIND,
        keys: Path | None = None,
        config: ServeConfig | None = None,
    ) -> None:
        self.info = info
        self.config = config or ServeConfig(info.batch, info.batch_ms)
        self._factory = factory
        self._shared = None if info.labels else factory()
        self.episodes = _Episodes(self.config)
        self._check = DetectionCheck(f"{info.detector} (served grounder)", self.config.max_detections)
        self._queue = _Queue()
        self._clients = _Clients(self.config.active_s)
        self._alone_sizes: Counter[int] = Counter()
        self._router = RouterSocket(bind, keys, MAX_ARRAY_BYTES)
        self.endpoint = self._router.endpoint
        self._times = ServerTimes()
        self._deferred: list[tuple[bytes, Message, tuple[int, ...]]] = []
        self._streams = DeviceStreams(info.device)
        self._model = None if self._shared is None else self._model_pool(self._shared, factory)

    def _model_pool(self, shared: Grounder, factory: Callable[[], Grounder]) -> ModelPool:
        """``config.copies`` model threads: the shared grounder's, and one for each further copy ``factory`` builds."""
        copies = [shared, *(factory() for _ in range(self.config.copies - 1))]

        def encode(reply: Message) -> list[object]:
            return list(self._router.frames(reply, GROUNDER_PROTOCOL))

        context = self._router.context
        return ModelPool(copies, context, self._check.checked, encode, self.config.phrases, self._streams)

    @property
    def batch_sizes(self) -> Counter[int]:
        """The batches run so far, counted by their number of requests."""
        return self._alone_sizes if self._model is None else self._model.batch_sizes

    @property
    def steady(self) -> Steady | None:
        """The frames a second it served while every client that grounded was grounding (:class:`SteadyRate`)."""
        return self._clients.rate.steady()

    @property
    def times(self) -> ServerTimes:
        """Where the frames served so far spent their time (:class:`~drivenav.semantics.serve_pipeline.ServerTimes`),
        with the frames that came (:class:`~drivenav.semantics.serve_pipeline.SteadyRate`'s count)."""
        total = self._times if self._model is None else self._times.add(self._model.times)
        return replace(total, received=self._clients.rate.frames)

    def serve(self, stop: threading.Event | None = None) -> None:
        """Answer requests until ``stop`` is set (or Ctrl-C)."""
        stop = stop or threading.Event()
        poller = zmq.Poller()
        poller.register(self._router.socket, zmq.POLLIN)
        poller.register(self._router.monitor, zmq.POLLIN)
        if self._model is not None:
            poller.register(self._model.wake, zmq.POLLIN)
        log.info("serving the grounder %s on %s", self.info.detector, self.endpoint)
        while not stop.is_set():
            poller.modify(self._router.socket, 0 if self._holding() else zmq.POLLIN)
            events = dict(poller.poll(self._wait_ms()))
            if self._router.monitor in events:
                _log_socket_event(self._router)
            if self._model is not None and self._model.wake in events:
                self._send_replies()
            if self._router.socket in events:
                self._drain()
            if self._due():
                self._run_batch()
            elif self._growing():
                self._grow()

    def close(self) -> None:
        if self._model is not None:
            self._model.stop()
        self._router.close()

    def _send_replies(self) -> None:
        """The replies the model threads encoded, sent (they say so on the wake socket)."""
        assert self._model is not None
        start = time.perf_counter()
        for identity, frames in self._model.replies():
            self._router.send(identity, frames)
            self._clients.release(identity)
        self._times.seconds["send"] += time.perf_counter() - start
        waiting = []
        for identity, pong, ticket in self._deferred:
            if self._model.passed(ticket):
                self._send(identity, pong)
            else:
                waiting.append((identity, pong, ticket))
        self._deferred = waiting

    # -- requests ------------------------------------------------------------------------------------------------
    def _drain(self) -> None:
        """Every request already here, up to a full batch."""
        while not self._full() and self._router.socket.poll(0, zmq.POLLIN):
            self._receive()

    def _receive(self) -> None:
        start = time.perf_counter()
        identity, frames = self._router.receive()
        try:
            request = decode([f.buffer for f in frames], REQUESTS, GROUNDER_PROTOCOL)
        except ProtocolError as error:
            self._send(identity, error_reply(loose_id(frames), str(error)))
            return
        try:
            reply = self._answer(identity, request)
        except ProtocolError as error:
            reply = error_reply(request.request_id, str(error))
        except Exception as error:
            log.exception("%s could not be answered", request.type)
            reply = error_reply(request.request_id, f"{request.type} failed on the server: {one_line(error)}")
        if reply is not None:
            self._send(identity, reply)
        elif request.type == "SEGMENT":
            self._times.seconds["decode"] += time.perf_counter() - start

    def _answer(self, identity: bytes, request: Message) -> Message | None:
        """The reply to a request answered at once; a SEGMENT is queued (None)."""
        if request.type == "PING":
            return self._pong(identity, Message("PONG", request.request_id))
        if request.type == "HELLO":
            return Message("WELCOME", request.request_id, body=self.info.to_json())
        if request.type == "BEGIN":
            return self._begin(identity, request)
        segment = read_segment(request)
        if self._shared is None:
            self.episodes.get(segment.episode)  # an unknown episode is refused now, not after the batch
        pending = _Pending(identity, segment, time.monotonic())
        self._queue.pending.append(pending)
        self._clients.saw(identity, segment)
        return None

    def _pong(self, identity: bytes, pong: Message) -> Message | None:
        """A PONG now, or once the batches the model holds now are done (later ones aside): as between batches of
        one thread, a PING shows that the model answers, not only the socket (an episode's start does not begin on
        a stalled model), and a model kept busy by other workers still answers it within a batch or two."""
        if self._model is None:
            return pong
        ticket = self._model.ticket()
        if self._model.passed(ticket):
            return pong
        self._deferred.append((identity, pong, ticket))
        return None

    def _begin(self, identity: bytes, request: Message) -> Message:
        """A stand-in's episode begun for the client ``identity``, charged for its labels and names."""
        if self._shared is not None:
            raise ProtocolError("type", "no BEGIN: this server's grounder reads no ground truth", request.type)
        begin = read_begin(request, self.config.labels)
        labels = len(begin.truth.labels or {}) if begin.truth is not None else 0
        names = request.body.get("names") or []
        charged = LABEL_BYTES * labels + sum(ENTRY_BYTES + len(str(name)) for name in names)
        grounder = self._factory()
        grounder.begin_episode(begin.truth, begin.seed)
        self.episodes.begin(begin.episode, _Session(grounder, begin.vocabulary, identity, charged))
        return Message("BEGUN", request.request_id)

    # -- batches -------------------------------------------------------------------------------------------------
    def _wait_ms(self) -> int:
        """How long to wait for a request: until the oldest runnable frame's batch is due (or the oldest frame in
        parts runnable), at most ``poll_ms`` (while the model holds a batch in hand and another ready, until it says
        it is done)."""
        if not self._queue.pending or not self._model_ready():
            return self.config.poll_ms
        oldest = self._oldest_runnable()
        if oldest is not None:
            left = oldest + self.config.batch_ms / 1000.0 - time.monotonic()
        else:
            left = self._queue.pending[0].arrived + self.config.parts_s - time.monotonic()
        return max(0, min(self.config.poll_ms, math.ceil(left * 1000.0)))

    def _model_ready(self) -> bool:
        return self._model is None or self._model.ready

    def _whole(self) -> list[Frame]:
        """The frames queued whole (every SEGMENT their client sent of them at once), in arrival order."""
        return [frame for frame in self._queue.frames() if self._clients.complete(frame)]

    def _runnable(self) -> dict[Frame, float]:
        """The frames a batch may take, in arrival order with their first request's arrival: those queued whole, and
        those still in parts whose first request came ``parts_s`` ago (a client that sent fewer SEGMENTs of a frame
        than it said it sent at once). A frame in parts is otherwise left for its other phrases, which its client
        sent with it: taken, it would be encoded again with them in a later batch."""
        since = time.monotonic() - self.config.parts_s
        return {
            frame: arrived
            for frame, arrived in self._queue.arrivals().items()
            if arrived <= since or self._clients.complete(frame)
        }

    def _oldest_runnable(self) -> float | None:
        """When the first request of the oldest runnable frame came (None: no frame is runnable)."""
        return next(iter(self._runnable().values()), None)

    def _full(self) -> bool:
        """Whether ``batch`` frames are queued whole."""
        return len(self._whole()) >= self.config.batch

    def _holding(self) -> bool:
        """Whether a full batch is queued that no model copy can take yet: the requests that come would only queue
        behind it, so the socket is not read until a copy takes a batch or finishes one (a readable socket would
        wake the loop at once, again and again, for nothing)."""
        return self._model is not None and self._full() and not self._model_ready()

    def _due(self) -> bool:
        """A batch runs when a model copy is ready for it and ``batch`` whole frames are queued, or its oldest
        runnable frame has waited ``batch_ms``, or every client grounding now is waiting on it or on the model (no
        frame can come)."""
        if not self._queue.pending or not self._model_ready():
            return False
        oldest = self._oldest_runnable()
        if oldest is None:
            return False
        waited = time.monotonic() - oldest
        if self._full() or waited * 1000.0 >= self.config.batch_ms:
            return True
        return self._clients.all_waiting(set(self._queue.frames()))

    def _run_batch(self) -> None:
        batch = self._taken(self.config.batch)
        if self._model is None:
            self._alone_sizes[len(batch)] += 1
            for pending in batch:
                self._answer_alone(pending)
            return
        work = self._works(batch)
        if work:
            self._model.put(work)

    def _growing(self) -> bool:
        """Whether whole frames wait that can join the batch waiting for the model (a grounder whose preprocessed
        frames join, :class:`~drivenav.semantics.serve_pipeline.JoinsPixels`)."""
        if self._model is None or not isinstance(self._shared, JoinsPixels) or not self._whole():
            return False
        return self._model.waiting(self.config.batch) is not None

    def _grow(self) -> None:
        """The frames that came whole while the next batch waits for the model join it, up to ``batch`` frames,
        preprocessed now: a batch is not closed while the model runs the one before, so it runs as full as one
        formed when the model is free, its first frames preprocessed meanwhile. A frame whose phrases are not all
        here waits for the rest (joined in parts, it would be encoded once a part). Where the model took the batch
        first, they are the next one."""
        assert self._model is not None
        waiting = self._model.waiting(self.config.batch)
        if waiting is None:
            return
        thread, room = waiting
        work = self._works(self._taken(room, whole=True))
        if work and not thread.grow(work):
            self._model.put(work)

    def _taken(self, count: int, whole: bool = False) -> list[_Pending]:
        """The requests of the first ``count`` runnable frames (:meth:`_runnable`; only those queued whole, with
        ``whole``), out of the queue, their wait counted."""
        batch = self._queue.take((self._whole() if whole else list(self._runnable()))[:count])
        now = time.monotonic()
        self._times.seconds["wait"] += sum(now - pending.arrived for pending in batch)
        return batch

    def _works(self, batch: list[_Pending]) -> list[Work]:
        """``batch`` as the model's work, grouped by frame size (and phrase, for a grounder that takes one phrase a
        forward) and preprocessed; its clients held."""
        rows = isinstance(self._shared, RowGrounder)  # one forward for every phrase of a frame size
        groups: dict[tuple[str, tuple[int, ...]], list[_Pending]] = {}
        for pending in batch:
            key = ("" if rows else pending.request.phrase, pending.request.observation.depth.shape)
            groups.setdefault(key, []).append(pending)
        work = [prepared for group in groups.values() if (prepared := self._prepared(group)) is not None]
        self._clients.hold([identity for w in work for identity, _, _ in w.replies])
        return work

    def _prepared(self, group: list[_Pending]) -> Work | None:
        """``group`` as the model thread's work, its frames preprocessed here where the grounder allows (a failure
        answers the group with one ERROR now)."""
        replies = [(p.identity, p.request.request_id, _size(p.request)) for p in group]
        work = self._frames_of(group, replies)
        if not isinstance(self._shared, RowGrounder):
            return work
        start = time.perf_counter()
        try:
            with self._streams.preprocessing():
                work.pixels = [self._shared.preprocess(work.frames)]
        except Exception as error:
            log.exception("preprocessing frames for %s failed", ", ".join(map(repr, work.phrases)))
            for identity, request_id, _ in work.replies:
                self._send(identity, error_reply(request_id, grounding_failed(error)))
            return None
        finally:
            self._times.seconds["preprocess"] += time.perf_counter() - start
        return work

    def _frames_of(self, group: list[_Pending], replies: list[tuple[bytes, str, tuple[int, int]]]) -> Work:
        """``group``'s work: for a :class:`RowGrounder`, a frame sent several times by a client (its phrases of one
        step) is one frame, encoded once; else a frame per request."""
        observations: list[Observation] = []
        rows: list[tuple[int, str]] = []
        seen: dict[Frame, int] = {}
        shared_frames = isinstance(self._shared, RowGrounder)
        for pending in group:
            observation = pending.request.observation
            index = seen.get(pending.frame) if shared_frames else None
            if index is None or not np.array_equal(observations[index].rgb, observation.rgb):
                index = seen[pending.frame] = len(observations)
                observations.append(observation)
            rows.append((index, pending.request.phrase))
        return Work(replies, rows, observations)

    def _answer_alone(self, pending: _Pending) -> None:
        """A stand-in's episode grounds its one request, the phrase's category added to its vocabulary first; the
        detections checked as in process (:class:`DetectionCheck`), or an ERROR when grounding failed."""
        request, start = pending.request, time.perf_counter()

        def ground() -> list[list[Detection]]:
            session = self.episodes.get(request.episode)
            if session.vocabulary is not None:
                self._extend(session, session.vocabulary, request.canonical)
            found = session.grounder.segment(request.observation, request.phrase)
            self._times.seconds["forward"] += time.perf_counter() - start
            return [found]

        asked = [(request.request_id, _size(request), request.phrase)]
        (reply,) = grounded_replies(asked, ground, self._check.checked)
        self._send(pending.identity, reply)
        self._times.frames += 1
        self._times.batches += 1

    def _extend(self, session: _Session, vocabulary: TableVocabulary, canonical: Mapping[str, str | None]) -> None:
        """Add a SEGMENT's phrase and its category to an episode's vocabulary: at most ``phrases`` phrases an
        episode, each charged to it."""
        for phrase, category in canonical.items():
            if phrase not in vocabulary.table:
                if session.phrases >= self.config.phrases:
                    expected = f"at most {self.config.phrases} distinct phrases an episode (the server's limit)"
                    raise ProtocolError("body.phrase", expected, phrase)
                session.phrases += 1
                self.episodes.charge(session, ENTRY_BYTES + len(phrase) + len(category or ""))
            vocabulary.table[phrase] = category

    def _send(self, identity: bytes, reply: Message) -> None:
        start = time.perf_counter()
        self._router.send(identity, self._router.frames(reply, GROUNDER_PROTOCOL))
        self._times.seconds["reply"] += time.perf_counter() - start


def _size(request: SegmentRequest) -> tuple[int, int]:
    height, width = request.observation.depth.shape[:2]
    return height, width


def _log_socket_event(router: RouterSocket) -> None:
    if router.connection_event() == zmq.EVENT_DISCONNECTED:
        log.info("a client disconnected")


# -- building and running a server ------------------------------------------------------------------------------------


def served_info(spec: ModelSpec, grounder: Grounder, config: ServeConfig, model: str = "") -> ServedInfo:
    """What a server of ``spec.detector`` says of itself, from the built ``grounder`` (its model's device and
    dtype where it has a model); ``model`` describes the weights (default: ``spec.detector_model``, or "default"),
    followed by a box detector's segmenter."""
    backend = GROUNDER_BACKENDS.get(spec.detector)
    built = getattr(grounder, "model", None)
    device = str(getattr(built, "device", "cpu"))
    dtype = str(getattr(built, "dtype", "none")).removeprefix("torch.")
    name = model or spec.detector_model or "default"
    if spec.detector in BOX_DETECTORS:
        name += f" + {spec.segmenter}" + (f" ({spec.segmenter_model})" if spec.segmenter_model else "")
    return ServedInfo(
        spec.detector, name, device, dtype, backend.observes, backend.reads_labels, config.batch, config.batch_ms
    )


def build_server(
    spec: ModelSpec,
    bind: str,
    keys: Path | None,
    config: ServeConfig,
    build: Callable[[ModelSpec], Grounder] | None = None,
    model: str = "",
) -> GrounderServer:
    """A server of ``spec.detector`` (any but ``remote``), its model loaded (a missing one: one InputError line).
    ``build`` makes the grounder instead of its backend (``serve grounder --random-weights``), ``model`` then
    describing its weights."""
    if spec.detector == "remote":
        local = ", ".join(name for name in GROUNDER_BACKENDS.names if name != "remote")
        raise InputError("command line", "--detector", f"a detector run in this process ({local})", "remote")
    make = build or GROUNDER_BACKENDS.get(spec.detector).build

    def factory() -> Grounder:
        return make(spec)

    probe = factory()
    info = served_info(spec, probe, config, model)
    return GrounderServer(factory if info.labels else probe_first(probe, factory), info, bind, keys, config)


def probe_first(probe: Grounder, build: Callable[[], Grounder]) -> Callable[[], Grounder]:
    """A server's factory of shared copies: ``probe`` (a copy already built, to describe the server) first, then a
    new ``build()`` for each further copy (``ServeConfig.copies``)."""
    built = [probe]

    def copy() -> Grounder:
        return built.pop() if built else build()

    return copy


def run_server(server: GrounderServer, curve: bool) -> None:
    """Serve until Ctrl-C (or SIGTERM); the first line printed names the endpoint (``curve``: keys were given), the
    last one what was served (:func:`batches_line`) and where a frame's time went
    (:meth:`~drivenav.semantics.serve_pipeline.ServerTimes.line`)."""
    info, config = server.info, server.config
    print(
        f"serving the grounder {info.detector} ({info.model}, {info.device}, {info.dtype}; batch {config.batch} or "
        f"{config.batch_ms:g} ms{_copies(config.copies)}) on {server.endpoint}{' with CURVE' if curve else ''} "
        "(Ctrl-C stops)",
        flush=True,
    )
    try:
        server.serve()
    finally:
        server.close()
        steady = server.steady
        rate = "" if steady is None else f"; {steady.line()}"
        print(f"{batches_line(server.batch_sizes)}; {server.times.line()}{rate}", flush=True)


def _copies(copies: int) -> str:
    return f"; {copies} copies" if copies > 1 else ""


def batches_line(batch_sizes: Counter[int]) -> str:
    """What a server served: its frames, its batches and their mean size."""
    frames, batches = sum(n * c for n, c in batch_sizes.items()), sum(batch_sizes.values())
    mean = f" (mean {frames / batches:.2f} frames)" if batches else ""
    return f"served {frames} frames in {batches} batches{mean}"


@contextlib.contextmanager
def serving(server: GrounderServer) -> Iterator[str]:
    """``server`` served from a background thread for the duration; yields its endpoint, closes it after."""
    with in_background(server, "drivenav-grounder-server") as endpoint:
        yield endpoint
