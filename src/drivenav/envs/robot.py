"""A robot as an :class:`~drivenav.envs.base.Env`: the brain's side of the robot protocol (docs/robot.md).

The robot (``drivenav robot serve``, or the embedded world served as one by ``serve-sim``) owns its sensors, its
motion and, where it has them, its measures; :class:`RobotEnv` turns protocol replies into observations. A real
robot has no ground truth: its metrics are ``None`` and it provides nothing to agents (use ``--detector sam3`` or
``owlv2`` and ``--reasoner openai``). A simulated robot says in its WELCOME what it provides (instance labels) and
reports the Habitat metrics of each episode with BYE.
"""

from __future__ import annotations

from dataclasses import dataclass, fields
from pathlib import Path
from typing import ClassVar

import numpy as np

from drivenav.envs.base import EpisodeMeasures
from drivenav.envs.vocabulary import VOCABULARY
from drivenav.episode import Episode
from drivenav.errors import InputError, RunStoppedError
from drivenav.jsonstream import JsonObject
from drivenav.types import SEMANTIC, Action, GroundTruth, Observation, Pose, SimConfig
from drivenav.wire.client import ClientConfig, RobotClient, RobotRefusedError, RobotUnavailableError
from drivenav.wire.payloads import depth_from_wire, occupancy_from, reset_body, rgb_from_jpeg
from drivenav.wire.protocol import Message, ProtocolError, RobotInfo


@dataclass(frozen=True)
class RobotSpec:
    """Builds :class:`RobotEnv` connected to the robot at ``address`` (picklable; ``keys``: the brain's CURVE key
    folder, '' for none). ``ground_truth`` is what the robot said it provides at HELLO (see :func:`probe`)."""

    address: str
    keys: str = ""
    ground_truth: tuple[str, ...] = ()
    timeout_s: float = 10.0
    retries: int = 3
    name: ClassVar[str] = "robot"

    @property
    def provides(self) -> frozenset[str]:
        return frozenset(self.ground_truth) & {SEMANTIC}

    def build(self, sim: SimConfig) -> RobotEnv:
        return RobotEnv(self, sim)

    def client(self) -> RobotClient:
        keys = Path(self.keys) if self.keys else None
        return RobotClient(self.address, keys, ClientConfig(timeout_s=self.timeout_s, retries=self.retries))


def probe(spec: RobotSpec, sim: SimConfig) -> RobotInfo:
    """Greet the robot once and return what it says of itself; a mismatch with ``sim`` or no answer is an
    :class:`InputError` (one line, exit 2)."""
    env = RobotEnv(spec, sim)
    try:
        return env.info
    finally:
        env.close()


def _refused(address: str, error: RobotUnavailableError) -> InputError:
    """The one line for a HELLO that failed: the differing setting (``sim.<field>``), or why no robot answered."""
    differs = error.details.get("mismatch")
    if isinstance(differs, dict):
        field = f"sim.{differs.get('field')}"
        return InputError(address, field, f"the robot's {differs.get('robot')}", differs.get("brain"))
    return InputError(address, "--robot", "a robot that answers HELLO", str(error))


def _names_the_episode(error: RobotRefusedError) -> bool:
    """Whether a RESET was refused for its episode (an id the robot does not serve, or claims that differ)."""
    return str(error.details.get("error", "")).startswith(("field 'body.episode_id'", "field 'body.episode."))


def _not_served(address: str, episode: Episode, error: RobotRefusedError) -> InputError:
    """The one line for a robot that does not serve an episode of the brain's episodes file as the brain reads it."""
    expected = (
        "episodes the robot serves: give the brain and the robot (serve-sim --episodes) the same episodes file; the "
        f"robot refused episode {episode.episode_id!r}"
    )
    return InputError(address, "--episodes", expected, str(error.details.get("error", error)))


class RobotEnv:
    """The robot at ``spec.address`` behind the :class:`~drivenav.envs.base.Env` protocol."""

    def __init__(self, spec: RobotSpec, sim: SimConfig) -> None:
        self._spec = spec
        self._config = sim
        self._client = spec.client()
        self._odom = Pose(0.0, 0.0, 0.0)
        self._labels: dict[int, str] = {}
        self._lost = ""  # why the last request was lost (no reply through every retry, a restarted robot), or ""
        self.last: Message | None = None
        self.info = self._hello()
        self._greeted = self._client.server_id  # the robot (server id) greeted

    def _hello(self) -> RobotInfo:
        request = Message("HELLO", self._client.next_id(), body=RobotInfo.from_sim(self._config).to_json())
        try:
            return RobotInfo.from_json(self._client.request(request).body)
        except RobotUnavailableError as error:
            self._client.close()
            raise _refused(self._spec.address, error) from None
        except ProtocolError as error:
            self._client.close()
            raise InputError(self._spec.address, "--robot", "a robot speaking this protocol", str(error)) from None

    @property
    def config(self) -> SimConfig:
        return self._config

    def reset(self, episode: Episode) -> Observation:
        """Start ``episode`` on the robot. A robot silent through the last episode's end and this RESET too is gone:
        a :class:`RunStoppedError` stops the run (finished episodes saved) instead of an error record per episode
        left, each after the full wait. A robot restarted since its HELLO is greeted again first. A robot that does
        not serve an episode of the brain's episodes file is an :class:`InputError` naming ``--episodes``."""
        was_lost = self._lost
        try:
            if self._client.server_id != self._greeted:
                self._greet_again()
            reply = self._request("RESET", reset_body(episode))
        except RobotRefusedError as error:
            if episode.goals and _names_the_episode(error):
                raise _not_served(self._spec.address, episode, error) from None
            raise
        except RobotUnavailableError as error:
            if not was_lost:
                raise
            raise RunStoppedError(
                f"the robot at {self._spec.address} stopped answering ({error}); finished episodes are saved, "
                "rerun the same command to resume once it answers"
            ) from None
        labels = reply.body.get("labels") or {}
        self._labels = {int(k): str(v) for k, v in labels.items()}
        return self._observation(reply)

    def _greet_again(self) -> None:
        """HELLO to a robot restarted since the last one (it knows no brain yet); other settings than the first
        robot's are an :class:`InputError`, as at the start."""
        request = Message("HELLO", self._client.next_id(), body=RobotInfo.from_sim(self._config).to_json())
        try:
            info = RobotInfo.from_json(self._client.request(request).body)
        except RobotRefusedError as error:
            raise _refused(self._spec.address, error) from None
        if info != self.info:
            expected = f"the robot it started with ({self.info})"
            raise InputError(self._spec.address, "--robot", expected, f"a restarted robot with {info}")
        self._greeted = self._client.server_id

    def step(self, action: Action) -> Observation:
        return self._observation(self._request("STEP", {"action": int(action)}))

    def world_pose(self) -> Pose:
        return self._odom

    def measures(self) -> EpisodeMeasures:
        """The robot's metrics of the episode (a simulated robot's; ``None`` everywhere on a real one); none, at
        once, from a robot that lost the episode's last request (not a second full wait, nor a BYE to a restarted
        robot that never had the episode)."""
        if self._lost:
            raise RobotUnavailableError(f"no measures from the robot at {self._spec.address}: {self._lost}")
        reply = self._request("BYE", {})
        measures = reply.body.get("measures")
        if not isinstance(measures, dict):
            return EpisodeMeasures()
        known = {f.name for f in fields(EpisodeMeasures)}
        return EpisodeMeasures(**{k: v for k, v in measures.items() if k in known})

    def ground_truth(self, kinds: frozenset[str]) -> GroundTruth:
        """Instance labels of a simulated robot (``semantic``); nothing else travels."""
        if SEMANTIC in kinds and SEMANTIC in self.info.provides:
            return GroundTruth(dict(self._labels), VOCABULARY, None)
        return GroundTruth()

    def stop(self) -> None:
        """Tell the robot to stop now (Ctrl-C on the brain)."""
        self._request("STOP", {})

    def close(self) -> None:
        self._client.close()

    def _request(self, kind: str, body: JsonObject) -> Message:
        try:
            reply = self._client.request(Message(kind, self._client.next_id(), body=body))
        except RobotRefusedError:
            self._lost = ""  # an answer: the robot is there
            raise
        except RobotUnavailableError as error:
            self._lost = str(error)
            raise
        self._lost = ""
        self.last = reply
        return reply

    def _observation(self, reply: Message) -> Observation:
        if reply.type != "OBSERVATION" or reply.pose is None or reply.intrinsics is None:
            raise RobotRefusedError(f"the robot answered {reply.type} without an observation")
        self._odom = reply.odom or reply.pose
        intrinsics = reply.intrinsics
        shape = (intrinsics.height, intrinsics.width)
        jpeg = reply.arrays.get("rgb_jpeg")
        rgb = rgb_from_jpeg(jpeg, shape) if jpeg is not None else reply.arrays.get("rgb")
        depth = reply.arrays.get("depth")
        if rgb is None or depth is None or depth.dtype != np.uint16 or depth.shape != shape:
            raise RobotRefusedError(f"the robot's observation lacks rgb or a {shape} uint16 depth image")
        semantic = reply.arrays.get("semantic")
        return Observation(
            rgb=rgb,
            depth=depth_from_wire(depth),
            semantic=None if semantic is None else semantic.astype(np.int32, copy=False),
            pose=reply.pose,
            intrinsics=intrinsics,
            step=reply.step,
            collided=reply.collided,
            occupancy=occupancy_from(reply),
        )
