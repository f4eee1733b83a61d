"""Grounding overlapped with mapping (issue 61): a served grounder is told a frame's phrases before the frame is
mapped, its SEGMENTs go out at once and are collected when the search asks, each reply reaching its own request; a
frame is grounded once per phrase; a request sent ahead and never asked for is dropped. Records are those of the
grounder asked in order (served runs' records are compared with in-process ones in tests/test_grounder_server.py).

Every server binds 127.0.0.1 (a free port) and is stopped by its test. No timing is asserted.
"""

from __future__ import annotations

import math
import time
from collections.abc import Sequence
from dataclasses import replace
from functools import partial

import pytest

from agent_scenes import episode_for, t_junction
from drivenav.agent.body import ExplorerAgent
from drivenav.agent.explorers import explorer_entry
from drivenav.agent.trace import Trace
from drivenav.agents import make_agent
from drivenav.envs.embedded.env import EmbeddedEnv
from drivenav.eval.runner import run_episode
from drivenav.semantics.embedded_detector import EmbeddedGrounder
from drivenav.semantics.embedding import default_embedder
from drivenav.semantics.grounder_server import GrounderServer, serving
from drivenav.semantics.protocols import Detection, Grounder, Prefetching, prefetch
from drivenav.semantics.registry import make_grounder, make_reasoner, make_scorer
from drivenav.semantics.remote import RemoteGrounder
from drivenav.semantics.serve_config import ServeConfig
from drivenav.semantics.served import GrounderClient, GrounderRefusedError, ServedInfo, segment_request
from drivenav.settings import explorer_section, load_settings
from drivenav.types import GroundTruth, Observation, SimConfig
from drivenav.wire.protocol import Message
from test_grounder_server import PHRASES, TRUTH, identical, observation, remote, served
from test_served_throughput import SlowStaged, frame, staged_server
from test_target_search import PhraseGrounder, _frame, _search

SIM = SimConfig()


class Counting:
    """A grounder that counts the frames it is asked to segment (the server's side of the wire)."""

    def __init__(self, inner: Grounder, asked: list[str]) -> None:
        self.inner, self.asked = inner, asked
        self.name = inner.name

    def begin_episode(self, truth: GroundTruth | None, seed: int) -> None:
        self.inner.begin_episode(truth, seed)

    def segment(self, observation: Observation, phrase: str) -> list[Detection]:
        self.asked.append(phrase)
        return self.inner.segment(observation, phrase)


def embedded() -> Grounder:
    return EmbeddedGrounder(default_embedder())


# --- the wire ---------------------------------------------------------------------------------------------------------


def test_requests_out_at_once_each_get_their_own_reply_in_any_order() -> None:
    frame = observation(4)
    with served(embedded, "embedded") as (server, info), remote(server.endpoint, info) as grounder:
        grounder.begin_episode(TRUTH, 5)
        connection = grounder.client
        requests = [segment_request(connection.next_id(), grounder._episode, frame, p, info.observes) for p in PHRASES]
        sent = [connection.submit(request) for request in requests]
        replies = [connection.reply_to(s) for s in reversed(sent)]
    assert [r.request_id for r in replies] == [r.request_id for r in reversed(requests)]
    assert [r.body["phrase"] for r in replies] == list(reversed(PHRASES))


def test_a_prefetched_frame_is_sent_once_a_phrase_and_answered_as_in_process() -> None:
    asked: list[str] = []
    local = embedded()
    local.begin_episode(TRUTH, 7)
    with (
        served(lambda: Counting(embedded(), asked), "embedded") as (server, info),
        remote(server.endpoint, info) as grounder,
    ):
        assert isinstance(grounder, Prefetching)
        grounder.begin_episode(TRUTH, 7)
        found = 0
        for step in range(3):
            frame = observation(step, step)
            grounder.prefetch(frame, PHRASES)
            for phrase in reversed(PHRASES):  # asked in another order than sent
                detections = grounder.segment(frame, phrase)
                assert identical(detections, local.segment(frame, phrase))
                found += len(detections)
        assert not grounder.client._outstanding and not grounder.client._early
    assert found > 0
    assert sorted(asked) == sorted(PHRASES * 3)  # each frame and phrase grounded once on the server


def test_requests_sent_ahead_for_a_frame_never_asked_for_are_dropped() -> None:
    """A frame prefetched and then not segmented (its episode went on otherwise): the next frame's answers are its
    own, and the late replies are neither kept nor taken for another request's."""
    local = embedded()
    local.begin_episode(TRUTH, 2)
    with served(embedded, "embedded") as (server, info), remote(server.endpoint, info) as grounder:
        grounder.begin_episode(TRUTH, 2)
        skipped, asked = observation(1, 1), observation(2, 2)
        grounder.prefetch(skipped, PHRASES)
        grounder.prefetch(asked, PHRASES[:2])
        for phrase in PHRASES:
            assert identical(grounder.segment(asked, phrase), local.segment(asked, phrase))
        grounder.prefetch(skipped, PHRASES)  # and again, ended by a new episode
        grounder.begin_episode(TRUTH, 2)
        assert identical(grounder.segment(asked, "sofa"), local.segment(asked, "sofa"))
        assert not grounder.client._outstanding and not grounder.client._early


def test_an_in_process_grounder_is_not_told_and_wrappers_pass_it_on() -> None:
    plain = PhraseGrounder(1, {"sofa"})
    prefetch(plain, _frame(0, 1), ("sofa",))  # no prefetch method: nothing happens
    assert not isinstance(plain, Prefetching) and plain.asked == []
    told: list[tuple[str, ...]] = []

    class Told(PhraseGrounder):
        def prefetch(self, observation: Observation, phrases: Sequence[str]) -> None:
            told.append(tuple(phrases))

    checked = make_grounder(load_settings("drive-nav").models)
    checked.inner = Told(1, {"sofa"})  # type: ignore[attr-defined]
    prefetch(checked, _frame(0, 1), ("sofa", "couch"))
    assert told == [("sofa", "couch")]


# --- the search and the body ------------------------------------------------------------------------------------------


def test_a_frame_is_grounded_once_a_phrase_however_often_the_search_asks() -> None:
    """The pending candidate's last frame (verify_now) is the frame observe grounded: the detector is not asked
    again; the next frame is."""
    grounder = PhraseGrounder(2, {"couch"})
    search = _search(grounder, "couch", verify=True)
    trace = Trace()
    frame = _frame(0, 2)
    search.observe(frame, trace)
    candidate = search.current()
    assert candidate is not None
    search.verify_now(frame, candidate.candidate_id, trace)
    assert grounder.asked == ["couch"]
    search.observe(_frame(1, 2), trace)
    assert grounder.asked == ["couch", "couch"]


class Logged:
    """A grounder that logs what it is told ahead and what it is asked, frame by frame."""

    def __init__(self, inner: Grounder) -> None:
        self.inner, self.name = inner, inner.name
        self.log: list[tuple[str, int, tuple[str, ...]]] = []

    def begin_episode(self, truth: GroundTruth | None, seed: int) -> None:
        self.inner.begin_episode(truth, seed)

    def prefetch(self, observation: Observation, phrases: Sequence[str]) -> None:
        self.log.append(("prefetch", observation.step, tuple(phrases)))

    def segment(self, observation: Observation, phrase: str) -> list[Detection]:
        self.log.append(("segment", observation.step, (phrase,)))
        return self.inner.segment(observation, phrase)


@pytest.mark.parametrize("method", ["drive-nav", "apexnav"])
def test_the_body_tells_the_grounder_every_phrase_of_a_frame_before_it_grounds_it(method: str) -> None:
    """Every frame grounded was announced first with the search's phrases (ApexNav's: the target and the objects
    it is confused with), each announced phrase grounded in that frame: no request goes out in vain."""
    settings = load_settings(method)
    entry = explorer_entry(settings.explorer.name)
    logged: list[Logged] = []

    def grounder() -> Grounder:
        logged.append(Logged(make_grounder(settings.models)))
        return logged[-1]

    reference = make_agent(settings)
    assert isinstance(reference, ExplorerAgent)
    agent = ExplorerAgent(
        settings.sim,
        settings.agent,
        settings.paper,
        settings.mapping,
        name=method,
        explorer=entry,
        explorer_config=explorer_section(settings, entry.name),
        reasoner_factory=partial(make_reasoner, settings.models),
        grounder_factory=grounder,
        requires=reference.requires,
        scorer_factory=partial(make_scorer, settings.models),
    )
    scene = t_junction(target_on_left=True)
    env = EmbeddedEnv(lambda _: scene, SIM)
    record, _ = run_episode(env, agent, episode_for(scene, (12.0, 2.5), math.pi / 2, "plant"), 0, 150)
    assert not record.error
    steps: dict[int, list[tuple[str, tuple[str, ...]]]] = {}
    for kind, step, phrases in logged[0].log:
        steps.setdefault(step, []).append((kind, phrases))
    assert steps, "the episode grounded nothing"
    expected = 1 if method == "drive-nav" else 2  # ApexNav: the target and what it is confused with
    for step, calls in steps.items():
        kind, announced = calls[0]
        assert kind == "prefetch" and len(announced) >= expected, (step, calls)
        grounded = [phrases[0] for kind, phrases in calls[1:] if kind == "segment"]
        assert grounded[: len(announced)] == list(announced), (step, calls)
    reference_record, _ = run_episode(
        env, make_agent(settings), episode_for(scene, (12.0, 2.5), math.pi / 2, "plant"), 0, 150
    )
    assert reference_record.success == record.success and reference_record.steps == record.steps


# --- one frame's requests in one batch --------------------------------------------------------------------------------


def sent_apart(config: ServeConfig, sent: int, gap_s: float) -> tuple[GrounderServer, list[Message], float]:
    """A frame's three SEGMENTs said to go together (``together`` 3), the first sent alone and ``sent`` - 1 more
    ``gap_s`` later, to a server with ``config``: the server, the replies and the seconds the first one took."""
    server = staged_server(SlowStaged(forward_s=0.0), config)
    with serving(server) as endpoint:
        connection = GrounderClient(endpoint)
        try:
            info = ServedInfo.from_json(connection.request(Message("HELLO", connection.next_id())).body)
            remote = RemoteGrounder(connection, info)
            remote.begin_episode(None, 0)
            shown = frame(7, 4)
            requests = [
                segment_request(connection.next_id(), remote._episode, shown, p, ("rgb",), None, 3) for p in "abc"
            ]
            start = time.monotonic()
            out = [connection.submit(requests[0])]
            if sent > 1:
                time.sleep(gap_s)
                out += [connection.submit(request) for request in requests[1:sent]]
            replies = [connection.reply_to(out[0])]
            first_s = time.monotonic() - start
            replies += [connection.reply_to(s) for s in out[1:]]
        finally:
            connection.close()
    return server, replies, first_s


@pytest.mark.parametrize("batch_ms", [1000.0, 0.0])
def test_a_batch_waits_for_every_request_a_client_sent_of_its_frame_at_once(batch_ms: float) -> None:
    """A frame's three SEGMENTs, the last two sent 0.3 s after the first (a sender descheduled between them): the
    server runs the three as one batch rather than the first alone, whether its batch may wait 1 s or not at all (a
    frame in parts is no batch's until its rest come; before, a batch due took the first alone and the frame was
    encoded twice)."""
    server, replies, _ = sent_apart(ServeConfig(batch=8, batch_ms=batch_ms), 3, 0.3)
    assert [r.type for r in replies] == ["DETECTIONS"] * 3
    assert server.batch_sizes == {3: 1}


def test_a_frame_whose_client_sent_fewer_requests_than_it_said_is_grounded_after_parts_s() -> None:
    """A client said three SEGMENTs of a frame go together and sent one: the server grounds it once it has waited
    ``parts_s`` for the others, and goes on."""
    server, replies, first_s = sent_apart(ServeConfig(batch=8, batch_ms=0.0, parts_s=0.5), 1, 0.0)
    assert [r.type for r in replies] == ["DETECTIONS"] and server.batch_sizes == {1: 1}
    assert 0.5 <= first_s < 5.0


@pytest.mark.parametrize("together", [0, 65, "3", True])
def test_a_together_that_is_not_a_count_of_requests_is_refused(together: object) -> None:
    with served(embedded, "embedded") as (server, info), remote(server.endpoint, info) as grounder:
        grounder.begin_episode(TRUTH, 1)
        request = segment_request(grounder.client.next_id(), grounder._episode, observation(), "sofa", info.observes)
        request = replace(request, body={**request.body, "together": together})
        with pytest.raises(GrounderRefusedError, match=r"body\.together"):
            grounder.client.request(request)
        assert grounder.segment(observation(), "sofa") is not None  # the server goes on
