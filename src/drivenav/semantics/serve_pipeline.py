"""The served grounder's model thread and the timing of its stages (issue 61).

A :class:`~drivenav.semantics.grounder_server.GrounderServer` of a model (not a stand-in) runs in two threads: its
socket thread receives and decodes requests, forms the batches and preprocesses them, and sends the replies; the
:class:`ModelThread` runs the model's forward and postprocessing and encodes the replies. The socket thread hands
over one prepared batch at a time while the model runs the one before, so that receiving, decoding and
preprocessing the next batch overlap the forward instead of following it. Until the model takes that batch, the
frames that come join it (:meth:`ModelThread.grow`, for a grounder whose preprocessed frames join,
:class:`JoinsPixels`): a batch closed as soon as it was handed over would run small, and the frames behind it would
wait a whole forward more. A served model's time is thus the forward's, plus the little the socket thread cannot
overlap.

:class:`ServerTimes` says where a served frame's time went: the server's busy seconds by stage (``decode``:
receiving and decoding a request; ``preprocess``, ``forward``, ``postprocess``: the grounder's stages, the forward
holding what a grounder that does not split its stages takes; ``reply``: checking the detections, packing the masks
and encoding the reply; ``send``), and the seconds each frame waited for its batch to start (``wait``).
"""

from __future__ import annotations

import contextlib
import logging
import math
import queue
import threading
import time
import uuid
from collections import Counter
from collections.abc import Callable, Iterator, Sequence
from dataclasses import dataclass, field
from typing import Any, Final, Protocol, runtime_checkable

import numpy as np
import zmq
from numpy.typing import NDArray

from drivenav.errors import one_line
from drivenav.semantics.protocols import Detection, Grounder
from drivenav.semantics.served import detections_reply
from drivenav.types import Observation
from drivenav.wire.protocol import Message, ProtocolError
from drivenav.wire.router import error_reply

log = logging.getLogger(__name__)

STAGES: Final[tuple[str, ...]] = ("decode", "wait", "preprocess", "forward", "postprocess", "reply", "send")
"""A served frame's stages, in order (module docstring)."""
MODEL_STAGES: Final[frozenset[str]] = frozenset({"preprocess", "forward", "postprocess"})
"""The grounder's own stages: what the frame costs in process too."""
SERVING_STAGES: Final[tuple[str, ...]] = ("decode", "reply", "send")
"""What serving adds to a frame's busy time: the stages that are neither the grounder's nor the queue's wait."""

Encoded = list[Any]
"""A reply's frames, ready to send (:meth:`~drivenav.wire.router.RouterSocket.frames`)."""


@runtime_checkable
class BatchGrounder(Protocol):
    """A grounder that segments one phrase in several frames in one forward (the transformers grounders)."""

    def segment_batch(self, frames: Sequence[NDArray[np.uint8]], phrase: str) -> list[list[Detection]]: ...


@runtime_checkable
class RowGrounder(Protocol):
    """A grounder that segments a different phrase in each row of one forward, its frames preprocessed apart (so
    that a server preprocesses the next batch while the model runs this one): the vision encoder once over the
    distinct frames, the rest once over the rows (the transformers grounders'
    :meth:`~drivenav.semantics.hf_common.TransformersGrounder.segment_rows`). A server batches the frames of
    workers looking for different objects, and a frame asked for several phrases (one ApexNav step) is encoded
    once."""

    def preprocess(self, frames: Sequence[NDArray[np.uint8]]) -> Any: ...

    def segment_rows(
        self,
        pixels: Any,
        frames: Sequence[NDArray[np.uint8]],
        rows: Sequence[tuple[int, str]],
        lap: Callable[[str], None] | None = None,
    ) -> list[list[Detection]]: ...


@runtime_checkable
class JoinsPixels(Protocol):
    """A :class:`RowGrounder` whose preprocessed frames can be joined into one batch (the transformers grounders:
    pixel tensors concatenated). A server's next batch, handed over while the model runs the one before, then takes
    the frames that come before the model is free (:meth:`ModelThread.grow`)."""

    def join_pixels(self, parts: Sequence[Any]) -> Any: ...


class DeviceStreams:
    """Where a served model's device work is queued (``device``; on the CPU each method does nothing).

    On CUDA the socket thread preprocesses on a stream of its own (:meth:`preprocessing`): on the device's default
    stream, its copy of the frames to the device (from pageable memory, which CUDA begins only once the stream's
    earlier work is done) would wait for the forward the model thread queued there, and the socket thread with it.
    A model thread makes its own stream wait for that one before it reads the pixels (:meth:`await_pixels`); a
    stage's time is its own stream's kernels (:meth:`sync`), not the next batch's preprocessing."""

    def __init__(self, device: str) -> None:
        self._stream: Any = None
        if device.startswith("cuda"):
            import torch

            self._stream = torch.cuda.Stream(device=device)  # type: ignore[no-untyped-call]

    def preprocessing(self) -> contextlib.AbstractContextManager[Any]:
        """The socket thread's preprocessing stream, current within the block."""
        if self._stream is None:
            return contextlib.nullcontext()
        import torch

        return torch.cuda.stream(self._stream)

    def await_pixels(self) -> None:
        """The calling thread's stream made to wait for every preprocessing queued so far (no host wait)."""
        if self._stream is not None:
            import torch

            torch.cuda.current_stream(self._stream.device).wait_stream(self._stream)

    def sync(self) -> None:
        """Wait for the calling thread's stream (a stage's time on a GPU is its kernels', not their launch)."""
        if self._stream is not None:
            import torch

            torch.cuda.current_stream(self._stream.device).synchronize()


@dataclass
class ServerTimes:
    """Seconds by stage (:data:`STAGES`; ``wait`` summed over frames, the others the server's busy time) over
    ``frames`` frames (requests: one a phrase) in ``batches`` batches, whose forwards encoded ``encoded`` images; of
    the ``received`` frames that came (a client's steps), each is encoded once where its requests came in one batch
    (a frame's phrases sent together, :meth:`encodings_per_frame`)."""

    frames: int = 0
    batches: int = 0
    seconds: dict[str, float] = field(default_factory=lambda: dict.fromkeys(STAGES, 0.0))
    encoded: int = 0
    received: int = 0

    def add(self, other: ServerTimes) -> ServerTimes:
        seconds = {stage: self.seconds[stage] + other.seconds[stage] for stage in STAGES}
        return ServerTimes(
            frames=self.frames + other.frames,
            batches=self.batches + other.batches,
            seconds=seconds,
            encoded=self.encoded + other.encoded,
            received=self.received + other.received,
        )

    def encodings_per_frame(self) -> float | None:
        """The images encoded a frame received: 1 where each frame's phrases were grounded in one batch, more where
        a frame was asked for a phrase later (prompt enrichment, Sec. IV-B: a new phrase on the same frame) or split
        between batches (none without frames)."""
        return round(self.encoded / self.received, 3) if self.received else None

    def per_frame_ms(self) -> dict[str, float]:
        """Each stage's milliseconds a frame (none without frames)."""
        if not self.frames:
            return {}
        return {stage: round(1000.0 * self.seconds[stage] / self.frames, 3) for stage in STAGES}

    def added_ms(self) -> float | None:
        """What serving adds to a frame's busy time beyond the grounder's own stages (decode, reply, send)."""
        if not self.frames:
            return None
        return round(1000.0 * sum(self.seconds[stage] for stage in SERVING_STAGES) / self.frames, 3)

    def line(self) -> str:
        """The breakdown in words (a server's last line)."""
        shown = ", ".join(f"{stage} {ms:g}" for stage, ms in self.per_frame_ms().items())
        return f"ms a frame: {shown}; added by serving {self.added_ms():g}" if self.frames else "no frames"


STEADY_MIN_S: Final[int] = 10
"""The shortest window, in seconds, over which :class:`SteadyRate` gives a rate."""


@dataclass(frozen=True)
class Steady:
    """Frames a second while every one of ``clients`` clients was grounding, over ``window_s`` whole seconds."""

    frames_per_second: float
    window_s: int
    clients: int

    def line(self) -> str:
        return f"steady {self.frames_per_second:g} frames a second over {self.window_s} s, {self.clients} clients"


class SteadyRate:
    """The frames (a client's steps) as they come, by client and by whole second since ``start`` (monotonic): the
    rate while every client that grounded was grounding, from the last one's first frame to the first one's last,
    leaves out an eval's start-up (workers still starting) and its tail (workers done, batches shrinking), which the
    eval's own rate includes: the rate a served model sustains (issue 61). A few numbers a client and one a second."""

    def __init__(self, start: float) -> None:
        self._start = start
        self._first: dict[bytes, float] = {}
        self._last: dict[bytes, float] = {}
        self._by_second: Counter[int] = Counter()

    def arrived(self, identity: bytes, now: float) -> None:
        """A frame of ``identity``'s (its first SEGMENT) came at ``now``."""
        self._first.setdefault(identity, now)
        self._last[identity] = now
        self._by_second[int(now - self._start)] += 1

    @property
    def frames(self) -> int:
        """The frames that came so far."""
        return sum(self._by_second.values())

    def steady(self) -> Steady | None:
        """The frames that came in the whole seconds when every client was grounding, a second; None when that
        window is shorter than :data:`STEADY_MIN_S`."""
        if not self._first:
            return None
        begin = math.ceil(max(self._first.values()) - self._start)
        end = math.floor(min(self._last.values()) - self._start)
        if end - begin < STEADY_MIN_S:
            return None
        frames = sum(self._by_second[second] for second in range(begin, end))
        return Steady(round(frames / (end - begin), 2), end - begin, len(self._first))


@dataclass
class Work:
    """Requests of frames of one size to be grounded in one forward: the requests' ``replies`` (client identity,
    request id, frame size), each request's ``rows`` entry (its frame's index in ``observations``, its phrase), the
    distinct frames' observations, and their pixels where the socket thread preprocessed them: one part, or several
    when frames joined the batch after it was handed over (:meth:`merge`). One phrase throughout unless the grounder
    is a :class:`RowGrounder`."""

    replies: list[tuple[bytes, str, tuple[int, int]]]
    rows: list[tuple[int, str]]
    observations: list[Observation]
    pixels: list[Any] = field(default_factory=list)

    @property
    def frames(self) -> list[NDArray[np.uint8]]:
        return [observation.rgb for observation in self.observations]

    @property
    def phrases(self) -> list[str]:
        """The distinct phrases, in the order of the rows."""
        return list(dict.fromkeys(phrase for _, phrase in self.rows))

    @property
    def size(self) -> tuple[int, ...]:
        """Its frames' size."""
        return tuple(self.observations[0].rgb.shape[:2])

    def merge(self, later: Work) -> None:
        """``later``'s requests (frames of the same size, preprocessed apart) added after this work's."""
        offset = len(self.observations)
        self.replies += later.replies
        self.rows += [(index + offset, phrase) for index, phrase in later.rows]
        self.observations += later.observations
        self.pixels += later.pixels


class ModelThread:
    """Grounds the batches the socket thread prepares (:class:`Work` lists), one at a time, and leaves each reply,
    encoded, in :attr:`outbox`; ``wake`` (an inproc PULL socket's address) is told when it takes a batch and when
    replies are there. One batch
    waits for the model at most, handed over (:meth:`put`) while the model runs the one before; until the model
    takes it, frames that come may join it (:meth:`grow`). :attr:`batch_sizes` counts the batches the model took, by
    their number of requests.

    ``check`` checks a frame's detections (as in process); ``encode`` makes a reply's frames; ``admit`` is called
    with a batch's phrase before it is grounded (the phrase cache); ``streams`` orders and times its device work."""

    def __init__(
        self,
        grounder: Grounder,
        context: zmq.Context[Any],
        wake: str,
        check: Callable[[Sequence[object], tuple[int, int]], list[Detection]],
        encode: Callable[[Message], Encoded],
        admit: Callable[[str], None],
        streams: DeviceStreams,
        name: str = "drivenav-grounder-model",
    ) -> None:
        self.grounder = grounder
        self.times = ServerTimes()
        self.outbox: queue.SimpleQueue[tuple[bytes, Encoded]] = queue.SimpleQueue()
        self._next: list[Work] | None = None
        self._stopping = False
        self._sizes: Counter[int] = Counter()
        self._handed = self._done = 0
        self._lock = threading.Condition()
        self._check, self._encode, self._admit, self._streams = check, encode, admit, streams
        self._signal = context.socket(zmq.PUSH)
        self._signal.setsockopt(zmq.LINGER, 0)
        self._signal.connect(wake)
        self._thread = threading.Thread(target=self._run, daemon=True, name=name)
        self._thread.start()

    @property
    def ready(self) -> bool:
        """Whether a prepared batch can be handed over now (the one before was taken)."""
        with self._lock:
            return self._next is None

    @property
    def batch_sizes(self) -> Counter[int]:
        with self._lock:
            return self._sizes.copy()

    def room(self, batch: int) -> int:
        """How many more frames the batch waiting for the model can take, up to ``batch`` (0 when none waits)."""
        with self._lock:
            return 0 if self._next is None else max(0, batch - sum(len(work.observations) for work in self._next))

    @property
    def idle(self) -> bool:
        """Whether it holds no batch, running or waiting."""
        with self._lock:
            return self._done == self._handed

    @property
    def handed(self) -> int:
        """How many batches were handed over so far."""
        with self._lock:
            return self._handed

    @property
    def done(self) -> int:
        """How many batches are done (their replies in :attr:`outbox`)."""
        with self._lock:
            return self._done

    def put(self, work: list[Work]) -> None:
        """Hand over ``work`` (:attr:`ready` first)."""
        with self._lock:
            self._handed += 1
            self._next = work
            self._lock.notify()

    def grow(self, more: list[Work]) -> bool:
        """``more`` joined to the batch waiting for the model, each part to the work of its frame size; False when
        the model took the batch first."""
        with self._lock:
            if self._next is None:
                return False
            for work in more:
                same = next((waiting for waiting in self._next if waiting.size == work.size), None)
                if same is None:
                    self._next.append(work)
                else:
                    same.merge(work)
            return True

    def stop(self) -> None:
        """Finish the batches handed over, then end the thread."""
        with self._lock:
            self._stopping = True
            self._lock.notify()
        self._thread.join()
        self._signal.close(linger=0)

    def _take(self) -> list[Work] | None:
        """The next batch, once handed over (None once stopping with none left)."""
        with self._lock:
            while self._next is None and not self._stopping:
                self._lock.wait()
            work, self._next = self._next, None
            if work is not None:
                self._sizes[sum(len(part.rows) for part in work)] += 1
        if work is not None:
            self._signal.send(b"", copy=True)  # the socket thread may hand over the next batch
        return work

    def _run(self) -> None:
        while (work := self._take()) is not None:
            try:
                for group in work:
                    self._ground(group)
            except Exception:  # a reply that could not be encoded: its client times out, the thread goes on
                log.exception("the model thread failed on a batch")
            finally:
                with self._lock:
                    self._done += 1
                self._signal.send(b"", copy=True)

    def _ground(self, work: Work) -> None:
        """Each request of ``work`` answered with its detections, or all with one ERROR when grounding failed."""
        mark = time.perf_counter()

        def lap(stage: str) -> None:
            nonlocal mark
            self._streams.sync()
            now = time.perf_counter()
            self.times.seconds[stage] += now - mark
            mark = now

        requests = zip(work.replies, work.rows, strict=True)
        asked = [(request_id, size, phrase) for (_, request_id, size), (_, phrase) in requests]
        replies = grounded_replies(asked, lambda: self._segment(work, lap), self._check)
        for (identity, _, _), reply in zip(work.replies, replies, strict=True):
            self.outbox.put((identity, self._encode(reply)))
        lap("reply")
        self.times.frames += len(work.rows)
        self.times.batches += 1
        self.times.encoded += len(work.observations)

    def _segment(self, work: Work, lap: Callable[[str], None]) -> list[list[Detection]]:
        """Each request's detections, in one forward where the grounder batches; the stages timed by ``lap``."""
        for phrase in work.phrases:
            self._admit(phrase)
        if work.pixels and isinstance(self.grounder, RowGrounder):
            self._streams.await_pixels()
            pixels = work.pixels[0]
            if len(work.pixels) > 1:
                assert isinstance(self.grounder, JoinsPixels)  # only such a grounder's batch grows
                pixels = self.grounder.join_pixels(work.pixels)
                lap("preprocess")
            return self.grounder.segment_rows(pixels, work.frames, work.rows, lap)
        (phrase,) = work.phrases
        if isinstance(self.grounder, BatchGrounder):
            found = self.grounder.segment_batch(work.frames, phrase)
        else:
            found = [self.grounder.segment(observation, phrase) for observation in work.observations]
        lap("forward")
        return found


def grounded_replies(
    asked: Sequence[tuple[str, tuple[int, int], str]],
    ground: Callable[[], list[list[Detection]]],
    check: Callable[[Sequence[object], tuple[int, int]], list[Detection]],
) -> list[Message]:
    """The replies to requests (``asked``: each request's id, frame size and phrase): DETECTIONS of what ``ground``
    found for each, checked as in process (``check``), or, where grounding failed, an ERROR each naming why (a
    request the server refuses, :class:`ProtocolError`, or the grounder's own failure, logged)."""
    try:
        found = ground()
        return [
            detections_reply(request_id, phrase, check(d, size), size)
            for (request_id, size, phrase), d in zip(asked, found, strict=True)
        ]
    except ProtocolError as error:
        return [error_reply(request_id, str(error)) for request_id, _, _ in asked]
    except Exception as error:
        log.exception("grounding %s failed", ", ".join(repr(p) for p in dict.fromkeys(p for _, _, p in asked)))
        return [error_reply(request_id, grounding_failed(error)) for request_id, _, _ in asked]


def grounding_failed(error: Exception) -> str:
    """An ERROR reply's words for a grounder (or its preprocessing) that raised ``error``."""
    return f"grounding failed: {one_line(error)}"


@dataclass
class Phrases:
    """The distinct phrases whose text features a shared grounder holds (emptied past ``limit``)."""

    limit: int
    seen: set[str] = field(default_factory=set)

    def admit(self, phrase: str, grounder: Grounder) -> None:
        if phrase in self.seen:
            return
        if len(self.seen) >= self.limit:
            grounder.begin_episode(None, 0)  # the transformers grounders forget their text features
            self.seen.clear()
        self.seen.add(phrase)


class ModelPool:
    """One :class:`ModelThread` per copy of the model (``copies``: several fill a GPU that one leaves idle), their
    replies announced on :attr:`wake` (a PULL socket the socket thread polls). A prepared batch goes to an idle copy
    where there is one, else to the first copy ready for one; each copy keeps its own phrases (``phrases`` at
    most)."""

    def __init__(
        self,
        copies: Sequence[Grounder],
        context: zmq.Context[Any],
        check: Callable[[Sequence[object], tuple[int, int]], list[Detection]],
        encode: Callable[[Message], Encoded],
        phrases: int,
        streams: DeviceStreams,
    ) -> None:
        address = f"inproc://drivenav-grounder-{uuid.uuid4().hex}"
        self.wake = context.socket(zmq.PULL)
        self.wake.setsockopt(zmq.LINGER, 0)
        self.wake.bind(address)
        self.threads = [
            ModelThread(copy, context, address, check, encode, _admit(Phrases(phrases), copy), streams, _name(i))
            for i, copy in enumerate(copies)
        ]

    @property
    def ready(self) -> bool:
        """Whether a copy can take a prepared batch now."""
        return any(thread.ready for thread in self.threads)

    def ticket(self) -> tuple[int, ...]:
        """Each copy's batches handed over so far: :meth:`passed` once all of them are done."""
        return tuple(thread.handed for thread in self.threads)

    def passed(self, ticket: tuple[int, ...]) -> bool:
        """Whether every batch each copy held at ``ticket`` is done (later ones aside)."""
        return all(thread.done >= handed for thread, handed in zip(self.threads, ticket, strict=True))

    @property
    def times(self) -> ServerTimes:
        total = ServerTimes()
        for thread in self.threads:
            total = total.add(thread.times)
        return total

    def put(self, work: list[Work]) -> None:
        """Hand ``work`` to an idle copy, else to the first copy ready for it (:attr:`ready` first): a batch does not
        wait behind another copy's forward while one is free."""
        ready = [thread for thread in self.threads if thread.ready]
        next((thread for thread in ready if thread.idle), ready[0]).put(work)

    def waiting(self, batch: int) -> tuple[ModelThread, int] | None:
        """A copy whose batch waiting for it can take more frames, and how many (up to ``batch``); none while a copy
        is idle (the frames are its next batch)."""
        if any(thread.idle for thread in self.threads):
            return None
        rooms = ((thread, thread.room(batch)) for thread in self.threads)
        return next(((thread, room) for thread, room in rooms if room > 0), None)

    @property
    def batch_sizes(self) -> Counter[int]:
        """The batches the copies took, by their number of requests."""
        return sum((thread.batch_sizes for thread in self.threads), Counter())

    def replies(self) -> Iterator[tuple[bytes, Encoded]]:
        """Every reply encoded so far (the wake socket's signals read)."""
        while self.wake.poll(0, zmq.POLLIN):
            self.wake.recv()
        for thread in self.threads:
            while not thread.outbox.empty():
                yield thread.outbox.get()

    def stop(self) -> None:
        for thread in self.threads:
            thread.stop()
        self.wake.close(linger=0)


def _admit(phrases: Phrases, grounder: Grounder) -> Callable[[str], None]:
    return lambda phrase: phrases.admit(phrase, grounder)


def _name(index: int) -> str:
    """A model thread's name: the first copy's plain, the others numbered from 2."""
    return "drivenav-grounder-model" + (f"-{index + 1}" if index else "")
