"""The served grounder's client side (:mod:`drivenav.semantics.served`'s protocol): :class:`RemoteGrounder`, the
``--detector remote`` backend that grounds with a ``drivenav serve grounder`` (reached, checked and timed out as the
protocol's docstring says), and :class:`ShadowedGrounder`, a detector whose every frame is also sent to a served
model and its answer discarded (``--detector-shadow-url``: a served model's cost beside the detector's detections)."""

from __future__ import annotations

import functools
import uuid
from collections.abc import Sequence
from dataclasses import replace
from pathlib import Path

from drivenav.errors import InputError, RunStoppedError
from drivenav.semantics.model_spec import ModelSpec
from drivenav.semantics.protocols import Detection, Grounder, prefetch
from drivenav.semantics.registry import GROUNDER_BACKENDS
from drivenav.semantics.served import (
    HEARTBEAT_S,
    HELLO_TIMEOUT_S,
    MAX_TIMEOUT_S,
    GrounderClient,
    GrounderRefusedError,
    GrounderUnavailableError,
    ServedInfo,
    begin_request,
    read_detections,
    segment_request,
)
from drivenav.types import CategoryVocabulary, GroundTruth, Observation
from drivenav.wire.client import ClientConfig, PeerUnavailableError, Sent
from drivenav.wire.protocol import Message, ProtocolError
from drivenav.wire.security import check_endpoint, client_keys, is_loopback


class GrounderGoneError(RunStoppedError):
    """The served grounder did not answer at an episode's start (``cause``): the run stops, finished episodes saved.
    Its line is advice for a server of the user's (``--detector remote``): restart or fix it, then rerun; the run's
    own server (``eval --share-detector``) is served anew by a rerun, and says so instead
    (:func:`~drivenav.eval.shared_detector.shared_detector`). Pickled as its ``cause`` (from a worker)."""

    def __init__(self, cause: str) -> None:
        super().__init__(cause)
        self.cause = cause

    def __str__(self) -> str:
        return (
            f"{self.cause} (at an episode's start): finished episodes are saved; restart or fix the grounder server "
            "(drivenav serve grounder) and rerun the same command to resume"
        )


# -- the client -------------------------------------------------------------------------------------------------------


class RemoteGrounder:
    """Implements :class:`~drivenav.semantics.protocols.Grounder` with a served grounder (module docstring).

    Each episode has a fresh key; a server that grounds with a stand-in is sent the episode's ground truth
    (BEGIN), any other is asked whether it is there (PING).
    """

    name = "remote"

    def __init__(self, client: GrounderClient, info: ServedInfo) -> None:
        self.client = client
        self.info = info
        self._episode = ""
        self._vocabulary: CategoryVocabulary | None = None
        self._frame: Observation | None = None  # the frame whose requests are out (:meth:`prefetch`)
        self._out: dict[str, Sent] = {}  # its SEGMENTs sent ahead, by phrase

    def begin_episode(self, truth: GroundTruth | None, seed: int) -> None:
        """Begin an episode on the server; a server that does not answer (or refuses) stops the run (one line)."""
        self._drop_prefetched()
        self._episode = uuid.uuid4().hex
        self._vocabulary = truth.vocabulary if truth is not None and self.info.labels else None
        request = (
            begin_request(self.client.next_id(), self._episode, truth, seed)
            if self.info.labels
            else Message("PING", self.client.next_id())
        )
        try:
            self.client.request(request)
        except GrounderUnavailableError as error:
            raise GrounderGoneError(str(error)) from None

    def prefetch(self, observation: Observation, phrases: Sequence[str]) -> None:
        """Send the SEGMENTs of ``phrases`` in ``observation`` now, all at once (the server may batch them): the
        server grounds the frame while the agent maps it, and :meth:`segment` then waits only for what is left.
        Requests sent ahead for another frame and never asked for are dropped."""
        if observation is not self._frame:
            self._drop_prefetched()
            self._frame = observation
        new = [phrase for phrase in dict.fromkeys(phrases) if phrase not in self._out]
        requests = {phrase: self._request(observation, phrase, len(new)) for phrase in new}
        for phrase, request in requests.items():  # made first, then sent back to back: one batch takes them all
            self._out[phrase] = self.client.submit(request)

    def segment(self, observation: Observation, phrase: str) -> list[Detection]:
        """The server's detections of ``phrase`` in the frame (a :class:`GrounderUnavailableError` when it does
        not answer in time or refuses), from the request :meth:`prefetch` sent where it sent one."""
        if observation is not self._frame:
            self._drop_prefetched()
        sent = self._out.pop(phrase, None)
        reply = self.client.reply_to(sent or self.client.submit(self._request(observation, phrase)))
        if reply.type != "DETECTIONS":
            raise GrounderRefusedError(f"the grounder server answered {reply.type} to SEGMENT")
        height, width = observation.depth.shape[:2]
        return read_detections(reply, phrase, (height, width))

    def _request(self, observation: Observation, phrase: str, together: int = 1) -> Message:
        return segment_request(
            self.client.next_id(), self._episode, observation, phrase, self.info.observes, self._vocabulary, together
        )

    def _drop_prefetched(self) -> None:
        for sent in self._out.values():
            self.client.forget(sent)
        self._out.clear()
        self._frame = None


@functools.cache
def _connection(url: str, keys: str, timeout_s: float) -> tuple[GrounderClient, ServedInfo]:
    """This process's client of the server at ``url`` and what it said in its WELCOME (one connection a process,
    kept for its episodes)."""
    hello = GrounderClient(url, Path(keys) if keys else None, ClientConfig(min(timeout_s, HELLO_TIMEOUT_S), 0))
    try:
        info = ServedInfo.from_json(hello.request(Message("HELLO", hello.next_id())).body)
    finally:
        hello.close()
    config = ClientConfig(timeout_s=timeout_s, retries=0, heartbeat_s=min(HEARTBEAT_S, timeout_s))
    return GrounderClient(url, Path(keys) if keys else None, config), info


def connect(spec: ModelSpec) -> tuple[GrounderClient, ServedInfo]:
    """The connection to ``spec``'s server and its WELCOME; a server that runs another detector than
    ``detector_served`` says is an :class:`~drivenav.errors.InputError`."""
    client, info = _connection(spec.detector_url, spec.detector_keys, spec.detector_timeout_s)
    if spec.detector_served and info.detector != spec.detector_served:
        expected = f"{info.detector} (what the server at {spec.detector_url} runs)"
        raise InputError("settings", "models.detector_served", expected, spec.detector_served)
    if info.labels and not spec.detector_served:
        expected = f"{info.detector}: the server runs a stand-in that reads ground-truth labels"
        raise InputError("settings", "models.detector_served", expected, "(empty)")
    return client, info


def remote_grounder(spec: ModelSpec) -> RemoteGrounder:
    """``--detector remote``: a grounder served at ``models.detector_url``."""
    client, info = connect(spec)
    return RemoteGrounder(client, info)


def reach_server(spec: ModelSpec, option: str = "--detector-url") -> None:
    """The server at ``detector_url`` answers HELLO: else one line naming ``option`` (before any episode)."""
    try:
        connect(spec)
    except (PeerUnavailableError, ProtocolError) as error:
        expected = "a grounder server that answers (drivenav serve grounder)"
        raise InputError("command line", option, expected, f"{spec.detector_url}: {error}") from None


def check_detector_url(spec: ModelSpec, option: str = "--detector-url") -> None:
    """``detector_url`` (set by ``option``) is an endpoint; off loopback it needs ``detector_keys`` (CURVE), whose
    files are read now; ``detector_timeout_s`` is a wait a request can have (more than 0 s, at most
    :data:`MAX_TIMEOUT_S`); ``detector_served`` names a detector run in process (or nothing)."""
    timeout_s = spec.detector_timeout_s
    if not (0.0 < timeout_s <= MAX_TIMEOUT_S):
        expected = f"the seconds a request may wait for its reply, more than 0 and at most {MAX_TIMEOUT_S:g}"
        raise InputError("settings", "models.detector_timeout_s", expected, timeout_s)
    check_endpoint(spec.detector_url, option)
    if spec.detector_keys:
        client_keys(Path(spec.detector_keys), "--detector-keys")
    elif not is_loopback(spec.detector_url):
        expected = "a key folder (drivenav robot keys DIR) to reach a grounder off this host: CURVE is required"
        raise InputError("command line", "--detector-keys", expected, spec.detector_url)
    local = [name for name in GROUNDER_BACKENDS.names if name != "remote"]
    if spec.detector_served and spec.detector_served not in local:
        expected = f"empty or one of {', '.join(local)}"
        raise InputError("settings", "models.detector_served", expected, spec.detector_served)


# -- a served model's cost beside another grounder's detections -------------------------------------------------------


SHADOW_OPTION = "--detector-shadow-url"


def shadow_spec(spec: ModelSpec) -> ModelSpec:
    """The served grounder at ``detector_shadow_url`` as a ``remote`` detector's settings."""
    return replace(spec, detector="remote", detector_url=spec.detector_shadow_url, detector_served="")


class ShadowedGrounder:
    """Implements :class:`~drivenav.semantics.protocols.Grounder` with ``grounder``'s detections, every request also
    sent to a served grounder (``shadow``) whose answer is discarded: an episode pays what the served model costs
    (the wire, the batch, the forward), and its agent acts on ``grounder``'s answers. A throughput benchmark of a
    real model with random weights (``models.detector_shadow_url``), whose own detections would be noise."""

    def __init__(self, grounder: Grounder, shadow: RemoteGrounder) -> None:
        self.grounder = grounder
        self.shadow = shadow
        self.name = grounder.name

    def begin_episode(self, truth: GroundTruth | None, seed: int) -> None:
        self.grounder.begin_episode(truth, seed)
        self.shadow.begin_episode(truth, seed)

    def prefetch(self, observation: Observation, phrases: Sequence[str]) -> None:
        """The served copy's requests go out at once; the detector's own detections are made when asked for."""
        self.shadow.prefetch(observation, phrases)
        prefetch(self.grounder, observation, phrases)

    def segment(self, observation: Observation, phrase: str) -> list[Detection]:
        self.shadow.segment(observation, phrase)
        return self.grounder.segment(observation, phrase)


def shadowed(grounder: Grounder, spec: ModelSpec) -> ShadowedGrounder:
    """``grounder`` shadowed by the served grounder at ``spec.detector_shadow_url`` (a model server: a stand-in that
    reads labels is refused, as for ``remote``)."""
    return ShadowedGrounder(grounder, remote_grounder(shadow_spec(spec)))
