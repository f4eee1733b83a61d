"""Hostile servers and what clients send them (issue 44): a request never waits past its deadline, whatever its
server answers meanwhile (a server that holds it, one restarted on the same endpoint); options that bound waiting
are checked; what a served grounder keeps of its clients is bounded; ``--share-detector`` refuses an endpoint of
the user's; an episode a server lost is run again by a resume, an agent's crash and a server's refusal are not; a
robot that serves another episodes file says so.

Every server binds 127.0.0.1 and is stopped by its test. Waits are bounded (:data:`LIMIT`, far above any answer)
and no duration is asserted: a client that waits forever fails its test at the limit instead of hanging it.
"""

from __future__ import annotations

import json
import subprocess
import sys
import threading
import time
from collections.abc import Callable, Iterator
from contextlib import contextmanager
from pathlib import Path
from typing import Any

import pytest
import zmq

from conftest import REPO
from drivenav.agent.base import Agent
from drivenav.benchmarks.generate import generate_episodes
from drivenav.cli import main
from drivenav.envs.embedded.env import EmbeddedSpec
from drivenav.envs.embedded.library import SceneLibrary
from drivenav.envs.robot import RobotSpec
from drivenav.episode import Episode
from drivenav.eval import runner
from drivenav.eval.episodes import save_episodes
from drivenav.eval.records import EpisodeRecord, read_records
from drivenav.eval.rundir import EPISODES_FILE, LOST_TO_A_SERVER, lost_to_a_server
from drivenav.eval.runner import RunSpec, evaluate
from drivenav.semantics.ground_truth import GroundTruthGrounder
from drivenav.semantics.grounder_server import GrounderServer, served_info, serving
from drivenav.semantics.model_spec import ModelSpec
from drivenav.semantics.remote import RemoteGrounder
from drivenav.semantics.serve_config import ENTRY_BYTES, LABEL_BYTES, ServeConfig
from drivenav.semantics.served import (
    GROUNDER_PROTOCOL,
    GrounderClient,
    GrounderRefusedError,
    GrounderUnavailableError,
    ServedInfo,
    begin_request,
    segment_request,
)
from drivenav.settings import load_settings
from drivenav.types import Action, GroundTruth, Observation, SimConfig
from drivenav.wire.client import ClientConfig, RobotRefusedError, RobotUnavailableError
from drivenav.wire.protocol import Message, ProtocolError, decode, encode
from test_grounder_server import LABELS, LOOPBACK, TRUTH, identical, observation, raw_request
from test_robot_bridge import CountingMotion, free_port, still_session

LIMIT = 60.0
"""The longest a test waits on a client: far above any answer here, so only a client that waits forever meets it."""


def outcome_of(call: Callable[[], object], started: threading.Event | None = None) -> Callable[[], object]:
    """Run ``call`` in a thread now; the returned function waits for it (at most :data:`LIMIT`) and gives its
    result or the exception it raised. A call still waiting then fails the test."""
    box: list[object] = []

    def run() -> None:
        try:
            box.append(call())
        except Exception as error:
            box.append(error)

    thread = threading.Thread(target=run, daemon=True)
    thread.start()

    def result() -> object:
        thread.join(LIMIT)
        if thread.is_alive():
            pytest.fail(f"the client still waits after {LIMIT:g} s: it would wait forever")
        return box[0]

    return result


def wait_until(condition: Callable[[], bool]) -> None:
    deadline = time.monotonic() + LIMIT
    while not condition():
        assert time.monotonic() < deadline, "the condition never held"
        time.sleep(0.01)


class HoldingServer(GrounderServer):
    """Answers HELLO, BEGIN and every PING, never a SEGMENT: it holds each (as ``--batch-ms 1e9`` did). Give it a
    batch of more than one, so that it goes on reading (and answering PINGs) with a SEGMENT held."""

    def _due(self) -> bool:
        return False

    def _wait_ms(self) -> int:
        return self.config.poll_ms


def ground_truth_server(
    endpoint: str = LOOPBACK, config: ServeConfig | None = None, kind: type[GrounderServer] = GrounderServer
) -> GrounderServer:
    config = config or ServeConfig(batch=1)
    info = served_info(ModelSpec(detector="ground-truth"), GroundTruthGrounder(), config)
    return kind(GroundTruthGrounder, info, endpoint, None, config)


def grounder_client(endpoint: str, info: ServedInfo, timeout_s: float) -> RemoteGrounder:
    """A remote grounder whose client PINGs every 0.05 s: a server answering them never goes silent."""
    return RemoteGrounder(GrounderClient(endpoint, None, ClientConfig(timeout_s, 0, heartbeat_s=0.05)), info)


# --- a request's deadline ----------------------------------------------------------------------------------------


def test_a_held_request_ends_at_its_deadline_though_its_server_answers_every_heartbeat() -> None:
    server = ground_truth_server(config=ServeConfig(batch=8), kind=HoldingServer)
    with serving(server) as endpoint:
        grounder = grounder_client(endpoint, server.info, timeout_s=0.5)
        grounder.begin_episode(TRUTH, 0)  # answered at once
        outcome = outcome_of(lambda: grounder.segment(observation(), "sofa"))()
        grounder.client.close()
    assert isinstance(outcome, GrounderUnavailableError) and not isinstance(outcome, GrounderRefusedError)
    assert str(outcome).startswith("no reply from the grounder server at tcp://127.0.0.1:")


def test_a_grounder_restarted_on_the_same_endpoint_fails_the_waiting_request_at_once() -> None:
    """The request reached the first server, which never answered it; the second answers every PING. The request's
    own deadline is far away: only the other server id ends it. The next episode begins on the new server."""
    endpoint = f"tcp://127.0.0.1:{free_port()}"
    first = ground_truth_server(endpoint, ServeConfig(batch=8), HoldingServer)
    grounder = grounder_client(endpoint, first.info, timeout_s=10 * LIMIT)
    with serving(first):
        grounder.begin_episode(TRUTH, 0)
        waiting = outcome_of(lambda: grounder.segment(observation(), "sofa"))
        wait_until(lambda: bool(first._queue.pending))  # the request reached the first server
    with serving(ground_truth_server(endpoint)):
        outcome = waiting()
        assert isinstance(outcome, GrounderUnavailableError) and not isinstance(outcome, GrounderRefusedError)
        assert "restarted while SEGMENT waited" in str(outcome) and endpoint in str(outcome)
        grounder.begin_episode(TRUTH, 1)
        local = GroundTruthGrounder(TRUTH)
        assert identical(grounder.segment(observation(1), "chair"), local.segment(observation(1), "chair"))
    grounder.client.close()


def test_a_robot_restarted_mid_step_fails_the_step_at_once_and_is_greeted_again() -> None:
    """serve-sim killed and started again on the same port while a STEP moves: the STEP is lost at once (not after
    its deadline, not retried into a robot that knows no episode), its episode gets no BYE, and the next RESET
    greets the new robot first."""
    from drivenav.brain.live import live_episode
    from drivenav.robot.server import served

    endpoint = f"tcp://127.0.0.1:{free_port()}"
    sim = SimConfig(width=64, height=48)
    moving = CountingMotion(seconds=LIMIT)  # until stopped: the server stops it on its way out
    with served(still_session(moving), bind=endpoint):
        env = RobotSpec(endpoint, timeout_s=10 * LIMIT, retries=1).build(sim)
        env.reset(live_episode("chair"))
        waiting = outcome_of(lambda: env.step(Action.MOVE_FORWARD))
        wait_until(lambda: moving.executed == 1)
    with served(still_session(CountingMotion()), bind=endpoint):
        outcome = waiting()
        assert isinstance(outcome, RobotUnavailableError) and not isinstance(outcome, RobotRefusedError)
        assert "restarted while STEP waited" in str(outcome)
        with pytest.raises(RobotUnavailableError, match="no measures"):
            env.measures()  # no BYE: the new robot never had the episode
        assert env.reset(live_episode("chair")).step == 0  # HELLO first, then RESET
    env.close()


def test_replies_name_their_server_and_a_hostile_server_id_is_refused() -> None:
    reply = decode(encode(Message("PONG", "p-1", server="a1b2")), ["PONG"])
    assert reply.server == "a1b2"
    assert decode(encode(Message("PING", "p-2")), ["PING"]).server == ""  # a request names none
    header = json.loads(bytes(encode(Message("PONG", "p-3"))[0]))
    for hostile in ("x" * 65, 7, ["a"]):
        header["server"] = hostile
        with pytest.raises(ProtocolError, match="'server'"):
            decode([json.dumps(header).encode()], ["PONG"])


def test_a_client_config_that_could_wait_forever_is_refused() -> None:
    for bad in ({"timeout_s": 0.0}, {"timeout_s": float("inf")}, {"heartbeat_s": float("nan")}, {"retries": -1}):
        with pytest.raises(ValueError):
            ClientConfig(**bad)


# --- options that bound waiting ---------------------------------------------------------------------------------


@pytest.mark.parametrize(
    ("option", "value"), [("--batch-ms", "1e300"), ("--batch-ms", "1e9"), ("--batch-ms", "inf"), ("--batch", "100000")]
)
def test_a_serve_option_past_its_limit_is_one_line_before_serving(option: str, value: str) -> None:
    """``--batch-ms 1e300`` started and died at the first request (OverflowError), ``1e9`` held every request."""
    command = [sys.executable, "-m", "drivenav.cli", "serve", "grounder", "--detector", "ground-truth"]
    command += ["--bind", "tcp://127.0.0.1:*", option, value]
    try:
        result = subprocess.run(command, capture_output=True, text=True, timeout=LIMIT, cwd=REPO, check=False)
    except subprocess.TimeoutExpired:
        pytest.fail(f"serve grounder {option} {value} served instead of refusing the option")
    assert result.returncode == 2 and len(result.stderr.strip().splitlines()) == 1, result.stderr
    assert option in result.stderr and "Traceback" not in result.stderr


def test_a_batch_window_past_its_limit_is_refused_in_the_configuration() -> None:
    for bad in ({"batch_ms": 1e9}, {"batch_ms": 1e300}, {"batch": 0}, {"batch": 10**6}, {"client_episodes": 0}):
        with pytest.raises(ValueError):
            ServeConfig(**bad)


def test_a_detector_timeout_that_never_waits_names_the_setting_not_the_server(
    capsys: pytest.CaptureFixture[str], tmp_path: Path
) -> None:
    for timeout in ("0", "1e300"):
        args = ["eval", "--agent", "drive-nav", "--episodes", "1", "--out", str(tmp_path / "never-written")]
        assert main([*args, "--detector", "remote", "--set", f"models.detector_timeout_s={timeout}"]) == 2
        error = capsys.readouterr().err
        assert len(error.strip().splitlines()) == 1 and "models.detector_timeout_s" in error, error
        assert "--detector-url" not in error
    assert not (tmp_path / "never-written").exists()


def test_a_blank_phrase_is_refused_as_blank() -> None:
    with serving(ground_truth_server()) as endpoint, raw_socket(endpoint) as sock:
        raw_request(sock, encode(begin_request("b-1", "e", TRUTH, 0), GROUNDER_PROTOCOL))
        blank = raw_request(
            sock, encode(segment_request("s-1", "e", observation(), "  ", ("semantic",)), GROUNDER_PROTOCOL)
        )
        assert "body.phrase" in blank.body["error"] and "blank" in blank.body["error"]
        assert "512" not in blank.body["error"]
        long = raw_request(
            sock, encode(segment_request("s-2", "e", observation(), "a" * 600, ("semantic",)), GROUNDER_PROTOCOL)
        )
        assert "at most 512 characters" in long.body["error"] and "600 characters" in long.body["error"]


# --- what the served grounder keeps ------------------------------------------------------------------------------


@contextmanager
def raw_socket(endpoint: str) -> Iterator[zmq.Socket[Any]]:
    """A bare DEALER socket: one client (one identity) of the server."""
    context: zmq.Context[Any] = zmq.Context()
    sock = context.socket(zmq.DEALER)
    sock.setsockopt(zmq.LINGER, 0)
    sock.connect(endpoint)
    try:
        yield sock
    finally:
        sock.close()
        context.term()


def begin(sock: zmq.Socket[Any], episode: str, truth: GroundTruth = TRUTH) -> Message:
    return raw_request(sock, encode(begin_request(f"b-{episode}", episode, truth, 0), GROUNDER_PROTOCOL))


def ground(sock: zmq.Socket[Any], episode: str, phrase: str = "sofa") -> Message:
    request = segment_request(f"s-{episode}-{phrase}", episode, observation(), phrase, ("semantic",), TRUTH.vocabulary)
    return raw_request(sock, encode(request, GROUNDER_PROTOCOL))


def test_a_begin_over_the_label_limit_is_refused_in_one_line() -> None:
    """One BEGIN of 16 M labels grew the server by 1.85 GB; past ``labels`` a BEGIN is refused before any is read."""
    server = ground_truth_server()
    many = GroundTruth({i: "sofa" for i in range(server.config.labels + 1)}, TRUTH.vocabulary)
    with serving(server) as endpoint, raw_socket(endpoint) as sock:
        refused = begin(sock, "big", many)
        assert refused.type == "ERROR" and "\n" not in refused.body["error"]
        assert f"at most {server.config.labels} labels an episode" in refused.body["error"]
        assert ground(sock, "big").type == "ERROR" and len(server.episodes) == 0
        assert begin(sock, "fine").type == "BEGUN" and ground(sock, "fine").type == "DETECTIONS"


def test_one_client_keeps_at_most_its_episodes_the_others_keep_theirs() -> None:
    """Forty BEGINs from one client pinned 7.6 GB; now it keeps its last ``client_episodes``, and its BEGINs never
    push out another client's episodes while the total bounds hold."""
    config = ServeConfig(batch=1, client_episodes=2)
    server = ground_truth_server(config=config)
    with serving(server) as endpoint, raw_socket(endpoint) as greedy, raw_socket(endpoint) as other:
        assert begin(other, "other").type == "BEGUN"
        for k in range(40):
            assert begin(greedy, f"g{k}").type == "BEGUN"
        assert len(server.episodes) == 3
        forgotten = ground(greedy, "g0")
        assert forgotten.type == "ERROR" and "forgets the least recently used" in forgotten.body["error"]
        assert ground(greedy, "g38").type == ground(greedy, "g39").type == "DETECTIONS"
        assert ground(other, "other").type == "DETECTIONS"


PER_EPISODE = len(LABELS) * LABEL_BYTES + sum(ENTRY_BYTES + len(name) for name in set(LABELS.values()))
"""What a BEGIN of TRUTH is charged: its five labels and their names."""
PHRASE = ENTRY_BYTES + 2 * len("sofa")
"""What a SEGMENT of "sofa" (its category "sofa") adds to an episode's vocabulary."""


@pytest.mark.parametrize(
    "config",
    [
        ServeConfig(batch=1, episodes=3),
        ServeConfig(
            batch=1,
            labels=8,
            client_bytes=2 * (PER_EPISODE + PHRASE),
            held_bytes=3 * (PER_EPISODE + PHRASE) + ENTRY_BYTES,
        ),
    ],
    ids=["episodes", "bytes"],
)
def test_all_clients_together_keep_at_most_the_total_episodes_and_bytes(config: ServeConfig) -> None:
    """Past either total bound the least recently used episode of any client is forgotten."""
    server = ground_truth_server(config=config)
    with serving(server) as endpoint, raw_socket(endpoint) as a, raw_socket(endpoint) as b, raw_socket(endpoint) as c:
        for sock, name in ((a, "a"), (b, "b"), (c, "c"), (a, "a2")):
            assert begin(sock, name).type == "BEGUN"
            assert len(server.episodes) <= config.episodes and server.episodes.held <= config.held_bytes
        assert len(server.episodes) == 3
        assert ground(a, "a").type == "ERROR"  # the least recently used of all
        assert [ground(s, n).type for s, n in ((b, "b"), (c, "c"), (a, "a2"))] == ["DETECTIONS"] * 3
        assert server.episodes.held <= config.held_bytes


def test_an_episode_vocabulary_grows_by_at_most_its_phrases() -> None:
    server = ground_truth_server(config=ServeConfig(batch=1, phrases=2))
    with serving(server) as endpoint, raw_socket(endpoint) as sock:
        begin(sock, "e")
        known = ("sofa", "couch", "settee", "couch", "chair")  # sofa and chair are label names: no growth
        assert [ground(sock, "e", phrase).type for phrase in known] == ["DETECTIONS"] * len(known)
        refused = ground(sock, "e", "divan")
        assert refused.type == "ERROR" and "at most 2 distinct phrases an episode" in refused.body["error"]


# --- --share-detector and the episodes a server lost ------------------------------------------------------------

RUN = ["eval", "--agent", "drive-nav", "--scenes", "procedural:2", "--episodes", "2", "--seed", "2"]
RUN += ["--max-steps", "60"]


@pytest.mark.parametrize(
    ("option", "value"), [("--detector-url", "tcp://127.0.0.1:5999"), ("--detector-keys", "keys-of-mine")]
)
def test_share_detector_refuses_an_endpoint_of_the_users(
    capsys: pytest.CaptureFixture[str], tmp_path: Path, option: str, value: str
) -> None:
    assert main([*RUN, "--share-detector", option, value, "--out", str(tmp_path / "run")]) == 2
    error = capsys.readouterr().err
    assert len(error.strip().splitlines()) == 1 and "--share-detector" in error and option in error, error
    assert "--detector remote" in error  # how to use a server of one's own
    assert not (tmp_path / "run" / EPISODES_FILE).exists()


def records_of(out: Path) -> list[dict[str, Any]]:
    varying = {"vlm_latency_ms", "trace"}
    lines = (out / EPISODES_FILE).read_text(encoding="utf-8").splitlines()
    return sorted(({k: v for k, v in json.loads(line).items() if k not in varying} for line in lines), key=str)


def test_episodes_a_dead_shared_server_lost_are_run_again_by_a_resume(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    """The shared server is killed while the first episode waits on it: that episode is an ``error`` record (lost),
    the next episode's start finds no server and stops the run. The same command again serves a new server and
    runs the lost episode as well: the records of a run that never lost its server (not an SR of 50 %)."""
    from drivenav.eval import shared_detector

    assert main([*RUN, "--out", str(tmp_path / "local")]) == 0
    started: list[subprocess.Popen[str]] = []
    real_endpoint, real_segment = shared_detector._endpoint, RemoteGrounder.segment

    def recorded(process: subprocess.Popen[str], log_path: Path, start_s: float) -> str:
        started.append(process)
        return real_endpoint(process, log_path, start_s)

    def killed_at_the_fifth(self: RemoteGrounder, frame: Observation, phrase: str) -> Any:
        calls.append(1)
        if len(calls) == 5 and len(started) == 1:
            started[0].kill()
            started[0].wait()
        return real_segment(self, frame, phrase)

    calls: list[int] = []
    monkeypatch.setattr(shared_detector, "_endpoint", recorded)
    monkeypatch.setattr(RemoteGrounder, "segment", killed_at_the_fifth)
    shared = [*RUN, "--share-detector", "--set", "models.detector_timeout_s=2", "--out", str(tmp_path / "shared")]
    assert main(shared) == 1  # the run stopped: no server at the second episode's start
    (lost,) = read_records(tmp_path / "shared" / EPISODES_FILE)
    assert lost.stop_reason == "error" and lost_to_a_server(lost), lost.error
    assert main(shared) == 0  # resumed with a new server: the lost episode runs again
    assert len(started) == 2 and records_of(tmp_path / "shared") == records_of(tmp_path / "local")


class _EndedBy(Agent):
    """Raises ``error`` at its third step, as a model or a server would mid-episode."""

    name = "ended"
    error: Exception = RuntimeError()

    def decide(self, observation: Observation) -> Action:
        if observation.step == 2:
            raise self.error
        return Action.TURN_LEFT


REAL_BUILD = runner.build_agent


def _run_with(error: Exception | None, out: Path, monkeypatch: pytest.MonkeyPatch) -> list[EpisodeRecord]:
    """Two episodes of the random agent, every one ended by ``error`` (None: run as they are)."""
    monkeypatch.setattr(runner, "_WORKER", None)

    def build(spec: RunSpec) -> Agent:
        if error is None:
            return REAL_BUILD(spec)
        agent = _EndedBy(spec.settings.sim)
        agent.error = error
        return agent

    monkeypatch.setattr(runner, "build_agent", build)
    spec = RunSpec(EmbeddedSpec("procedural:2", 0), load_settings("random", options={"sim.max_steps": 20}))
    evaluate(generate_episodes(SceneLibrary("procedural:2", 0), 2, 0), spec, out, show_progress=False)
    return read_records(out / EPISODES_FILE)


LOST = GrounderUnavailableError("no reply from the grounder server at tcp://127.0.0.1:1 to SEGMENT in 5 s")


@pytest.mark.parametrize(
    ("error", "rerun"),
    [
        (LOST, True),
        (RobotUnavailableError("the robot at tcp://127.0.0.1:1 restarted while STEP waited"), True),
        (GrounderRefusedError("the grounder server refused SEGMENT: grounding failed: CUDA out of memory"), False),
        (RobotRefusedError("the robot refused STEP: a STEP is in progress"), False),
        (ZeroDivisionError("model exploded"), False),
    ],
    ids=["grounder-lost", "robot-restarted", "grounder-refused", "robot-refused", "agent-crash"],
)
def test_a_resume_runs_again_only_the_episodes_a_server_lost(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch, error: Exception, rerun: bool
) -> None:
    """A lost request is no result of the agent's: a resume runs its episode again. An agent's crash and a
    server's refusal are results, recorded as errors for good (never disguised as navigation failures)."""
    first = _run_with(error, tmp_path / "run", monkeypatch)
    assert [(r.stop_reason, lost_to_a_server(r)) for r in first] == [("error", rerun)] * 2
    assert first[0].error.split(":", 1)[0] == type(error).__name__
    resumed = _run_with(None, tmp_path / "run", monkeypatch)
    if rerun:
        fresh = _run_with(None, tmp_path / "fresh", monkeypatch)
        assert not any(r.is_error for r in fresh) and resumed == fresh
    else:
        assert resumed == first


def test_the_lost_errors_are_named_as_their_classes() -> None:
    """A record says ``Type: message``; the resume recognises a lost request by its type's name."""
    assert set(LOST_TO_A_SERVER) == {GrounderUnavailableError.__name__, RobotUnavailableError.__name__}
    for refused in (GrounderRefusedError, RobotRefusedError):
        assert refused.__name__ not in LOST_TO_A_SERVER


# --- a robot that serves another episodes file -------------------------------------------------------------------


@pytest.mark.parametrize("other", ["other-scenes", "other-ids"])
def test_a_robot_that_serves_another_episodes_file_says_so_in_one_line(
    tmp_path: Path, capsys: pytest.CaptureFixture[str], other: str
) -> None:
    """It said the robot "stopped answering" (after an error record of the first episode)."""
    from drivenav.robot.server import served
    from test_robot_bridge import sim_session

    settings = load_settings("drive-nav", options={"sim.max_steps": 20})
    served_episodes = generate_episodes(SceneLibrary("procedural:2", 5), 2, 5, settings.sim)
    theirs = generate_episodes(SceneLibrary("procedural:2", 9), 2, 9, settings.sim)
    if other == "other-ids":
        theirs = [_renamed(e, f"x{e.episode_id}") for e in served_episodes]
    file = tmp_path / "episodes.json.gz"
    save_episodes(theirs, file)
    with served(sim_session(settings, served_episodes)) as endpoint:
        args = ["eval", "--agent", "drive-nav", "--env", "robot", "--robot", endpoint, "--episodes", str(file)]
        assert main([*args, "--max-steps", "20", "--out", str(tmp_path / "run")]) == 2
    error = capsys.readouterr().err.strip().splitlines()[-1]
    assert error.startswith("drivenav: error: ") and "--episodes" in error and "same episodes file" in error, error
    assert "stopped answering" not in error
    assert read_records(tmp_path / "run" / EPISODES_FILE) == []


def _renamed(episode: Episode, episode_id: str) -> Episode:
    from dataclasses import replace

    return replace(episode, episode_id=episode_id)


def test_a_grounder_restarted_between_episodes_costs_no_episode() -> None:
    """A server restarted while no request waits (between two episodes) is simply the server of the next one."""
    endpoint = f"tcp://127.0.0.1:{free_port()}"
    info = served_info(ModelSpec(detector="ground-truth"), GroundTruthGrounder(), ServeConfig(batch=1))
    grounder = grounder_client(endpoint, info, timeout_s=LIMIT)
    ids = []
    for seed in range(2):
        with serving(ground_truth_server(endpoint)):
            grounder.begin_episode(TRUTH, seed)
            local = GroundTruthGrounder(TRUTH)
            assert identical(grounder.segment(observation(seed), "sofa"), local.segment(observation(seed), "sofa"))
            ids.append(grounder.client.server_id)
    grounder.client.close()
    assert ids[0] != ids[1]
