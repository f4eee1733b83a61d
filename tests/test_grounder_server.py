"""The served grounder (``drivenav serve grounder``, ``--detector remote``, ``eval --share-detector``) on the CPU:
served and in-process detections identical in fp32 (tiny random SAM3, OWLv2 with MobileSAM, Grounding DINO, the
embedded and ground-truth stand-ins), dynamic batching, a stalled or gone server ending only the waiting episode (no
run hangs), hostile requests, loopback-only binds, and runs through a server giving the in-process records.

Every server binds 127.0.0.1 (a free port) and is stopped by its test. No timing is asserted.
"""

from __future__ import annotations

import json
import threading
from collections import Counter
from collections.abc import Callable, Iterator
from contextlib import contextmanager
from pathlib import Path
from typing import Any

import numpy as np
import pytest
import zmq

from drivenav.cli import main
from drivenav.envs.vocabulary import VOCABULARY
from drivenav.errors import InputError, RunStoppedError
from drivenav.semantics.embedded_detector import EmbeddedGrounder
from drivenav.semantics.embedding import default_embedder
from drivenav.semantics.ground_truth import GroundTruthGrounder
from drivenav.semantics.grounder_server import GrounderServer, served_info, serving
from drivenav.semantics.model_spec import ModelSpec
from drivenav.semantics.protocols import Detection, Grounder
from drivenav.semantics.registry import check_models, model_requirements
from drivenav.semantics.remote import RemoteGrounder
from drivenav.semantics.serve_config import ServeConfig
from drivenav.semantics.served import (
    GROUNDER_PROTOCOL,
    REPLIES,
    GrounderClient,
    GrounderUnavailableError,
    ServedInfo,
    detections_reply,
    read_detections,
    segment_request,
)
from drivenav.types import SEMANTIC, CameraIntrinsics, GroundTruth, Observation, Pose
from drivenav.wire.client import ClientConfig
from drivenav.wire.protocol import Message, decode, encode

H, W = 48, 64
LOOPBACK = "tcp://127.0.0.1:*"
LABELS = {1: "sofa", 2: "chair", 3: "armchair", 4: "toilet", 5: "tv"}
TRUTH = GroundTruth(LABELS, VOCABULARY)
PHRASES = ("sofa", "couch", "armchair", "chair", "television")


def observation(seed: int = 0, step: int = 0) -> Observation:
    """A random frame with five boxes of instances at 1-4.5 m."""
    rng = np.random.default_rng(seed)
    semantic = np.zeros((H, W), dtype=np.int32)
    depth = np.full((H, W), 4.8, dtype=np.float32)
    for instance in LABELS:
        row, col = int(rng.integers(0, H - 16)), int(rng.integers(0, W - 16))
        semantic[row : row + 16, col : col + 16] = instance
        depth[row : row + 16, col : col + 16] = rng.uniform(1.0, 4.5)
    return Observation(
        rgb=rng.integers(0, 256, (H, W, 3), dtype=np.uint8),
        depth=depth,
        semantic=semantic,
        pose=Pose(0.5, -1.0, 0.25),
        intrinsics=CameraIntrinsics.from_hfov(W, H, 79.0),
        step=step,
        collided=False,
    )


def identical(a: list[Detection], b: list[Detection]) -> bool:
    return len(a) == len(b) and all(
        np.array_equal(x.mask, y.mask) and x.score == y.score and x.phrase == y.phrase
        for x, y in zip(a, b, strict=True)
    )


def client(endpoint: str, timeout_s: float = 20.0) -> GrounderClient:
    return GrounderClient(endpoint, None, ClientConfig(timeout_s=timeout_s, retries=0, heartbeat_s=0.1))


@contextmanager
def served(
    factory: Callable[[], Grounder], detector: str, config: ServeConfig | None = None
) -> Iterator[tuple[GrounderServer, ServedInfo]]:
    config = config or ServeConfig(batch=1)
    info = served_info(ModelSpec(detector=detector), factory(), config)
    server = GrounderServer(factory, info, LOOPBACK, None, config)
    with serving(server):
        yield server, info


@contextmanager
def remote(endpoint: str, info: ServedInfo, timeout_s: float = 20.0) -> Iterator[RemoteGrounder]:
    connection = client(endpoint, timeout_s)
    try:
        yield RemoteGrounder(connection, info)
    finally:
        connection.close()


# --- equivalence -----------------------------------------------------------------------------------------------------


@pytest.fixture(scope="module")
def transformers_grounders() -> dict[str, tuple[str, Callable[[], Grounder]]]:
    """Tiny random SAM3, OWLv2 with MobileSAM and Grounding DINO (threshold 0: every query or box is kept, so there
    is much to compare), by case: the detector's name and a factory of grounders sharing one model."""
    pytest.importorskip("torch")
    pytest.importorskip("transformers")
    import torch

    from drivenav.semantics.grounding_dino_grounder import GroundingDinoGrounder
    from drivenav.semantics.mobilesam_segmenter import MobileSamSegmenter
    from drivenav.semantics.owlv2_grounder import Owlv2Grounder
    from drivenav.semantics.random_grounders import random_grounding_dino, random_mobile_sam, random_owlv2, random_sam3
    from drivenav.semantics.sam3_grounder import Sam3Grounder

    torch.set_num_threads(1)
    torch.manual_seed(0)
    sam3, sam3_processor = random_sam3(tiny=True)
    owl, owl_processor = random_owlv2(tiny=True)
    with torch.no_grad():  # boxes at their patch priors (a random regressor saturates them)
        owl.box_head.dense2.weight.zero_()
        owl.box_head.dense2.bias.zero_()
    mobile_sam = MobileSamSegmenter(random_mobile_sam(tiny=True), "cpu")
    gdino, gdino_processor = random_grounding_dino(tiny=True)

    def make_sam3() -> Grounder:
        return Sam3Grounder(device="cpu", score_threshold=0.0, model_obj=sam3, processor_obj=sam3_processor)

    def make_owl() -> Grounder:
        return Owlv2Grounder(
            device="cpu", score_threshold=0.0, model_obj=owl, processor_obj=owl_processor, segmenter=mobile_sam
        )

    def make_gdino() -> Grounder:
        return GroundingDinoGrounder(device="cpu", score_threshold=0.0, model_obj=gdino, processor_obj=gdino_processor)

    return {
        "sam3": ("sam3", make_sam3),
        "owlv2+mobilesam": ("owlv2", make_owl),
        "grounding-dino": ("grounding-dino", make_gdino),
    }


@pytest.mark.parametrize("size", [(24, 32), (7, 13), (480, 641)])
@pytest.mark.parametrize("count", [0, 1, 5])
def test_masks_travel_bit_packed_and_come_back_exact(size: tuple[int, int], count: int) -> None:
    """Each mask's rows packed to ceil(width / 8) bytes (a width not a multiple of 8 padded), decoded to the same
    boolean masks and the same scores, through the wire's encoding."""
    rng = np.random.default_rng(count)
    sent = [Detection(rng.random(size) > 0.6, float(rng.random()), "sofa") for _ in range(count)]
    reply = detections_reply("r1", "sofa", sent, size)
    assert reply.arrays["masks"].shape == (count, size[0], (size[1] + 7) // 8)
    back = read_detections(decode(encode(reply, GROUNDER_PROTOCOL), REPLIES, GROUNDER_PROTOCOL), "sofa", size)
    assert [d.score for d in back] == [d.score for d in sent]
    assert all(d.mask.dtype == bool and np.array_equal(d.mask, s.mask) for d, s in zip(back, sent, strict=True))
    with pytest.raises(ValueError, match="not the frame's"):
        detections_reply("r2", "sofa", [Detection(np.zeros((2, 2), bool), 0.5, "sofa")], size)


@pytest.mark.parametrize("case", ["sam3", "owlv2+mobilesam", "grounding-dino"])
def test_served_and_in_process_detections_are_identical_in_fp32(
    case: str, transformers_grounders: dict[str, tuple[str, Callable[[], Grounder]]]
) -> None:
    detector, factory = transformers_grounders[case]
    local = factory()
    local.begin_episode(None, 0)
    with served(factory, detector) as (server, info), remote(server.endpoint, info) as grounder:
        assert info.observes == ("rgb",) and not info.labels and info.dtype == "float32" and info.device == "cpu"
        grounder.begin_episode(None, 0)
        found = 0
        for seed in range(3):
            frame = observation(seed, step=seed)
            for phrase in ("chair", "red sofa"):
                served_detections = grounder.segment(frame, phrase)
                assert identical(served_detections, local.segment(frame, phrase))
                found += len(served_detections)
    assert found > 0
    assert set(server.batch_sizes) == {1}


@pytest.mark.parametrize("detector", ["embedded", "ground-truth"])
def test_served_stand_ins_give_the_in_process_detections(detector: str) -> None:
    """A stand-in is begun per episode with its truth and seed: synonyms, confusions and seeded misses as in
    process, in several interleaved episodes."""

    def factory() -> Grounder:
        return EmbeddedGrounder(default_embedder()) if detector == "embedded" else GroundTruthGrounder()

    with served(factory, detector) as (server, info):
        assert info.labels and "semantic" in info.observes and "rgb" not in info.observes
        with remote(server.endpoint, info) as first, remote(server.endpoint, info) as second:
            locals_ = {}
            for seed, grounder in ((3, first), (11, second)):
                grounder.begin_episode(TRUTH, seed)
                locals_[seed] = factory()
                locals_[seed].begin_episode(TRUTH, seed)
            found = 0
            for step in range(4):
                frame = observation(step, step)
                for phrase in PHRASES:
                    for seed, grounder in ((3, first), (11, second)):
                        detections = grounder.segment(frame, phrase)
                        assert identical(detections, locals_[seed].segment(frame, phrase))
                        found += len(detections)
    assert found > 0


def test_a_deferred_rgb_image_is_not_rendered_for_a_stand_in() -> None:
    frame = observation()
    rendered: list[int] = []

    def render() -> Any:
        rendered.append(1)
        return frame.rgb

    deferred = Observation.deferred(
        render, frame.depth, frame.semantic, frame.pose, frame.intrinsics, frame.step, frame.collided
    )
    message = segment_request("r-1", "e", deferred, "sofa", ("depth", "semantic"))
    assert set(message.arrays) == {"depth", "semantic"} and rendered == []


# --- batching --------------------------------------------------------------------------------------------------------


def test_the_server_batches_the_frames_of_concurrent_clients(
    transformers_grounders: dict[str, tuple[str, Callable[[], Grounder]]],
) -> None:
    """Four clients, a batch of up to 4 frames or 300 ms: batches of several frames, each client's detections those
    of its own frame (a batched matrix product may round differently: scores within 1e-6)."""
    _, factory = transformers_grounders["sam3"]
    local = factory()
    frames = [observation(seed, seed) for seed in range(4)]
    expected = [local.segment(frame, "chair") for frame in frames]
    answers: dict[int, list[list[Detection]]] = {}
    with served(factory, "sam3", ServeConfig(batch=4, batch_ms=300.0)) as (server, info):
        barrier = threading.Barrier(4)

        def work(index: int) -> None:
            with remote(server.endpoint, info) as grounder:
                grounder.begin_episode(None, 0)
                barrier.wait()
                answers[index] = [grounder.segment(frames[index], "chair") for _ in range(3)]

        threads = [threading.Thread(target=work, args=(i,)) for i in range(4)]
        for thread in threads:
            thread.start()
        for thread in threads:
            thread.join()
    assert max(server.batch_sizes) > 1 and sum(n * c for n, c in server.batch_sizes.items()) == 12
    for index, rounds in answers.items():
        for detections in rounds:
            assert len(detections) == len(expected[index])
            for got, want in zip(detections, expected[index], strict=True):
                assert np.array_equal(got.mask, want.mask) and got.score == pytest.approx(want.score, abs=1e-6)


def close_enough(got: list[Detection], want: list[Detection]) -> None:
    """A batched forward's detections: the same masks and phrases, scores within a batched product's rounding."""
    assert len(got) == len(want)
    for a, b in zip(got, want, strict=True):
        assert np.array_equal(a.mask, b.mask) and a.phrase == b.phrase and a.score == pytest.approx(b.score, abs=1e-6)


def vision_encodings(server: GrounderServer) -> list[int]:
    """The number of frames of each vision encoding the served model runs from now on."""
    encoded: list[int] = []
    model = server._model.threads[0].grounder  # type: ignore[union-attr]
    encode = model.encode_vision
    model.encode_vision = lambda pixels: encoded.append(len(pixels)) or encode(pixels)
    return encoded


@pytest.mark.parametrize("case", ["sam3", "owlv2+mobilesam", "grounding-dino"])
def test_a_frame_asked_for_several_phrases_is_one_forward_and_encoded_once(
    case: str, transformers_grounders: dict[str, tuple[str, Callable[[], Grounder]]]
) -> None:
    """A client's phrases of one frame, sent ahead together (ApexNav's step): one batch, one forward, the frame's
    vision encoded once, each phrase's detections those of the phrase grounded alone in process."""
    detector, factory = transformers_grounders[case]
    local, frame = factory(), observation(9, 3)
    expected = {phrase: local.segment(frame, phrase) for phrase in PHRASES}
    with served(factory, detector, ServeConfig(batch=8, batch_ms=1000.0)) as (server, info):
        encoded = vision_encodings(server)
        with remote(server.endpoint, info) as grounder:
            grounder.begin_episode(None, 0)
            grounder.prefetch(frame, PHRASES)
            answers = {phrase: grounder.segment(frame, phrase) for phrase in reversed(PHRASES)}
    assert server.batch_sizes == {len(PHRASES): 1} and server.times.batches == 1 and encoded == [1]
    assert (server.times.frames, server.times.encoded, server.times.received) == (len(PHRASES), 1, 1)
    assert server.times.encodings_per_frame() == 1.0
    assert sum(len(found) for found in answers.values()) > 0
    for phrase in PHRASES:
        close_enough(answers[phrase], expected[phrase])


def grounding_now(
    server: GrounderServer,
    info: ServedInfo,
    clients: int,
    first: Callable[[RemoteGrounder, int], object],
    then: Callable[[RemoteGrounder, int], None],
) -> tuple[Counter[int], list[int]]:
    """``clients`` clients of ``server``, each (``index``) grounding ``first`` (seen grounding: the server then waits
    for every client's next frame), then, once all have, ``then``: the batches run and the images encoded since."""
    before: Counter[int] = Counter()
    encoded = vision_encodings(server)
    barrier = threading.Barrier(clients, action=lambda: (before.update(server.batch_sizes), encoded.clear()))

    def work(index: int) -> None:
        with remote(server.endpoint, info) as grounder:
            grounder.begin_episode(None, 0)
            first(grounder, index)
            barrier.wait()
            then(grounder, index)

    threads = [threading.Thread(target=work, args=(i,)) for i in range(clients)]
    for thread in threads:
        thread.start()
    for thread in threads:
        thread.join()
    return server.batch_sizes - before, encoded


@pytest.mark.parametrize("case", ["sam3", "owlv2+mobilesam", "grounding-dino"])
def test_workers_looking_for_different_objects_share_one_forward(
    case: str, transformers_grounders: dict[str, tuple[str, Callable[[], Grounder]]]
) -> None:
    """Three clients grounding now (each has grounded once), each its own frame and phrase: one batch, one forward
    (the three frames' vision encoded together), each client's detections those of its phrase in its frame."""
    detector, factory = transformers_grounders[case]
    local = factory()
    asked = [(observation(seed, seed), phrase) for seed, phrase in enumerate(("sofa", "chair", "television"))]
    expected = [local.segment(frame, phrase) for frame, phrase in asked]
    answers: dict[int, list[Detection]] = {}

    def then(grounder: RemoteGrounder, index: int) -> None:
        answers[index] = grounder.segment(*asked[index])

    with served(factory, detector, ServeConfig(batch=3, batch_ms=1000.0)) as (server, info):
        batches, encoded = grounding_now(server, info, 3, lambda g, i: g.segment(*asked[i]), then)
    assert batches == Counter({3: 1}) and encoded == [3]
    for index, want in enumerate(expected):
        close_enough(answers[index], want)


def test_a_batch_counts_frames_not_phrases(
    transformers_grounders: dict[str, tuple[str, Callable[[], Grounder]]],
) -> None:
    """``batch`` counts frames: two clients each send one frame's five phrases together (ApexNav's step) to a server
    of batches of 2: one batch of ten requests, one forward, the two frames' vision encoded once, not five batches
    of two requests."""
    _, factory = transformers_grounders["sam3"]
    local = factory()
    frames = [observation(seed, seed) for seed in (11, 12)]
    expected = [{phrase: local.segment(frame, phrase) for phrase in PHRASES} for frame in frames]
    answers: dict[int, dict[str, list[Detection]]] = {}

    def then(grounder: RemoteGrounder, index: int) -> None:
        grounder.prefetch(frames[index], PHRASES)
        answers[index] = {phrase: grounder.segment(frames[index], phrase) for phrase in PHRASES}

    with served(factory, "sam3", ServeConfig(batch=2, batch_ms=1000.0)) as (server, info):
        batches, encoded = grounding_now(server, info, 2, lambda g, _: g.segment(observation(0), "chair"), then)
    assert batches == Counter({2 * len(PHRASES): 1}) and encoded == [2]
    for index, want in enumerate(expected):
        for phrase in PHRASES:
            close_enough(answers[index][phrase], want[phrase])


# --- a server that stalls or is gone ---------------------------------------------------------------------------------


class StallingGrounder:
    """Blocks in ``segment`` until released (a hung forward)."""

    name = "stalling"

    def __init__(self) -> None:
        self.release = threading.Event()

    def begin_episode(self, truth: GroundTruth | None, seed: int) -> None:
        pass

    def segment(self, observation: Observation, phrase: str) -> list[Detection]:
        self.release.wait(30.0)
        return []


@contextmanager
def stalling_server() -> Iterator[tuple[GrounderServer, StallingGrounder]]:
    stalling = StallingGrounder()
    info = ServedInfo("stalling", "-", "cpu", "none", ("semantic",), False, 1, 0.0)
    server = GrounderServer(lambda: stalling, info, LOOPBACK, None, ServeConfig(batch=1))
    with serving(server):
        try:
            yield server, stalling
        finally:
            stalling.release.set()  # the server's thread leaves its forward, and stops


def test_a_stalled_server_ends_the_waiting_request_then_stops_the_next_episode() -> None:
    with stalling_server() as (server, _), remote(server.endpoint, server.info, timeout_s=0.3) as grounder:
        grounder.begin_episode(None, 0)  # answered: the server is idle
        with pytest.raises(GrounderUnavailableError) as waited:
            grounder.segment(observation(), "sofa")
        assert len(str(waited.value).splitlines()) == 1 and server.endpoint in str(waited.value)
        with pytest.raises(RunStoppedError) as stopped:
            grounder.begin_episode(None, 1)
        assert "grounder server" in str(stopped.value) and "rerun" in str(stopped.value)


def test_a_gone_server_ends_the_request_in_its_timeout() -> None:
    factory = GroundTruthGrounder
    with served(factory, "ground-truth") as (server, info):
        endpoint = server.endpoint
    with remote(endpoint, info, timeout_s=0.3) as grounder:
        with pytest.raises(RunStoppedError):
            grounder.begin_episode(TRUTH, 0)
        with pytest.raises(GrounderUnavailableError, match="no reply from the grounder server"):
            grounder.segment(observation(), "sofa")


def spec_options(endpoint: str, timeout_s: float, served: str = "") -> dict[str, object]:
    return {
        "models.detector": "remote",
        "models.detector_url": endpoint,
        "models.detector_timeout_s": timeout_s,
        "models.detector_served": served,
        "sim.max_steps": 60,
    }


def test_a_run_on_a_stalled_server_records_the_episode_as_an_error_and_stops(tmp_path: Path) -> None:
    """The first episode waits on the stalled server: an ``error`` record of one line; the second finds the server
    still silent at its start: the run stops (RunStoppedError), nothing hangs."""
    from drivenav.benchmarks.generate import generate_episodes
    from drivenav.envs.embedded.env import EmbeddedSpec
    from drivenav.envs.embedded.library import SceneLibrary
    from drivenav.eval.records import read_records
    from drivenav.eval.rundir import make_directory
    from drivenav.eval.runner import RunSpec, evaluate
    from drivenav.settings import load_settings

    episodes = generate_episodes(SceneLibrary("procedural:1", 0), 2, seed=0)
    make_directory(tmp_path / "run")
    with stalling_server() as (server, _):
        settings = load_settings("drive-nav", options=spec_options(server.endpoint, 0.5))
        spec = RunSpec(EmbeddedSpec("procedural:1", 0), settings)
        with pytest.raises(RunStoppedError, match="grounder server"):
            evaluate(episodes, spec, tmp_path / "run", show_progress=False)
    records = read_records(tmp_path / "run" / "episodes.jsonl")
    assert len(records) == 1 and records[0].stop_reason == "error"
    assert records[0].error.startswith("GrounderUnavailableError: no reply from the grounder server")
    assert len(records[0].error.splitlines()) == 1


# --- hostile requests and binds --------------------------------------------------------------------------------------


def raw_request(sock: zmq.Socket[Any], frames: list[Any]) -> Message:
    sock.send_multipart([b"", *frames])
    assert sock.poll(10_000)
    reply = sock.recv_multipart()
    return decode(reply[1:], REPLIES, GROUNDER_PROTOCOL)


def test_a_malformed_request_gets_an_error_reply_and_the_server_keeps_serving() -> None:
    with served(GroundTruthGrounder, "ground-truth") as (server, info):
        context: zmq.Context[Any] = zmq.Context()
        sock = context.socket(zmq.DEALER)
        sock.setsockopt(zmq.LINGER, 0)
        sock.connect(server.endpoint)
        try:
            assert "header" in raw_request(sock, [b"not json"]).body["error"]
            robot = encode(Message("PING", "x-1"))  # the robot protocol's name
            assert "protocol" in raw_request(sock, robot).body["error"]
            bad_phrase = segment_request("x-2", "e", observation(), "", ("semantic",))
            assert "body.phrase" in raw_request(sock, encode(bad_phrase, GROUNDER_PROTOCOL)).body["error"]
            unknown = segment_request("x-3", "never-begun", observation(), "sofa", ("semantic",))
            assert "body.episode" in raw_request(sock, encode(unknown, GROUNDER_PROTOCOL)).body["error"]
            lying = Message("SEGMENT", "x-4", body={"episode": "e", "phrase": "sofa", "height": 2, "width": 2})
            huge = raw_request(sock, encode(lying, GROUNDER_PROTOCOL)).body["error"]
            assert "pose" in huge
            wrong = Message("STEP", "x-5")
            assert "type" in raw_request(sock, encode(wrong, GROUNDER_PROTOCOL)).body["error"]
            assert raw_request(sock, encode(Message("PING", "x-6"), GROUNDER_PROTOCOL)).type == "PONG"
        finally:
            sock.close()
            context.term()
        with remote(server.endpoint, info) as grounder:
            grounder.begin_episode(TRUTH, 0)
            local = GroundTruthGrounder(TRUTH)
            assert identical(grounder.segment(observation(1), "chair"), local.segment(observation(1), "chair"))


def test_an_image_of_the_wrong_size_is_refused() -> None:
    with served(GroundTruthGrounder, "ground-truth") as (server, info), remote(server.endpoint, info) as grounder:
        grounder.begin_episode(TRUTH, 0)
        frame = observation()
        assert frame.semantic is not None
        bad = Observation(frame.rgb, frame.depth, frame.semantic[:, :10].copy(), frame.pose, frame.intrinsics, 0, False)
        with pytest.raises(GrounderUnavailableError, match=r"arrays\.semantic"):
            grounder.segment(bad, "sofa")


def test_a_non_loopback_bind_without_keys_is_refused(capsys: pytest.CaptureFixture[str]) -> None:
    info = ServedInfo("ground-truth", "-", "cpu", "none", ("semantic",), True, 1, 0.0)
    with pytest.raises(InputError, match="--keys"):
        GrounderServer(GroundTruthGrounder, info, "tcp://0.0.0.0:5999")
    assert main(["serve", "grounder", "--detector", "ground-truth", "--bind", "tcp://0.0.0.0:5999"]) == 2
    error = capsys.readouterr().err
    assert len(error.strip().splitlines()) == 1 and "--keys" in error


@pytest.mark.parametrize(
    ("spec", "needle"),
    [
        (ModelSpec(detector="remote", detector_url="tcp://10.1.2.3:5557"), "--detector-keys"),
        (ModelSpec(detector="remote", detector_url="http://127.0.0.1:5557"), "--detector-url"),
        (ModelSpec(detector="remote", detector_served="remote"), "models.detector_served"),
    ],
)
def test_a_bad_remote_setting_is_one_input_error(spec: ModelSpec, needle: str) -> None:
    with pytest.raises(InputError, match=needle):
        check_models(spec, connect=False)


def test_a_server_that_does_not_answer_fails_before_any_episode(capsys: pytest.CaptureFixture[str]) -> None:
    with served(GroundTruthGrounder, "ground-truth") as (server, _):
        endpoint = server.endpoint  # now closed: nothing answers there
    args = ["eval", "--agent", "drive-nav", "--episodes", "1", "--out", "/nonexistent/never-written"]
    args += ["--detector", "remote", "--detector-url", endpoint, "--set", "models.detector_timeout_s=0.3"]
    assert main(args) == 2
    error = capsys.readouterr().err
    assert len(error.strip().splitlines()) == 1 and "--detector-url" in error and endpoint in error


def test_a_served_stand_in_must_be_named_so_the_agent_gets_ground_truth() -> None:
    spec = ModelSpec(detector="remote", reasoner="geometric")
    assert model_requirements(spec) == frozenset()
    assert model_requirements(ModelSpec(detector="remote", reasoner="geometric", detector_served="embedded")) == {
        SEMANTIC
    }
    with served(GroundTruthGrounder, "ground-truth") as (server, _):
        unnamed = ModelSpec(detector="remote", detector_url=server.endpoint, detector_timeout_s=5.0)
        with pytest.raises(InputError, match=r"models\.detector_served"):
            check_models(unnamed)
        wrong = ModelSpec(
            detector="remote", detector_url=server.endpoint, detector_timeout_s=5.0, detector_served="embedded"
        )
        with pytest.raises(InputError, match="ground-truth"):
            check_models(wrong)


# --- runs through a server -------------------------------------------------------------------------------------------

RUN = ["eval", "--agent", "drive-nav", "--scenes", "procedural:2", "--episodes", "2", "--seed", "2"]
RUN += ["--max-steps", "120"]
VARYING = {"vlm_latency_ms", "trace"}


def run_records(out: Path) -> list[dict[str, Any]]:
    lines = (out / "episodes.jsonl").read_text(encoding="utf-8").splitlines()
    records = [{k: v for k, v in json.loads(line).items() if k not in VARYING} for line in lines]
    return sorted(records, key=lambda r: str(r["episode_id"]))


@pytest.mark.parametrize("agent", ["drive-nav", "apexnav"])
def test_eval_through_a_served_embedded_detector_gives_the_in_process_records(agent: str, tmp_path: Path) -> None:
    """Served frames go out before the frame is mapped (all of ApexNav's phrases at once) and give the records of
    the in-process detector."""
    run = [*RUN, "--agent", agent]
    assert main([*run, "--out", str(tmp_path / "local")]) == 0
    local = run_records(tmp_path / "local")
    assert any(r["success"] for r in local)  # the detector found targets: its answers mattered
    with served(lambda: EmbeddedGrounder(default_embedder()), "embedded") as (server, _):
        args = ["--detector", "remote", "--detector-url", server.endpoint, "--set", "models.detector_served=embedded"]
        assert main([*run, *args, "--out", str(tmp_path / "remote")]) == 0
    assert run_records(tmp_path / "remote") == local


def test_eval_share_detector_serves_one_copy_to_the_workers(tmp_path: Path) -> None:
    """Two workers, the embedded detector served by a subprocess the run starts and stops: the in-process records;
    the run directory records the detector itself, so a rerun without sharing resumes it."""
    assert main([*RUN, "--out", str(tmp_path / "local")]) == 0
    shared = tmp_path / "shared"
    assert main([*RUN, "--workers", "2", "--share-detector", "--out", str(shared)]) == 0
    assert run_records(shared) == run_records(tmp_path / "local")
    assert (shared / "grounder-server.log").is_file()
    run = json.loads((shared / "run.json").read_text())
    assert run["config"]["models"]["detector"] == "embedded"
    assert main([*RUN, "--out", str(shared)]) == 0  # resumes: nothing left to run


def test_share_detector_refuses_a_remote_detector(capsys: pytest.CaptureFixture[str], tmp_path: Path) -> None:
    args = [*RUN, "--share-detector", "--detector", "remote", "--set", "models.detector_served=embedded"]
    assert main([*args, "--out", str(tmp_path / "x")]) == 2
    assert "--share-detector" in capsys.readouterr().err


# --- bench ------------------------------------------------------------------------------------------------------------


def test_bench_grounder_measures_the_served_path(capsys: pytest.CaptureFixture[str]) -> None:
    pytest.importorskip("transformers")
    args = ["bench", "grounder", "--tiny", "--device", "cpu", "--json", "--frames", "2", "--clients", "2"]
    assert main([*args, "--detector", "owlv2"]) == 0
    result = json.loads(capsys.readouterr().out)
    assert isinstance(result["served_ms_per_frame"], float) and result["served_ms_per_frame"] > 0.0
    assert isinstance(result["served_overhead_ms"], float) and result["clients"] == 2
    assert "served" in result["notes"]


def test_bench_grounder_clients_look_for_different_objects(capsys: pytest.CaptureFixture[str]) -> None:
    pytest.importorskip("transformers")
    args = ["bench", "grounder", "--tiny", "--device", "cpu", "--json", "--frames", "2", "--clients", "3"]
    assert main([*args, "--phrases", "3"]) == 0
    result = json.loads(capsys.readouterr().out)
    assert result["clients"] == 3 and result["client_phrases"] == 3 and result["served_ms_per_frame"] > 0.0


@pytest.mark.parametrize("phrases", [["--phrases", "2"], ["--clients", "2", "--phrases", "17"], ["--phrases", "0"]])
def test_bench_grounder_refuses_phrases_it_cannot_give(phrases: list[str], capsys: pytest.CaptureFixture[str]) -> None:
    pytest.importorskip("transformers")
    assert main(["bench", "grounder", "--tiny", "--device", "cpu", "--frames", "1", *phrases]) == 2
    err = capsys.readouterr().err.strip()
    assert "--phrases" in err and len(err.splitlines()) == 1
