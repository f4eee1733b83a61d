"""The brain and a robot over ZMQ on 127.0.0.1: parity with the embedded world (plain and CURVE), the allow-list,
and the faults a real link has (a dead server, retries, duplicates, oversized and malformed frames, the deadman)."""

from __future__ import annotations

import json
import re
import socket
import subprocess
import sys
import threading
import time
from collections.abc import Iterator
from contextlib import contextmanager
from pathlib import Path
from typing import Any

import numpy as np
import pytest
import zmq

from conftest import REPO, run_cli
from drivenav.benchmarks.generate import generate_episodes
from drivenav.envs.embedded.env import EmbeddedSpec
from drivenav.envs.embedded.library import SceneLibrary
from drivenav.envs.robot import RobotSpec
from drivenav.episode import Episode
from drivenav.errors import InputError, RunStoppedError
from drivenav.eval.episodes import save_episodes
from drivenav.eval.records import EpisodeRecord
from drivenav.eval.runner import RunSpec, build_agent, run_episode
from drivenav.robot.parts import HeldStill, MotionResult
from drivenav.robot.server import RobotSession, ServerConfig, served
from drivenav.robot.sim import SimulatedLidar, SimulatedRobot
from drivenav.settings import Settings, load_settings
from drivenav.types import Action, Pose
from drivenav.wire.protocol import REPLIES, Message, RobotInfo, decode, encode
from drivenav.wire.security import check_bind, write_keys

SCENES = "procedural:2"
MEASURED = ("success", "spl", "steps", "path_length", "distance_to_goal", "collisions", "stop_reason", "revisits")


@pytest.fixture(scope="module")
def settings() -> Settings:
    return load_settings("drive-nav", options={"sim.max_steps": 60})


@pytest.fixture(scope="module")
def episodes(settings: Settings) -> list[Episode]:
    return generate_episodes(SceneLibrary(SCENES, 5), 2, 5, settings.sim)


@pytest.fixture(scope="module")
def direct(settings: Settings, episodes: list[Episode]) -> list[tuple[EpisodeRecord, list[int]]]:
    return directly(settings, episodes)


def directly(settings: Settings, episodes: list[Episode]) -> list[tuple[EpisodeRecord, list[int]]]:
    """The episodes run in the embedded world itself: the reference a robot run must match."""
    spec = RunSpec(EmbeddedSpec(SCENES, 5), settings)
    env, agent = spec.env.build(settings.sim), build_agent(spec)
    results = []
    for episode in episodes:
        record, trace = run_episode(env, agent, episode, 0, settings.sim.max_steps)
        results.append((record, list(trace.actions)))
    return results


def sim_session(settings: Settings, episodes: list[Episode], lidar: bool = False) -> RobotSession:
    robot = SimulatedRobot(EmbeddedSpec(SCENES, 5).build(settings.sim), episodes, SimulatedLidar() if lidar else None)
    return RobotSession(robot.info(), robot, robot, robot)


def through_robot(
    settings: Settings, episodes: list[Episode], endpoint: str, keys: Path | None
) -> list[tuple[EpisodeRecord, list[int]]]:
    robot_spec = RobotSpec(endpoint, str(keys or ""), ("semantic",))
    spec = RunSpec(robot_spec, settings)
    env, agent = robot_spec.build(settings.sim), build_agent(spec)
    try:
        results = []
        for episode in episodes:
            record, trace = run_episode(env, agent, episode, 0, settings.sim.max_steps)
            results.append((record, list(trace.actions)))
        return results
    finally:
        env.close()


def assert_same(direct: list[tuple[EpisodeRecord, list[int]]], robot: list[tuple[EpisodeRecord, list[int]]]) -> None:
    for (want, want_actions), (got, got_actions) in zip(direct, robot, strict=True):
        assert got.error == ""
        assert got_actions == want_actions
        assert {k: getattr(got, k) for k in MEASURED} == {k: getattr(want, k) for k in MEASURED}


@pytest.mark.parametrize("curve", [False, True], ids=["plain", "curve"])
def test_the_same_episodes_give_the_same_actions_and_metrics_through_the_robot_protocol(
    tmp_path: Path, settings: Settings, episodes: list[Episode], direct: Any, curve: bool
) -> None:
    keys = tmp_path / "keys" if curve else None
    if keys is not None:
        write_keys(keys)
    with served(sim_session(settings, episodes, lidar=curve), keys) as endpoint:
        assert_same(direct, through_robot(settings, episodes, endpoint, keys))


def test_vlfm_gives_the_same_actions_and_metrics_through_the_robot_protocol(episodes: list[Episode]) -> None:
    """The VLFM baseline (value map from the image-text scorer, Yokoyama et al. 2024) through the same bridge."""
    vlfm = load_settings("vlfm", options={"sim.max_steps": 60})
    reference = directly(vlfm, episodes)
    assert any(record.vlm_calls > 0 for record, _ in reference)  # the scorer ran on the brain's side
    with served(sim_session(vlfm, episodes), None) as endpoint:
        assert_same(reference, through_robot(vlfm, episodes, endpoint, None))


def test_apexnav_gives_the_same_actions_and_metrics_through_the_robot_protocol(episodes: list[Episode]) -> None:
    """ApexNav (value map, mode switch, TSP, target-centric fusion; Zhang et al. 2025) through the same bridge."""
    apexnav = load_settings("apexnav", options={"sim.max_steps": 60})
    reference = directly(apexnav, episodes)
    assert all(record.vlm_calls > 0 for record, _ in reference)  # the category question and the scorer ran
    with served(sim_session(apexnav, episodes), None) as endpoint:
        assert_same(reference, through_robot(apexnav, episodes, endpoint, None))


def test_an_unlisted_client_key_is_refused(tmp_path: Path, settings: Settings, episodes: list[Episode]) -> None:
    robot_keys, stranger = tmp_path / "robot", tmp_path / "stranger"
    write_keys(robot_keys)
    write_keys(stranger)
    (stranger / "server.key").write_bytes((robot_keys / "server.key").read_bytes())  # knows the robot, not listed
    with served(sim_session(settings, episodes), robot_keys) as endpoint:
        spec = RobotSpec(endpoint, str(stranger), timeout_s=0.5, retries=1)
        with pytest.raises(InputError, match="no reply from the robot"):
            spec.build(settings.sim)
        listed = RobotSpec(endpoint, str(robot_keys), timeout_s=5.0).build(settings.sim)  # the listed key still works
        assert listed.info.provides == ("semantic",)
        listed.close()


def test_a_non_loopback_bind_without_keys_refuses_to_start(tmp_path: Path) -> None:
    with pytest.raises(InputError, match="--keys"):
        check_bind("tcp://0.0.0.0:5555", None)
    check_bind("tcp://127.0.0.1:5555", None)
    check_bind("tcp://0.0.0.0:5555", tmp_path)
    episodes = tmp_path / "episodes.json.gz"
    result = run_cli("robot", "serve-sim", "--episodes", str(episodes), "--bind", "tcp://0.0.0.0:5599", timeout=120)
    assert result.returncode == 2
    assert result.stderr.count("\n") == 1 and "--keys" in result.stderr


def test_a_hello_mismatch_names_the_differing_setting(settings: Settings, episodes: list[Episode]) -> None:
    with served(sim_session(settings, episodes)) as endpoint:
        brain = load_settings("drive-nav", overrides=["sim.hfov_deg=90"]).sim
        expected = "field 'sim.hfov_deg': expected the robot's 79.0, got 90.0"
        with pytest.raises(InputError, match=re.escape(expected)):
            RobotSpec(endpoint).build(brain)


def free_port() -> int:
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return int(s.getsockname()[1])


def wait_for_robot(endpoint: str, settings: Settings) -> None:
    RobotSpec(endpoint, timeout_s=30.0, retries=0).build(settings.sim).close()


class KilledAtStep:
    """A robot env whose server process is killed with SIGKILL right before step ``at``."""

    def __init__(self, env: Any, server: subprocess.Popen[bytes], at: int) -> None:
        self.env, self.server, self.at, self.steps = env, server, at, 0

    def __getattr__(self, name: str) -> Any:
        return getattr(self.env, name)

    def step(self, action: Action) -> Any:
        self.steps += 1
        if self.steps == self.at:
            self.server.kill()
            self.server.wait()
        return self.env.step(action)


@contextmanager
def killed_at_step_3(tmp_path: Path, settings: Settings, episodes: list[Episode]) -> Iterator[tuple[Any, Any]]:
    """A ``serve-sim`` process and a robot env (0.3 s timeout, one retry) whose server is killed before step 3,
    with the agent; the env is closed and the server gone on leaving."""
    file = tmp_path / "episodes.json.gz"
    save_episodes(episodes, file)
    endpoint = f"tcp://127.0.0.1:{free_port()}"
    command = [sys.executable, "-m", "drivenav.cli", "robot", "serve-sim", "--scenes", SCENES, "--seed", "5"]
    server = subprocess.Popen([*command, "--episodes", str(file), "--bind", endpoint], cwd=REPO)
    try:
        wait_for_robot(endpoint, settings)
        robot_spec = RobotSpec(endpoint, "", ("semantic",), timeout_s=0.3, retries=1)
        env = KilledAtStep(robot_spec.build(settings.sim), server, at=3)
        try:
            yield env, build_agent(RunSpec(robot_spec, settings))
        finally:
            env.close()
    finally:
        if server.poll() is None:
            server.kill()


def test_a_server_killed_mid_episode_ends_it_as_an_error_after_the_timeout(
    tmp_path: Path, settings: Settings, episodes: list[Episode]
) -> None:
    with killed_at_step_3(tmp_path, settings, episodes) as (env, agent):
        started = time.monotonic()
        record, _ = run_episode(env, agent, episodes[0], 0, settings.sim.max_steps)  # type: ignore[arg-type]
        assert time.monotonic() - started < 10.0
    assert record.stop_reason == "error"
    assert record.error.startswith("RobotUnavailableError: no reply from the robot at tcp://127.0.0.1:")
    assert "\n" not in record.error
    assert record.steps == 2  # the two steps the robot answered


class Requests:
    """The types of the requests an env's client sends."""

    def __init__(self, env: Any) -> None:
        self.types: list[str] = []
        client, send = env._client, env._client.request

        def counted(message: Message) -> Message:
            self.types.append(message.type)
            return send(message)

        client.request = counted


def test_a_robot_gone_for_good_stops_the_run_instead_of_a_wait_per_episode(
    tmp_path: Path, settings: Settings, episodes: list[Episode]
) -> None:
    """The episode the robot dies in ends after one wait (no BYE into the silence); the next episode's RESET gets
    one more chance, then the run stops: not an error record per episode left, each after the full wait."""
    with killed_at_step_3(tmp_path, settings, episodes) as (env, agent):
        requests = Requests(env.env)
        record, _ = run_episode(env, agent, episodes[0], 0, settings.sim.max_steps)  # type: ignore[arg-type]
        assert record.stop_reason == "error" and requests.types[-1] == "STEP"  # no BYE after the silent STEP
        with pytest.raises(RunStoppedError, match=r"stopped answering.*rerun the same command to resume"):
            run_episode(env, agent, episodes[1], 0, settings.sim.max_steps)  # type: ignore[arg-type]
        assert requests.types[-1] == "RESET"  # one more chance, then the run stops


class CountingMotion(HeldStill):
    """Counts executions; each takes ``seconds`` unless stopped."""

    def __init__(self, seconds: float = 0.0) -> None:
        self.executed = 0
        self.completed: list[bool] = []
        self.stopped = threading.Event()
        self.seconds = seconds

    def execute(self, action: Action) -> MotionResult:
        self.executed += 1
        self.stopped.clear()
        self.completed.append(not self.stopped.wait(self.seconds) if self.seconds else True)
        return MotionResult(collided=False, completed=self.completed[-1])

    def stop(self) -> None:
        self.stopped.set()


def still_session(motion: CountingMotion, config: ServerConfig | None = None) -> RobotSession:
    from drivenav.brain.bench import StillCamera
    from drivenav.types import SimConfig

    sim = SimConfig(width=64, height=48)
    return RobotSession(RobotInfo.from_sim(sim), StillCamera(sim), motion, config=config)


class RawClient:
    """A bare DEALER socket: requests exactly as written, no heartbeats, no retries."""

    def __init__(self, endpoint: str) -> None:
        self.context: zmq.Context[Any] = zmq.Context()
        self.socket = self.context.socket(zmq.DEALER)
        self.socket.setsockopt(zmq.LINGER, 0)
        self.socket.connect(endpoint)

    def send(self, frames: list[Any]) -> None:
        self.socket.send_multipart([b"", *frames])

    def request(self, message: Message) -> None:
        self.send(encode(message))

    def reply(self, timeout_s: float = 5.0) -> Message | None:
        if not self.socket.poll(int(timeout_s * 1000)):
            return None
        frames = self.socket.recv_multipart()
        return decode(frames[1:], REPLIES)

    def close(self) -> None:
        self.socket.close()
        self.context.term()


def hello(client: RawClient, width: int = 64, height: int = 48) -> Message | None:
    from drivenav.types import SimConfig

    client.request(Message("HELLO", "h1", body=RobotInfo.from_sim(SimConfig(width=width, height=height)).to_json()))
    return client.reply()


@pytest.fixture
def raw() -> Any:
    clients: list[RawClient] = []

    def connect(endpoint: str) -> RawClient:
        clients.append(RawClient(endpoint))
        return clients[-1]

    yield connect
    for client in clients:
        client.close()


def test_a_duplicate_request_id_is_answered_but_not_executed_twice(raw: Any) -> None:
    motion = CountingMotion()
    with served(still_session(motion)) as endpoint:
        client = raw(endpoint)
        assert hello(client).type == "WELCOME"  # type: ignore[union-attr]
        client.request(Message("RESET", "r1", body={"episode_id": "e", "target": "chair"}))
        assert client.reply().type == "OBSERVATION"  # type: ignore[union-attr]
        step = Message("STEP", "s1", body={"action": int(Action.MOVE_FORWARD)})
        client.request(step)
        first = client.reply()
        client.request(step)  # a retry: same id
        second = client.reply()
        assert first is not None and second is not None
        assert (first.type, first.step) == (second.type, second.step) == ("OBSERVATION", 1)
        assert motion.executed == 1


@pytest.mark.parametrize(
    ("frames", "expected"),
    [
        ([b"{oops"], "field 'header'"),
        ([json.dumps({"protocol": "drivenav-robot", "version": 99, "type": "PING", "id": "v"}).encode()], "version"),
        ([json.dumps({"protocol": "drivenav-robot", "version": 1, "type": "DANCE", "id": "d"}).encode()], "type"),
    ],
    ids=["malformed", "version", "unknown"],
)
def test_a_bad_message_gets_an_error_reply_and_the_server_keeps_serving(
    raw: Any, frames: list[bytes], expected: str
) -> None:
    with served(still_session(CountingMotion())) as endpoint:
        client = raw(endpoint)
        client.send(frames)
        reply = client.reply()
        assert reply is not None and reply.type == "ERROR" and expected in reply.body["error"]
        assert hello(client).type == "WELCOME"  # type: ignore[union-attr]


def test_out_of_order_requests_are_refused_by_name(raw: Any) -> None:
    with served(still_session(CountingMotion())) as endpoint:
        client = raw(endpoint)
        client.request(Message("OBSERVE", "o1"))
        assert "HELLO first" in client.reply().body["error"]  # type: ignore[union-attr]
        hello(client)
        client.request(Message("STEP", "s1", body={"action": 1}))
        assert "RESET before STEP" in client.reply().body["error"]  # type: ignore[union-attr]
        client.request(Message("RESET", "r1", body={}))
        client.reply()
        client.request(Message("STEP", "s2", body={"action": 7}))
        assert "body.action" in client.reply().body["error"]  # type: ignore[union-attr]


def test_an_oversized_frame_drops_only_that_connection(raw: Any) -> None:
    with served(still_session(CountingMotion(), ServerConfig(max_message_bytes=4096))) as endpoint:
        big = raw(endpoint)
        big.send([*encode(Message("PING", "p1")), b"x" * 10_000])
        assert big.reply(timeout_s=1.0) is None  # libzmq drops the frame and the connection: silence
        assert hello(raw(endpoint)).type == "WELCOME"  # type: ignore[union-attr]


def test_a_dropped_connection_is_restored_by_the_client_retrying(settings: Settings) -> None:
    from drivenav.types import SimConfig

    endpoint = f"tcp://127.0.0.1:{free_port()}"
    sim = SimConfig(width=64, height=48)
    result: dict[str, Any] = {}

    def connect() -> None:
        try:
            env = RobotSpec(endpoint, timeout_s=0.4, retries=10).build(sim)
            result["info"] = env.info
            env.close()
        except InputError as error:
            result["error"] = error

    thread = threading.Thread(target=connect)
    thread.start()
    time.sleep(1.0)  # the first tries find nobody
    with served(still_session(CountingMotion()), bind=endpoint):
        thread.join(timeout=10.0)
    assert "error" not in result
    assert result["info"].width == 64


def test_the_deadman_stops_a_robot_that_hears_nothing_while_moving(raw: Any) -> None:
    motion = CountingMotion(seconds=5.0)
    with served(still_session(motion, ServerConfig(deadman_s=0.5))) as endpoint:
        client = raw(endpoint)
        hello(client)
        client.request(Message("RESET", "r1", body={}))
        client.reply()
        started = time.monotonic()
        client.request(Message("STEP", "s1", body={"action": int(Action.MOVE_FORWARD)}))
        reply = client.reply(timeout_s=5.0)  # no heartbeat from this client
        assert reply is not None and reply.type == "OBSERVATION"
        assert 0.5 <= time.monotonic() - started < 3.0
        assert motion.completed == [False]  # stopped by the deadman


def test_heartbeats_keep_the_deadman_quiet_during_a_long_motion() -> None:
    from drivenav.brain.live import live_episode
    from drivenav.types import SimConfig

    motion = CountingMotion(seconds=1.5)
    with served(still_session(motion, ServerConfig(deadman_s=0.5))) as endpoint:
        env = RobotSpec(endpoint, timeout_s=1.0).build(SimConfig(width=64, height=48))
        env.reset(live_episode("chair"))
        started = time.monotonic()
        env.step(Action.MOVE_FORWARD)
        env.close()
    assert time.monotonic() - started >= 1.5
    assert motion.completed == [True]  # not stopped by the deadman


def test_lidar_occupancy_travels_with_observations_and_is_fused_when_switched_on(
    settings: Settings, episodes: list[Episode]
) -> None:
    from drivenav.grid import GridSpec
    from drivenav.robot.serve import lidar_for

    env_world = EmbeddedSpec(SCENES, 5).build(settings.sim)
    robot = SimulatedRobot(env_world, episodes, SimulatedLidar())
    session = RobotSession(robot.info(), robot, robot, robot, lidar_for(settings.sim, True))
    fused = load_settings("drive-nav", options={"sim.max_steps": 20}, overrides=["mapping.fuse_lidar=true"])
    with served(session) as endpoint:
        env = RobotSpec(endpoint, "", ("semantic",)).build(fused.sim)
        observation = env.reset(episodes[0])
        local = observation.occupancy
        assert local is not None and (local.cells == 1).any() and (local.cells == 0).any()
        # every occupied cell lies on (or beside) a wall or piece of furniture of the scene, in the world frame
        start = env_world.start_pose
        grid = GridSpec(local.resolution, local.origin, local.cells.shape)
        rows, cols = (local.cells == 1).nonzero()
        centres = (np.stack([cols, rows], axis=1) + 0.5) * local.resolution + np.asarray(grid.origin)
        blocked = env_world.scene.obstacle_grid(settings.sim.agent_height)
        for x, y in centres:
            world = start.compose(Pose(float(x), float(y), 0.0))
            r, c = env_world.scene.grid.world_to_cell((world.x, world.y))
            assert blocked[max(r - 2, 0) : r + 3, max(c - 2, 0) : c + 3].any()
        env.close()
        record, _ = run_episode(
            RobotSpec(endpoint, "", ("semantic",)).build(fused.sim),
            build_agent(RunSpec(RobotSpec(endpoint), fused)),
            episodes[0],
            0,
            20,
        )
    assert record.error == "" and record.steps == 20


def test_ctrl_c_during_a_live_episode_stops_the_robot_and_ends_the_episode() -> None:
    from drivenav.brain.live import LiveEnv, OperatorStopError, live_episode
    from drivenav.types import SimConfig

    motion = CountingMotion()
    with served(still_session(motion)) as endpoint:
        sim = SimConfig(width=64, height=48)
        env = RobotSpec(endpoint).build(sim)
        live = LiveEnv(env, build_agent(RunSpec(RobotSpec(endpoint), load_settings("random"))))
        live.reset(live_episode("chair"))
        live.step(Action.MOVE_FORWARD)
        motion.stopped.clear()
        live.interrupted = True
        with pytest.raises(OperatorStopError, match="stopped by the operator"):
            live.step(Action.MOVE_FORWARD)
        assert motion.stopped.is_set() and motion.executed == 1  # STOP sent, the second step never ran
        env.close()


def test_a_reset_for_another_episode_under_a_served_id_is_refused(settings: Settings, episodes: list[Episode]) -> None:
    """The brain read another episodes file than serve-sim: same ids, other scenes. The metrics would belong to
    the served episode, recorded under the brain's scene and target; the RESET is refused naming the field, and the
    brain says in one line that the two sides read other episodes files (``--episodes``)."""
    other = generate_episodes(SceneLibrary("procedural:2", 9), 2, 9, settings.sim)
    assert [e.episode_id for e in other] == [e.episode_id for e in episodes]
    with served(sim_session(settings, episodes)) as endpoint:
        env = RobotSpec(endpoint, "", ("semantic",)).build(settings.sim)
        try:
            with pytest.raises(InputError, match=r"--episodes.*same episodes file.*body\.episode\.scene_id"):
                env.reset(other[0])
            assert env.reset(episodes[0]).step == 0  # the right episode still starts
        finally:
            env.close()
