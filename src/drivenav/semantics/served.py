"""One grounder for every worker: the served grounder's protocol, ``--detector remote`` (issue 37).

``drivenav serve grounder`` (:mod:`drivenav.semantics.grounder_server`) holds one copy of the model and batches the
requests of every worker; a worker grounds through :class:`~drivenav.semantics.remote.RemoteGrounder`, a
:class:`~drivenav.semantics.protocols.Grounder` like the others, at ``models.detector_url``. The wire is the robot
protocol's framing (:mod:`drivenav.wire.protocol`: a JSON header and raw array frames, size and nesting limits,
never pickle; loopback by default, CURVE keys off it) under its own protocol name, ``drivenav-grounder``:

========== ======================================================== ===============================================
request    header and arrays                                        reply
========== ======================================================== ===============================================
HELLO      --                                                       WELCOME: :class:`ServedInfo` (the detector, its
                                                                    model, device and dtype, the images it reads,
                                                                    whether it reads ground-truth labels, batching)
BEGIN      ``episode`` key, ``seed``, the label ``names`` and their BEGUN (sent only to a server whose grounder
           ``canonical`` categories; arrays ``label_ids`` and        reads ground-truth labels: a stand-in, begun
           ``label_names`` (int32: instance id, index in names)     per episode as in process)
SEGMENT    ``episode``, ``phrase``, the frame's ``height`` and      DETECTIONS: ``phrase``; arrays ``masks`` (uint8
           ``width``, ``canonical`` (the phrase's category, for a   N x H x ceil(W / 8), each row's bits packed,
           stand-in); step, pose, intrinsics; arrays: the images    ``numpy.packbits``) and ``scores`` (float64)
           WELCOME names (``rgb`` uint8, ``depth`` float32,
           ``semantic`` int32); ``together`` (optional, 1-64):
           how many SEGMENTs of this frame were sent at once
PING       --                                                       PONG
========== ======================================================== ===============================================

A client may have several SEGMENTs out at once: the agent body tells the grounder a frame's phrases before it maps
the frame (:func:`~drivenav.semantics.protocols.prefetch`), the requests go out then, and each reply is collected
when the search asks for it (:meth:`~drivenav.wire.client.WireClient.submit`,
:meth:`~drivenav.wire.client.WireClient.reply_to`), so that the server grounds while the worker maps.

A malformed or unknown request gets an ERROR naming what was wrong, and the server keeps serving. Images and
scores travel exactly (depth as float32 metres, not the robot's millimetres), so served and in-process detections
are the same: exactly at batch one in fp32, and within a batched matrix product's rounding when the server batched
frames of several workers.

A request's reply must come ``models.detector_timeout_s`` after its sending, whatever else the server says
meanwhile (its PONGs show that it is there, not that it will answer; a server restarted on the same endpoint, which
never had the request, answers with another server id and fails it at once): else the request raises
:class:`GrounderUnavailableError` and the episode waiting on it ends as an ``error`` whose one line names the server.
Such an episode was lost to its server, not ended by its agent: a resume runs it again. An ERROR reply raises
:class:`GrounderRefusedError`, an answer like any other. The next episode's start asks the server once more; a server
still gone stops the run (:class:`~drivenav.errors.RunStoppedError`, finished episodes saved), as a robot gone does:
no run waits on a dead server.
"""

from __future__ import annotations

import math
from collections.abc import Callable, Mapping, Sequence
from dataclasses import asdict, dataclass
from typing import Any, Final

import numpy as np
from numpy.typing import NDArray

from drivenav.jsonstream import JsonObject
from drivenav.semantics.protocols import Detection
from drivenav.types import CategoryVocabulary, GroundTruth, Observation
from drivenav.wire.client import Dialect, PeerRefusedError, PeerUnavailableError, WireClient
from drivenav.wire.protocol import JSON, Message, ProtocolError

GROUNDER_PROTOCOL: Final[str] = "drivenav-grounder"
REQUESTS: Final[tuple[str, ...]] = ("HELLO", "BEGIN", "SEGMENT", "PING")
REPLIES: Final[tuple[str, ...]] = ("WELCOME", "BEGUN", "DETECTIONS", "PONG", "ERROR")
MAX_TOGETHER: Final[int] = 64
"""The most SEGMENTs a client may say it sends of one frame at once (``together``: one step's phrases)."""
MAX_PHRASE_CHARS: Final[int] = 512
"""A phrase longer than this is refused (an enriched prompt is a few words; the text encoders keep 16-32 tokens)."""
IMAGES: Final[dict[str, tuple[str, int]]] = {"rgb": ("|u1", 3), "depth": ("<f4", 2), "semantic": ("<i4", 2)}
"""The images a SEGMENT may carry: dtype and dimensions (``rgb`` is H x W x 3, the others H x W)."""
HELLO_TIMEOUT_S: Final[float] = 10.0
"""The longest wait for a WELCOME before any episode (a server still loading its model has not bound yet)."""
HEARTBEAT_S: Final[float] = 1.0
"""A waiting client's PING interval: the PONGs a server sends between batches show it is busy, not gone."""


MAX_TIMEOUT_S: Final[float] = 3600.0
"""The longest ``models.detector_timeout_s``: a request waits at most an hour for its reply."""


class GrounderUnavailableError(PeerUnavailableError):
    """The grounder server did not answer a request in time (gone, or stalled), or restarted while it waited."""


class GrounderRefusedError(GrounderUnavailableError, PeerRefusedError):
    """The grounder server answered a request with an ERROR (or with a reply of another type)."""


GROUNDER = Dialect(
    GROUNDER_PROTOCOL, REPLIES, "the grounder server", "--detector-keys", GrounderUnavailableError, GrounderRefusedError
)


class GrounderClient(WireClient):
    """Requests to a served grounder (a DEALER socket; one per thread)."""

    dialect = GROUNDER


@dataclass(frozen=True)
class ServedInfo:
    """What a server says of itself (WELCOME): its ``detector`` and ``model``, ``device`` and ``dtype``, the images
    its grounder reads (``observes``), whether it reads ground-truth labels (``labels``: a stand-in, begun per
    episode with BEGIN), and its batching (``batch`` frames or ``batch_ms`` milliseconds)."""

    detector: str
    model: str
    device: str
    dtype: str
    observes: tuple[str, ...]
    labels: bool
    batch: int
    batch_ms: float

    def to_json(self) -> JsonObject:
        return {**asdict(self), "observes": list(self.observes)}

    @staticmethod
    def from_json(body: Mapping[str, JSON]) -> ServedInfo:
        detector, model, device, dtype = (_text(body, name) for name in ("detector", "model", "device", "dtype"))
        observes = body.get("observes")
        if not isinstance(observes, list) or not all(name in IMAGES for name in observes):
            raise ProtocolError("body.observes", f"a list of image names ({', '.join(IMAGES)})", observes)
        labels, batch, batch_ms = body.get("labels"), body.get("batch"), body.get("batch_ms")
        if not isinstance(labels, bool):
            raise ProtocolError("body.labels", "true or false", labels)
        if isinstance(batch, bool) or not isinstance(batch, int) or batch < 1:
            raise ProtocolError("body.batch", "an integer >= 1", batch)
        if isinstance(batch_ms, bool) or not isinstance(batch_ms, (int, float)) or not math.isfinite(batch_ms):
            raise ProtocolError("body.batch_ms", "a finite number", batch_ms)
        return ServedInfo(detector, model, device, dtype, tuple(observes), labels, batch, float(batch_ms))


def _text(body: Mapping[str, JSON], name: str, limit: int = 256) -> str:
    value = body.get(name)
    if not isinstance(value, str) or len(value) > limit:
        raise ProtocolError(f"body.{name}", f"a string of at most {limit} characters", value)
    return value


# -- BEGIN: a stand-in's ground truth ------------------------------------------------------------------------------


class TableVocabulary:
    """A world's vocabulary as far as a served stand-in needs it: the categories of the names it was told (the
    episode's instance labels at BEGIN, each phrase with its SEGMENT). The stand-ins read :meth:`canonical` only."""

    def __init__(self, table: Mapping[str, str | None]) -> None:
        self.table: dict[str, str | None] = dict(table)

    def canonical(self, name: str) -> str | None:
        return self.table.get(name)

    def synonyms(self, category: str) -> tuple[str, ...]:
        return ()

    def categories(self) -> list[str]:
        return sorted({category for category in self.table.values() if category is not None})

    @property
    def room_types(self) -> tuple[str, ...]:
        return ()

    def room_shares(self, category: str) -> dict[str, float]:
        return {}


def begin_request(request_id: str, episode: str, truth: GroundTruth | None, seed: int) -> Message:
    """BEGIN of ``episode``: the ground truth a stand-in reads (its instance labels and their categories)."""
    labels = dict(truth.labels or {}) if truth is not None else {}
    names = sorted(set(labels.values()))
    index = {name: i for i, name in enumerate(names)}
    vocabulary = truth.vocabulary if truth is not None else None
    body: JsonObject = {
        "episode": episode,
        "seed": seed,
        "truth": truth is not None,
        "names": names,
        "canonical": None if vocabulary is None else [vocabulary.canonical(name) for name in names],
    }
    arrays: dict[str, NDArray[Any]] = {
        "label_ids": np.fromiter(labels, dtype=np.int32, count=len(labels)),
        "label_names": np.fromiter((index[labels[i]] for i in labels), dtype=np.int32, count=len(labels)),
    }
    return Message("BEGIN", request_id, body=body, arrays=arrays)


@dataclass(frozen=True)
class BeginRequest:
    """A BEGIN as the server reads it: the episode key, its seed and the ground truth to begin the stand-in with
    (its vocabulary a :class:`TableVocabulary` that each SEGMENT's phrase extends)."""

    episode: str
    seed: int
    truth: GroundTruth | None
    vocabulary: TableVocabulary | None


def read_begin(message: Message, max_labels: int) -> BeginRequest:
    """The BEGIN in ``message``; more than ``max_labels`` labels is refused before any is read."""
    body = message.body
    episode, seed = _episode(body), body.get("seed")
    if isinstance(seed, bool) or not isinstance(seed, int):
        raise ProtocolError("body.seed", "an integer", seed)
    names, canonical = body.get("names"), body.get("canonical")
    if not isinstance(names, list) or not all(isinstance(n, str) for n in names):
        raise ProtocolError("body.names", "a list of label names", names)
    ids, indices = (_int_vector(message, name) for name in ("label_ids", "label_names"))
    if ids.size > max_labels:
        raise ProtocolError(
            "arrays.label_ids", f"at most {max_labels} labels an episode (the server's limit)", ids.size
        )
    if ids.shape != indices.shape or bool(np.any((indices < 0) | (indices >= len(names)))):
        raise ProtocolError("arrays.label_names", f"one index in names (0-{len(names) - 1}) per label id", indices)
    vocabulary = None
    if canonical is not None:
        valid = isinstance(canonical, list) and len(canonical) == len(names)
        if not valid or not all(c is None or isinstance(c, str) for c in canonical):
            raise ProtocolError("body.canonical", "null or one category (or null) per name", canonical)
        vocabulary = TableVocabulary(dict(zip(names, canonical, strict=True)))
    if not body.get("truth", False):
        return BeginRequest(episode, seed, None, None)
    labels = {int(i): names[int(n)] for i, n in zip(ids.tolist(), indices.tolist(), strict=True)}
    return BeginRequest(episode, seed, GroundTruth(labels=labels, vocabulary=vocabulary), vocabulary)


def _int_vector(message: Message, name: str) -> NDArray[np.int32]:
    array = message.arrays.get(name)
    if array is None or array.dtype != np.int32 or array.ndim != 1:
        raise ProtocolError(f"arrays.{name}", "an int32 vector", None if array is None else array.shape)
    return array


def _episode(body: Mapping[str, JSON]) -> str:
    value = body.get("episode")
    if not isinstance(value, str) or not value or len(value) > 128:
        raise ProtocolError("body.episode", "an episode key (a non-empty string of at most 128 characters)", value)
    return value


# -- SEGMENT and DETECTIONS -------------------------------------------------------------------------------------------


def segment_request(
    request_id: str,
    episode: str,
    observation: Observation,
    phrase: str,
    observes: Sequence[str],
    vocabulary: CategoryVocabulary | None = None,
    together: int = 1,
) -> Message:
    """SEGMENT of ``phrase`` in ``observation``, carrying only the images in ``observes`` (a deferred RGB image
    is not rendered for a stand-in that reads none) and, with a ``vocabulary``, the phrase's category. ``together``
    > 1: the number of SEGMENTs of this frame sent at once (the server batches them together)."""
    height, width = observation.depth.shape[:2]
    body: JsonObject = {"episode": episode, "phrase": phrase, "height": height, "width": width}
    if vocabulary is not None:
        body["canonical"] = vocabulary.canonical(phrase)
    if together > 1:
        body["together"] = together
    arrays = {name: image for name in observes if (image := _image(observation, name)) is not None}
    return Message(
        "SEGMENT",
        request_id,
        step=observation.step,
        pose=observation.pose,
        intrinsics=observation.intrinsics,
        collided=observation.collided,
        body=body,
        arrays=arrays,
    )


def _image(observation: Observation, name: str) -> NDArray[Any] | None:
    """The observation's image called ``name`` (``rgb`` renders a deferred one)."""
    if name == "rgb":
        return observation.rgb
    return observation.depth if name == "depth" else observation.semantic


@dataclass(frozen=True)
class SegmentRequest:
    """A SEGMENT as the server reads it: the episode key, the phrase, its category when a vocabulary is in use
    (``canonical``: empty, or ``{phrase: category or None}``) and the observation rebuilt from what was sent."""

    request_id: str
    episode: str
    phrase: str
    canonical: Mapping[str, str | None]
    observation: Observation
    together: int = 1


def read_segment(message: Message) -> SegmentRequest:
    """The SEGMENT in ``message``, every image checked against the frame's size; an image not sent reads as
    absent (``semantic``), NaN (``depth``) or, for ``rgb``, an error when read."""
    body = message.body
    phrase = body.get("phrase")
    if not isinstance(phrase, str) or not phrase.strip():
        raise ProtocolError("body.phrase", "a phrase that is not blank (the object to ground)", phrase)
    if len(phrase) > MAX_PHRASE_CHARS:
        raise ProtocolError(
            "body.phrase", f"a phrase of at most {MAX_PHRASE_CHARS} characters", f"{len(phrase)} characters"
        )
    height, width = body.get("height"), body.get("width")
    if not all(isinstance(n, int) and not isinstance(n, bool) and n > 0 for n in (height, width)):
        raise ProtocolError("body.height/width", "the frame's size in pixels", (height, width))
    assert isinstance(height, int) and isinstance(width, int)
    for name, array in message.arrays.items():
        _check_image(name, array, (height, width))
    canonical = body.get("canonical")
    if canonical is not None and not isinstance(canonical, str):
        raise ProtocolError("body.canonical", "the phrase's category or null", canonical)
    if message.pose is None or message.intrinsics is None:
        raise ProtocolError("pose/intrinsics", "the frame's pose and camera intrinsics")
    arrays = message.arrays
    depth = arrays.get("depth")
    observation = Observation.deferred(
        _sent_rgb(arrays.get("rgb")),
        depth if depth is not None else np.broadcast_to(np.float32(np.nan), (height, width)),
        arrays.get("semantic"),
        message.pose,
        message.intrinsics,
        message.step,
        message.collided,
    )
    together = body.get("together", 1)
    if isinstance(together, bool) or not isinstance(together, int) or not 1 <= together <= MAX_TOGETHER:
        expected = f"the number of SEGMENTs of this frame sent at once, 1-{MAX_TOGETHER}"
        raise ProtocolError("body.together", expected, together)
    table = {phrase: canonical} if "canonical" in body else {}
    return SegmentRequest(message.request_id, _episode(body), phrase, table, observation, together)


def _check_image(name: str, array: NDArray[Any], size: tuple[int, int]) -> None:
    if name not in IMAGES:
        raise ProtocolError(f"arrays.{name}", f"one of the images {', '.join(IMAGES)}")
    dtype, ndim = IMAGES[name]
    expected = (*size, 3) if ndim == 3 else size
    if array.dtype.str != dtype or array.shape != expected:
        raise ProtocolError(f"arrays.{name}", f"{dtype} {expected}", f"{array.dtype.str} {array.shape}")


def _sent_rgb(rgb: NDArray[np.uint8] | None) -> Callable[[], NDArray[np.uint8]]:
    """The rendering call of a rebuilt observation's RGB image: the one sent, or an error naming what is missing."""

    def render() -> NDArray[np.uint8]:
        if rgb is None:
            raise ProtocolError("arrays.rgb", "the RGB image (this grounder reads it: the client sent none)")
        return rgb

    return render


def detections_reply(request_id: str, phrase: str, detections: Sequence[Detection], size: tuple[int, int]) -> Message:
    """DETECTIONS: the masks' rows bit-packed into one uint8 array, the scores as float64 (exact). Each mask is
    packed straight into its place (stacking the masks first copied each one whole: 2.5 times slower)."""
    masks = np.empty(_packed_shape(len(detections), size), dtype=np.uint8)
    for k, detection in enumerate(detections):
        if detection.mask.shape != size:
            raise ValueError(f"a detection mask of {detection.mask.shape}, not the frame's {size}")
        masks[k] = np.packbits(detection.mask, axis=-1)
    arrays: dict[str, NDArray[Any]] = {
        "masks": masks,
        "scores": np.array([d.score for d in detections], dtype=np.float64),
    }
    return Message("DETECTIONS", request_id, body={"phrase": phrase}, arrays=arrays)


def _packed_shape(count: int, size: tuple[int, int]) -> tuple[int, int, int]:
    """The shape of ``count`` masks of a frame of ``size`` with their rows bit-packed (a row's last byte padded)."""
    return count, size[0], (size[1] + 7) // 8


def read_detections(message: Message, phrase: str, size: tuple[int, int]) -> list[Detection]:
    """The detections of a DETECTIONS reply to ``phrase`` on a frame of ``size`` (a malformed one is a
    :class:`~drivenav.wire.protocol.ProtocolError`). Their scores are checked as an in-process grounder's are, by
    the :class:`~drivenav.semantics.checked.CheckedGrounder` the remote grounder is built in (one outside [0, 1]
    dropped, not the reply refused)."""
    masks, scores = message.arrays.get("masks"), message.arrays.get("scores")
    if scores is None or scores.dtype != np.float64 or scores.ndim != 1:
        raise ProtocolError("arrays.scores", "a float64 vector of scores")
    packed = _packed_shape(len(scores), size)
    if masks is None or masks.dtype != np.uint8 or masks.shape != packed:
        raise ProtocolError("arrays.masks", f"uint8 {packed}", None if masks is None else masks.shape)
    if message.body.get("phrase") != phrase:
        raise ProtocolError("body.phrase", repr(phrase), message.body.get("phrase"))
    unpacked = np.unpackbits(masks, axis=-1, count=size[1]).view(bool)  # zeros and ones: no copy
    return [Detection(unpacked[i], float(scores[i]), phrase) for i in range(len(scores))]
