"""Served grounding at the model's speed (issue 61): the server's model thread (the next batch decoded and
preprocessed while the model runs the current one), where a served frame's time goes (``ServerTimes``), the eval's
rate (episodes an hour, frames a second: on its bar and in ``summary.json``) and ``bench eval-throughput``.

No speed is asserted: the figures have to be there and add up; what overlaps is checked from recorded intervals.
"""

from __future__ import annotations

import contextlib
import json
import signal
import subprocess
import sys
import threading
import time
from collections.abc import Callable, Iterator, Sequence
from pathlib import Path
from types import SimpleNamespace
from typing import Any, cast

import numpy as np
import pytest
from numpy.typing import NDArray

from conftest import run_cli, until_records
from drivenav.benchmarks.throughput_bench import run_for
from drivenav.cli import main
from drivenav.eval.report import Summary, Throughput, rate_kept, summarize
from drivenav.semantics import grounder_server
from drivenav.semantics.grounder_server import GrounderServer, serving
from drivenav.semantics.protocols import Detection
from drivenav.semantics.remote import RemoteGrounder
from drivenav.semantics.serve_config import ServeConfig
from drivenav.semantics.serve_pipeline import STAGES, ModelPool, RowGrounder, ServerTimes, SteadyRate
from drivenav.semantics.served import GrounderClient, SegmentRequest, ServedInfo
from drivenav.types import CameraIntrinsics, GroundTruth, Observation, Pose
from drivenav.wire.protocol import Message

LOOPBACK = "tcp://127.0.0.1:*"
RUN = ["eval", "--agent", "directional", "--scenes", "procedural:2", "--episodes", "2", "--seed", "2"]
RUN += ["--max-steps", "12", "--set", "sim.width=160", "--set", "sim.height=120"]


# --- the breakdown ---------------------------------------------------------------------------------------------------


def test_server_times_are_milliseconds_a_frame_and_serving_adds_what_is_not_the_model() -> None:
    seconds = dict.fromkeys(STAGES, 0.0)
    seconds.update(decode=0.004, wait=0.4, preprocess=0.02, forward=0.2, postprocess=0.04, reply=0.008, send=0.004)
    times = ServerTimes(frames=8, batches=2, seconds=seconds)
    assert times.per_frame_ms() == {
        "decode": 0.5,
        "wait": 50.0,
        "preprocess": 2.5,
        "forward": 25.0,
        "postprocess": 5.0,
        "reply": 1.0,
        "send": 0.5,
    }
    assert times.added_ms() == 2.0  # decode, reply, send: not the grounder's stages, not the queue
    both = times.add(times)
    assert (both.frames, both.batches, both.seconds["forward"]) == (16, 4, 0.4)
    assert ServerTimes().per_frame_ms() == {} and ServerTimes().added_ms() is None
    assert "added by serving 2" in times.line()


# --- the model thread ------------------------------------------------------------------------------------------------


class SlowStaged:
    """A staged grounder whose forward takes ``forward_s``: it records where (which thread) and when each stage ran,
    and finds one full-frame detection scored by the frame's first pixel."""

    name = "slow-staged"

    def __init__(self, forward_s: float) -> None:
        self.forward_s = forward_s
        self.spans: list[tuple[str, str, float, float]] = []
        self.lock = threading.Lock()

    def _span(self, stage: str, start: float) -> None:
        with self.lock:
            self.spans.append((stage, threading.current_thread().name, start, time.perf_counter()))

    def begin_episode(self, truth: GroundTruth | None, seed: int) -> None:
        pass

    def segment(self, observation: Observation, phrase: str) -> list[Detection]:
        return self.segment_batch([observation.rgb], phrase)[0]

    def segment_batch(self, frames: Sequence[NDArray[np.uint8]], phrase: str) -> list[list[Detection]]:
        return self.segment_rows(self.preprocess(frames), frames, [(i, phrase) for i in range(len(frames))])

    def preprocess(self, frames: Sequence[NDArray[np.uint8]]) -> Any:
        start = time.perf_counter()
        pixels = [float(frame[0, 0, 0]) / 255.0 for frame in frames]
        self._span("preprocess", start)
        return pixels

    def join_pixels(self, parts: Sequence[list[float]]) -> list[float]:
        return [value for part in parts for value in part]

    def segment_rows(
        self,
        pixels: Any,
        frames: Sequence[NDArray[np.uint8]],
        rows: Sequence[tuple[int, str]],
        lap: Callable[[str], None] | None = None,
    ) -> list[list[Detection]]:
        start = time.perf_counter()
        time.sleep(self.forward_s)
        self._span("forward", start)
        if lap is not None:
            lap("forward")
        found = [[Detection(np.ones(frames[i].shape[:2], dtype=bool), pixels[i], phrase)] for i, phrase in rows]
        if lap is not None:
            lap("postprocess")
        return found


def frame(value: int, step: int = 0) -> Observation:
    return Observation(
        rgb=np.full((24, 32, 3), value, dtype=np.uint8),
        depth=np.ones((24, 32), dtype=np.float32),
        semantic=None,
        pose=Pose(0.0, 0.0, 0.0),
        intrinsics=CameraIntrinsics.from_hfov(32, 24, 79.0),
        step=step,
        collided=False,
    )


def staged_server(grounder: SlowStaged, config: ServeConfig) -> GrounderServer:
    info = ServedInfo("slow-staged", "-", "cpu", "float32", ("rgb",), False, config.batch, config.batch_ms)
    return GrounderServer(lambda: grounder, info, LOOPBACK, None, config)


def ground(
    endpoint: str,
    values: list[int],
    answers: dict[int, float],
    ready: threading.Barrier,
    go: threading.Event | None = None,
) -> None:
    """A frame of each value grounded in turn (its score in ``answers``), the client connected and its episode begun
    before ``ready`` (a PING at an episode's start waits for the model's batches in hand), and after ``go`` is set
    where given."""
    client = GrounderClient(endpoint)
    try:
        info = ServedInfo.from_json(client.request(Message("HELLO", client.next_id())).body)
        grounder = RemoteGrounder(client, info)
        grounder.begin_episode(None, 0)
        ready.wait()
        if go is not None:
            go.wait(10.0)
        for step, value in enumerate(values):
            (detection,) = grounder.segment(frame(value, step), "chair")
            answers[value] = detection.score
    finally:
        client.close()


def two_frames_each(server: GrounderServer, clients: int) -> None:
    """``clients`` clients at ``server``, started together, each grounding two frames of its own (client ``c``: 10c + 1
    and 10c + 2); each gets its own frames' answers."""
    answers: dict[int, float] = {}
    ready = threading.Barrier(clients)
    with serving(server) as endpoint:
        threads = [
            threading.Thread(target=ground, args=(endpoint, [10 * c + 1, 10 * c + 2], answers, ready))
            for c in range(clients)
        ]
        for thread in threads:
            thread.start()
        for thread in threads:
            thread.join()
    assert answers == {v: pytest.approx(v / 255.0) for c in range(clients) for v in (10 * c + 1, 10 * c + 2)}


def test_the_next_batch_is_preprocessed_on_the_socket_thread_while_the_model_runs() -> None:
    """Four clients, batches of up to 2 frames, a 150 ms forward: the model runs on its own thread, and a batch's
    preprocessing overlaps the forward of the batch before; every client gets its own frame's answer."""
    grounder = SlowStaged(forward_s=0.15)
    server = staged_server(grounder, ServeConfig(batch=2, batch_ms=0.0))
    two_frames_each(server, 4)
    forwards = [(start, end) for stage, _, start, end in grounder.spans if stage == "forward"]
    preprocessed = [(name, start, end) for stage, name, start, end in grounder.spans if stage == "preprocess"]
    assert {name for stage, name, _, _ in grounder.spans if stage == "forward"} == {"drivenav-grounder-model"}
    assert {name for name, _, _ in preprocessed} == {"drivenav-grounder-server"}
    overlapping = [p for p in preprocessed if any(f0 < p[1] and p[2] < f1 for f0, f1 in forwards)]
    assert overlapping, "no batch was preprocessed while the model ran the one before"
    times = server.times
    assert times.frames == 8 == sum(n * c for n, c in server.batch_sizes.items())
    assert times.batches == sum(server.batch_sizes.values())
    assert times.seconds["forward"] >= 0.15 * times.batches * 0.9
    assert all(seconds >= 0.0 for seconds in times.seconds.values())


def until(condition: Callable[[], bool], timeout_s: float = 10.0) -> None:
    deadline = time.monotonic() + timeout_s
    while not condition():
        assert time.monotonic() < deadline, "timed out"
        time.sleep(0.005)


@contextlib.contextmanager
def cued_clients(
    server: GrounderServer, values: Sequence[int]
) -> Iterator[tuple[ModelPool, dict[int, threading.Event], dict[int, float]]]:
    """``server`` serving a client for each value, each connected and its episode begun; within the block, setting
    a value's event makes its client ground one frame of it (its answer in the dict). The clients are joined at the
    block's end."""
    answers: dict[int, float] = {}
    ready, go = threading.Barrier(len(values) + 1), {value: threading.Event() for value in values}
    with serving(server) as endpoint:
        threads = [threading.Thread(target=ground, args=(endpoint, [v], answers, ready, go[v])) for v in values]
        for thread in threads:
            thread.start()
        assert server._model is not None
        ready.wait()
        yield server._model, go, answers
        for thread in threads:
            thread.join()


def test_frames_that_come_while_the_next_batch_waits_for_the_model_join_it() -> None:
    """A 1 s forward runs client A's frame; B's frame is then handed over as the next batch at once (batch_ms 0), and
    C's and D's, coming while it waits for the model, join it: two batches (1 and 3 frames), not three, C's and D's
    frames preprocessed while A's forward ran, and every client its own frame's answer."""
    grounder = SlowStaged(forward_s=1.0)
    server = staged_server(grounder, ServeConfig(batch=8, batch_ms=0.0))
    with cued_clients(server, (1, 2, 3, 4)) as (model, go, answers):
        go[1].set()
        until(lambda: model.ticket() == (1,) and model.ready)  # A's batch taken
        go[2].set()
        until(lambda: model.waiting(8) is not None)  # B's batch handed over, waiting
        go[3].set()
        go[4].set()
    assert answers == {v: pytest.approx(v / 255.0) for v in go}
    assert server.batch_sizes == {1: 1, 3: 1}
    a_done = min(end for stage, _, _, end in grounder.spans if stage == "forward")
    assert all(end < a_done for stage, _, _, end in grounder.spans if stage == "preprocess")


class RecordingStreams:
    """Stands in for a CUDA device's streams: records, in order, what each thread asked of them."""

    def __init__(self, device: str) -> None:
        self.calls: list[tuple[str, str]] = []
        self.preprocessing_now = False

    def _record(self, what: str) -> None:
        self.calls.append((what, threading.current_thread().name))

    @contextlib.contextmanager
    def preprocessing(self) -> Iterator[None]:
        self._record("preprocessing")
        self.preprocessing_now = True
        try:
            yield
        finally:
            self.preprocessing_now = False

    def await_pixels(self) -> None:
        self._record("await_pixels")

    def sync(self) -> None:
        self._record("sync")


def test_the_socket_thread_preprocesses_on_its_stream_and_the_model_awaits_it(monkeypatch: pytest.MonkeyPatch) -> None:
    """On a GPU the frames are preprocessed on the socket thread's own stream, and the model thread's stream waits for
    it before the forward reads the pixels, then times its stages by its own stream (DeviceStreams; a fake here)."""
    made: list[RecordingStreams] = []
    monkeypatch.setattr(
        grounder_server, "DeviceStreams", lambda device: made.append(RecordingStreams(device)) or made[-1]
    )
    grounder = SlowStaged(forward_s=0.0)
    inside: list[bool] = []
    preprocess = grounder.preprocess
    grounder.preprocess = lambda frames: inside.append(made[0].preprocessing_now) or preprocess(frames)  # type: ignore[method-assign]
    server = staged_server(grounder, ServeConfig(batch=1, batch_ms=0.0))
    answers: dict[int, float] = {}
    with serving(server) as endpoint:
        ground(endpoint, [7, 8], answers, threading.Barrier(1))
    assert answers == {v: pytest.approx(v / 255.0) for v in (7, 8)} and inside == [True, True]
    calls = made[0].calls
    assert [what for what, name in calls if name == "drivenav-grounder-server"] == ["preprocessing"] * 2
    model = [what for what, name in calls if name == "drivenav-grounder-model"]
    assert model == ["await_pixels", "sync", "sync", "sync"] * 2  # then forward, postprocess, reply


def test_two_copies_of_a_model_run_two_batches_at_once() -> None:
    """``copies=2``: two model threads, each with its own copy; batches of one frame from four clients run on both
    at the same time, and each client still gets its own frame's answer."""
    first, second = SlowStaged(forward_s=0.15), SlowStaged(forward_s=0.15)
    second.spans, second.lock = first.spans, first.lock
    copies = iter([first, second])
    config = ServeConfig(batch=1, batch_ms=0.0, copies=2)
    info = ServedInfo("slow-staged", "-", "cpu", "float32", ("rgb",), False, 1, 0.0)
    server = GrounderServer(lambda: next(copies), info, LOOPBACK, None, config)
    answers: dict[int, float] = {}
    ready = threading.Barrier(4)
    with serving(server) as endpoint:
        threads = [threading.Thread(target=ground, args=(endpoint, [c + 1, c + 11], answers, ready)) for c in range(4)]
        for thread in threads:
            thread.start()
        for thread in threads:
            thread.join()
    assert answers == {v: pytest.approx(v / 255.0) for c in range(4) for v in (c + 1, c + 11)}
    forwards = [(name, start, end) for stage, name, start, end in first.spans if stage == "forward"]
    names = {name for name, _, _ in forwards}
    assert names == {"drivenav-grounder-model", "drivenav-grounder-model-2"}
    together = [
        (a, b) for a in forwards for b in forwards if a[0] != b[0] and a[1] < b[1] < a[2]
    ]  # one copy's forward began while the other's ran
    assert together
    assert server.times.frames == 8 and server.times.batches == 8


def test_a_batch_runs_once_every_client_grounding_now_waits_on_it() -> None:
    """Batches of up to 16 frames or 1 s. Two clients grounding together: after their first frames the server knows
    both, and a batch runs as soon as both wait (on the queue or the model), not 1 s later. A client seen within
    ``active_s`` that sends nothing (a worker waiting on its VLM) makes the other's frame wait its batch_ms, as
    before; once it has not been seen for ``active_s``, no more."""
    grounder = SlowStaged(forward_s=0.0)
    server = staged_server(grounder, ServeConfig(batch=16, batch_ms=1000.0, active_s=2.0))
    answers: dict[int, float] = {}

    def timed(values: list[int], clients: int = 1) -> float:
        ready = threading.Barrier(clients)
        threads = [
            threading.Thread(target=ground, args=(endpoint, values[c::clients], answers, ready)) for c in range(clients)
        ]
        start = time.perf_counter()
        for thread in threads:
            thread.start()
        for thread in threads:
            thread.join()
        return time.perf_counter() - start

    with serving(server) as endpoint:
        together = timed(list(range(40)), clients=2)
        behind_a_quiet_one = timed([100])  # the two clients above are still active: it waits for them
        time.sleep(2.1)
        alone = timed([101])
    assert len(answers) == 42
    assert together < 1.0 * 4  # 40 frames: at most the first batches waited their 1 s (not 20 batches x 1 s)
    assert behind_a_quiet_one >= 1.0
    assert alone < 1.0


def test_the_queue_counts_frames_and_takes_them_whole() -> None:
    """The server's queue: a frame is a client's step, whole once every SEGMENT its client sent together is in; a
    batch takes whole frames only (a frame taken in parts would be encoded once a part), or one in parts once it has
    waited ``parts_s`` for the rest."""
    from drivenav.semantics.grounder_server import _Pending
    from drivenav.semantics.served import SegmentRequest

    server = staged_server(SlowStaged(forward_s=0.0), ServeConfig(batch=8, batch_ms=0.0))

    def queued(client: bytes, step: int, phrase: str, together: int) -> None:
        segment = SegmentRequest(f"{client!r}{step}{phrase}", "e", phrase, {}, frame(step, step), together)
        server._queue.pending.append(_Pending(client, segment, time.monotonic()))
        server._clients.saw(client, segment)

    def phrases(pendings: list[_Pending]) -> list[str]:
        return [pending.request.phrase for pending in pendings]

    try:
        queued(b"a", 1, "sofa", 3)
        queued(b"a", 1, "chair", 3)
        queued(b"b", 4, "tv", 1)
        assert server._whole() == [(b"b", "e", 4)]
        assert phrases(server._taken(1)) == ["tv"]  # due: b's whole frame, not a's first in parts
        assert server._taken(1, whole=True) == [] and len(server._queue.pending) == 2  # a's step waits for its third
        queued(b"a", 1, "bed", 3)
        queued(b"a", 2, "sofa", 3)
        assert server._whole() == [(b"a", "e", 1)]
        assert phrases(server._taken(8)) == ["sofa", "chair", "bed"]  # due: the whole frames, a's step 2 waits
        assert server._taken(8) == [] and not server._due()  # for its other phrases
        (waiting,) = server._queue.pending
        waiting.arrived -= server.config.parts_s  # its client sent one of the three it said
        assert server._due() and phrases(server._taken(8)) == ["sofa"]
        assert server._queue.pending == [] and server._whole() == []
        queued(b"c", 5, "lamp", 1)  # c's step asked for one phrase, then for two more at once (a second burst)
        assert phrases(server._taken(8)) == ["lamp"]
        queued(b"c", 5, "desk lamp", 2)
        assert server._whole() == [] and server._taken(8) == []  # the burst's second is still to come
        queued(b"c", 5, "table lamp", 2)
        assert phrases(server._taken(8)) == ["desk lamp", "table lamp"]
    finally:
        server.close()


def test_a_full_queue_no_copy_can_take_does_not_spin_the_socket_thread(monkeypatch: pytest.MonkeyPatch) -> None:
    """Batches of one frame, a 0.1 s forward, six clients: most of the time a full batch is queued behind the one the
    model runs and the one handed over. The socket thread then waits for the model instead of waking at once, again
    and again, on requests it would only queue (before: hundreds of thousands of turns of its loop)."""
    grounder = SlowStaged(forward_s=0.1)
    server = staged_server(grounder, ServeConfig(batch=1, batch_ms=0.0))
    turns = [0]
    wait_ms = server._wait_ms

    def counted() -> int:
        turns[0] += 1
        return wait_ms()

    monkeypatch.setattr(server, "_wait_ms", counted)
    two_frames_each(server, 6)
    assert server.batch_sizes == {1: 12}
    assert turns[0] < 1000


def test_a_batch_goes_to_an_idle_copy_not_behind_a_busy_one() -> None:
    """Two copies, a 0.6 s forward: A's frame runs on the first copy; B's, coming while it runs, runs on the second
    at once rather than waiting behind A's forward on the first."""
    first, second = SlowStaged(forward_s=0.6), SlowStaged(forward_s=0.6)
    second.spans, second.lock = first.spans, first.lock
    copies = iter([first, second])
    info = ServedInfo("slow-staged", "-", "cpu", "float32", ("rgb",), False, 8, 0.0)
    server = GrounderServer(lambda: next(copies), info, LOOPBACK, None, ServeConfig(batch=8, batch_ms=0.0, copies=2))
    with cued_clients(server, (1, 2)) as (model, go, answers):
        go[1].set()
        until(lambda: model.ticket() == (1, 0) and model.ready)  # A's batch taken by the first copy
        go[2].set()
    assert answers == {v: pytest.approx(v / 255.0) for v in go}
    forwards = sorted((start, end, name) for stage, name, start, end in first.spans if stage == "forward")
    (_, a_end, a_copy), (b_start, _, b_copy) = forwards
    assert (a_copy, b_copy) == ("drivenav-grounder-model", "drivenav-grounder-model-2") and b_start < a_end


@pytest.mark.parametrize("copies", ["0", "9"])
def test_serve_grounder_copies_out_of_range_is_one_line(copies: str, capsys: pytest.CaptureFixture[str]) -> None:
    assert main(["serve", "grounder", "--detector", "ground-truth", "--copies", copies]) == 2
    error = capsys.readouterr().err
    assert len(error.strip().splitlines()) == 1 and "--copies" in error and "from 1 to 8" in error


def test_serve_grounder_copies_of_a_stand_in_are_refused(capsys: pytest.CaptureFixture[str]) -> None:
    """A stand-in is one instance per episode: copies of it mean nothing, and the option is refused, not ignored."""
    assert main(["serve", "grounder", "--detector", "embedded", "--copies", "2"]) == 2
    error = capsys.readouterr().err
    assert len(error.strip().splitlines()) == 1 and "--copies" in error


def test_a_ping_during_a_forward_is_answered_after_it() -> None:
    """As a server of one thread did: a PONG says the model answers, so it waits for the batch in hand."""
    grounder = SlowStaged(forward_s=0.4)
    server = staged_server(grounder, ServeConfig(batch=1, batch_ms=0.0))
    with serving(server) as endpoint:
        segmenting = GrounderClient(endpoint)
        pinging = GrounderClient(endpoint)
        try:
            info = ServedInfo.from_json(segmenting.request(Message("HELLO", segmenting.next_id())).body)
            remote = RemoteGrounder(segmenting, info)
            remote.begin_episode(None, 0)
            worker = threading.Thread(target=remote.segment, args=(frame(3), "chair"))
            worker.start()
            time.sleep(0.1)  # the forward has begun
            start = time.perf_counter()
            assert pinging.request(Message("PING", pinging.next_id())).type == "PONG"
            waited = time.perf_counter() - start
            worker.join()
        finally:
            segmenting.close()
            pinging.close()
    assert waited >= 0.2
    assert isinstance(grounder, RowGrounder)


def test_a_ping_while_other_workers_keep_the_model_busy_waits_for_the_batches_in_hand_only() -> None:
    """Two clients keep a 0.2 s forward busy without a pause for 2.5 s (each sends its next frame while the
    other's batch runs). A PING sent meanwhile (a third worker's episode start) is answered once the batches the
    model held when it came are done, about 0.4 s at most, not when the model is first idle (after 2.5 s)."""
    grounder = SlowStaged(forward_s=0.2)
    server = staged_server(grounder, ServeConfig(batch=1, batch_ms=0.0))
    answers: dict[int, float] = {}
    ready = threading.Barrier(3)
    with serving(server) as endpoint:
        busy = [
            threading.Thread(target=ground, args=(endpoint, list(range(c, 24, 2)), answers, ready)) for c in range(2)
        ]
        for thread in busy:
            thread.start()
        pinging = GrounderClient(endpoint)
        try:
            ready.wait()
            time.sleep(0.5)
            model = server._model
            assert model is not None and not model.passed(model.ticket())  # the model holds batches now
            start = time.perf_counter()
            assert pinging.request(Message("PING", pinging.next_id())).type == "PONG"
            waited = time.perf_counter() - start
        finally:
            pinging.close()
        still_busy = any(thread.is_alive() for thread in busy)
        for thread in busy:
            thread.join()
    assert len(answers) == 24 and still_busy
    assert 0.0 < waited < 1.0


# --- the eval's rate -------------------------------------------------------------------------------------------------


def test_the_summary_keeps_the_rate_and_a_rerun_with_nothing_to_run_keeps_it_too(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    out = tmp_path / "run"
    assert main([*RUN, "--out", str(out)]) == 0
    printed = capsys.readouterr().out
    summary = json.loads((out / "summary.json").read_text())
    steps = [json.loads(line)["steps"] for line in (out / "episodes.jsonl").read_text().splitlines()]
    eph, fps = summary["episodes_per_hour"], summary["frames_per_second"]
    assert eph > 0 and fps > 0
    assert fps / eph * 3600.0 == pytest.approx(sum(steps) / len(steps), rel=0.01)  # frames an episode
    assert "episodes per hour" in printed and "frames per second" in printed
    assert main([*RUN, "--out", str(out)]) == 0  # nothing left: the rate of the session that ran them stays
    again = json.loads((out / "summary.json").read_text())
    assert (again["episodes_per_hour"], again["frames_per_second"]) == (eph, fps)


def test_a_summary_of_records_read_back_has_no_rate(tmp_path: Path) -> None:
    assert summarize([]).episodes_per_hour is None and summarize([]).frames_per_second is None
    assert Throughput(episodes=3, frames=300, wall_s=60.0).line() == "180 ep/h, 5.0 frames/s"
    assert Throughput(episodes=0, frames=0, wall_s=1.0).line() == ""
    (tmp_path / "summary.json").write_text('{"episodes_per_hour": "fast"}')
    assert rate_kept(summarize([]), tmp_path / "summary.json") == summarize([])
    old = {k: v for k, v in summarize([]).to_json().items() if k not in ("episodes_per_hour", "frames_per_second")}
    assert Summary.from_json(old).episodes_per_hour is None  # a summary written before the rate reads


# --- bench eval-throughput -------------------------------------------------------------------------------------------


def test_bench_eval_throughput_runs_an_eval_beside_a_served_model(capsys: pytest.CaptureFixture[str]) -> None:
    pytest.importorskip("transformers")
    args = ["bench", "eval-throughput", "--tiny", "--device", "cpu", "--workers", "1", "--json", "--"]
    assert main([*args, *RUN[1:]]) == 0
    result = json.loads(capsys.readouterr().out.strip().splitlines()[-1])
    assert result["episodes"] == 2 and result["errors"] == 0 and result["workers"] == 1
    assert result["frames"] > 0 and result["frames_served"] >= result["frames"]  # every step grounded once at least
    assert result["encodings_per_frame"] >= 1.0  # an image encoded once a batch at least
    assert result["episodes_per_hour"] > 0 and result["frames_per_second"] > 0
    step = result["worker_step"]
    assert step["wall_ms"] == pytest.approx(step["agent_ms"] + step["grounding_ms"] + step["other_ms"], abs=0.01)
    assert set(result["server_stages_ms"]) == set(STAGES) and result["server_added_ms"] >= 0.0
    assert 0.0 < result["model_busy"] <= 1.0 and result["mean_batch"] >= 1.0
    assert result["stopped"] is None and result["steady_window_s"] is None  # a few seconds: no steady window


def test_the_steady_rate_counts_the_whole_seconds_when_every_client_grounds() -> None:
    """Client a grounds from 100.2 s to 130.2 s, b from 104.5 s to 120.5 s (start 100): every client grounds in
    seconds 5 to 20 of the server's life (from b's first frame, rounded up, to b's last, rounded down), 15 whole
    seconds, in which a sent one frame a second (105.2 ... 119.2) and b two (105.0 and 105.5 ... 119.0 and 119.5)."""
    rate = SteadyRate(100.0)
    for k in range(31):
        rate.arrived(b"a", 100.2 + k)
    for k in range(33):
        rate.arrived(b"b", 104.5 + k / 2)
    steady = rate.steady()
    assert steady is not None and (steady.window_s, steady.clients) == (15, 2)
    assert steady.frames_per_second == pytest.approx((15 + 30) / 15)
    assert steady.line() == "steady 3 frames a second over 15 s, 2 clients"
    short = SteadyRate(0.0)
    short.arrived(b"a", 0.5)
    short.arrived(b"a", 10.2)  # the window [1, 10): 9 s, under the 10 it takes
    assert short.steady() is None and SteadyRate(0.0).steady() is None


def test_the_server_counts_a_frame_once_however_many_phrases_it_is_sent_for(monkeypatch: pytest.MonkeyPatch) -> None:
    """A client's frame sent for five phrases (one ApexNav step) is one frame of the steady rate, at its first."""
    now = [50.0]
    clock = SimpleNamespace(monotonic=lambda: now[0], perf_counter=time.perf_counter)
    monkeypatch.setattr(grounder_server, "time", clock)
    clients = grounder_server._Clients(10.0)
    for step in range(12):
        now[0] = 50.0 + step
        for phrase in ("sofa", "chair", "bed", "tv", "sink"):
            clients.saw(
                b"w",
                cast(
                    SegmentRequest,
                    SimpleNamespace(episode="e", phrase=phrase, together=5, observation=SimpleNamespace(step=step)),
                ),
            )
    steady = clients.rate.steady()
    assert steady is not None and (steady.frames_per_second, steady.window_s, steady.clients) == (1.0, 11, 1)


def test_an_interrupted_eval_gives_the_bench_its_finished_episodes(tmp_path: Path) -> None:
    """Ctrl-C (or the SIGTERM of a timeout) during ``bench eval-throughput`` stops the eval, its finished episodes
    saved; the bench still prints its figures, of those episodes, says a signal stopped it and exits 130."""
    out = tmp_path / "run"
    run = [*RUN[1:]]
    run[run.index("--episodes") + 1] = "40"
    args = ["bench", "eval-throughput", "--forward-ms", "5", "--workers", "1", "--out", str(out), "--json", "--", *run]
    process = subprocess.Popen(
        [sys.executable, "-m", "drivenav.cli", *args], stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True
    )
    results = out / "episodes.jsonl"
    until_records(process, results, 2)
    process.send_signal(signal.SIGINT)
    stdout, stderr = process.communicate(timeout=120)
    assert process.returncode == 130, stderr
    result = json.loads(stdout.strip().splitlines()[-1])
    finished = len(results.read_text().splitlines())
    assert result["stopped"] == "signal" and 2 <= result["episodes"] == finished < 40 and result["errors"] == 0
    assert result["frames"] > 0 and result["frames_per_second"] > 0 and result["frames_served"] >= result["frames"]
    assert "steady_frames_per_second" in result and "steady_window_s" in result


def test_bench_eval_throughput_window_stops_the_eval_and_says_so(tmp_path: Path) -> None:
    """``--window S``: the eval is stopped S seconds after it starts, as Ctrl-C stops it; the bench prints the
    figures of the episodes it finished, says the window stopped it, and exits 0 (what was asked)."""
    run = [*RUN[1:]]
    run[run.index("--episodes") + 1] = "60"
    out = tmp_path / "run"
    args = ["bench", "eval-throughput", "--forward-ms", "5", "--window", "6", "--out", str(out), "--json", "--", *run]
    result = run_cli(*args, timeout=300)
    assert result.returncode == 0, result.stderr
    figures = json.loads(result.stdout.strip().splitlines()[-1])
    results = out / "episodes.jsonl"  # none yet where the window ended before an episode did (a loaded machine)
    finished = len(results.read_text().splitlines()) if results.exists() else 0
    assert figures["stopped"] == "window" and figures["episodes"] == finished < 60 and figures["errors"] == 0


def test_run_for_without_a_window_or_ended_before_it_is_the_runs_own_status() -> None:
    assert run_for(lambda: 0, None) == (0, False)
    assert run_for(lambda: 3, 60.0) == (3, False)  # ended first: the timer cancelled, nothing sent


@pytest.mark.parametrize("window", ["0", "-1", "nan", "1e9"])
def test_bench_eval_throughput_window_out_of_range_is_one_line(window: str, capsys: pytest.CaptureFixture[str]) -> None:
    assert main(["bench", "eval-throughput", "--forward-ms", "5", "--window", window]) == 2
    error = capsys.readouterr().err.strip()
    assert len(error.splitlines()) == 1 and "field '--window'" in error


def test_bench_eval_throughput_with_a_waiting_forward_serves_no_model(capsys: pytest.CaptureFixture[str]) -> None:
    """--forward-ms: each batch waits that long and finds nothing; the eval's records are its detector's."""
    args = ["bench", "eval-throughput", "--forward-ms", "20", "--workers", "1", "--json", "--"]
    assert main([*args, *RUN[1:]]) == 0
    result = json.loads(capsys.readouterr().out.strip().splitlines()[-1])
    assert result["detector"] == "wait" and result["device"] == "none" and result["errors"] == 0
    assert result["frames_served"] >= result["frames"] > 0
    assert result["server_stages_ms"]["forward"] >= 20.0 / result["mean_batch"] - 0.01  # slept, shared by a batch
    assert result["server_stages_ms"]["preprocess"] < 1.0 and 0.0 < result["model_busy"] <= 1.0  # nothing to prepare


@pytest.mark.parametrize(
    ("given", "field"),
    [
        (["--forward-ms", "-1"], "--forward-ms"),
        (["--forward-ms", "nan"], "--forward-ms"),
        (["--forward-ms", "20000"], "--forward-ms"),
        (["--forward-ms", "5", "--tiny"], "--tiny"),
        (["--forward-ms", "5", "--dtype", "bfloat16"], "--dtype"),
        (["--forward-ms", "5", "--segmenter", "mobilesam"], "--segmenter"),
    ],
)
def test_bench_eval_throughput_forward_ms_out_of_range_or_with_a_model_is_one_line(
    given: list[str], field: str, capsys: pytest.CaptureFixture[str]
) -> None:
    assert main(["bench", "eval-throughput", *given]) == 2
    error = capsys.readouterr().err.strip()
    assert len(error.splitlines()) == 1 and f"field '{field}'" in error


@pytest.mark.parametrize("own", ["--out", "--workers=2", "--detector-shadow-url"])
def test_bench_eval_throughput_refuses_the_options_it_sets(own: str, capsys: pytest.CaptureFixture[str]) -> None:
    assert main(["bench", "eval-throughput", "--tiny", "--", *RUN[1:], own, "x"]) == 2
    error = capsys.readouterr().err
    assert len(error.strip().splitlines()) == 1 and own in error and "the bench sets them" in error
