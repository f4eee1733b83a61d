"""The robot side of the protocol: ``drivenav robot serve`` and ``serve-sim`` (docs/robot.md).

:class:`RobotSession` answers protocol messages from a :class:`~drivenav.robot.parts.SensorSource` and a
:class:`~drivenav.robot.parts.MotionExecutor` (no sockets: tested on its own); :class:`RobotServer` puts it behind a
ZMQ ROUTER socket. Motion runs on a worker thread so that the socket keeps answering heartbeats while the robot
moves; a deadman stops the robot when nothing was heard from the brain for ``deadman_s`` while it moves. A STEP
whose request id was already seen (a client's retry) is answered again, never executed twice.
"""

from __future__ import annotations

import contextlib
import logging
import threading
import time
from collections import OrderedDict
from collections.abc import Iterator, Mapping
from concurrent.futures import Future, ThreadPoolExecutor
from dataclasses import asdict, dataclass, field
from pathlib import Path
from typing import TYPE_CHECKING, Any, Protocol

import zmq

from drivenav.envs.base import EpisodeMeasures, episode_pose
from drivenav.errors import one_line
from drivenav.jsonstream import JsonObject
from drivenav.robot.parts import MotionExecutor, MotionResult, SensorFrame, SensorSource
from drivenav.types import Action, Pose
from drivenav.wire.payloads import depth_to_wire, occupancy_body, rgb_to_jpeg
from drivenav.wire.protocol import MAX_ARRAY_BYTES, REQUESTS, Message, ProtocolError, RobotInfo, decode, mismatch
from drivenav.wire.router import Frames, RouterSocket, error_reply, in_background, loose_id

if TYPE_CHECKING:
    from drivenav.robot.lidar import LidarOccupancy

log = logging.getLogger(__name__)


@dataclass(frozen=True)
class ServerConfig:
    """The robot side's limits: ``deadman_s`` without a message from the brain while moving stops the robot;
    ``max_message_bytes`` is libzmq's MAXMSGSIZE (per frame: a larger frame drops the connection); ``reply_cache``
    request ids are remembered for retries; ``rgb_encoding`` is ``raw`` or ``jpeg``."""

    deadman_s: float = 1.0
    max_message_bytes: int = MAX_ARRAY_BYTES
    reply_cache: int = 256
    rgb_encoding: str = "raw"
    jpeg_quality: int = 90
    poll_ms: int = 20


class EpisodeWorld(Protocol):
    """A simulated robot that knows the episodes: it places itself at an episode's start and measures it."""

    def start(self, episode_id: str, body: Mapping[str, Any]) -> None:
        """Place the robot at the start of ``episode_id`` (KeyError: an unknown episode); a
        :class:`~drivenav.wire.protocol.ProtocolError` when what the RESET ``body`` claims of it (``episode``: its
        scene, target and start) is not this episode's: the two sides read other episode files."""
        ...

    def measures(self) -> EpisodeMeasures:
        """The Habitat metrics of the current episode."""
        ...

    def labels(self) -> Mapping[int, str]:
        """Instance id -> category of the current scene (what ``semantic`` images hold)."""
        ...


@dataclass
class _Motion:
    """A STEP being executed: its request, who to answer, and when the brain was last heard."""

    request: Message
    identity: bytes
    future: Future[MotionResult]
    deadman_fired: bool = False


@dataclass
class _Episode:
    origin: Pose
    step: int = 0
    collided: bool = False
    extra: JsonObject = field(default_factory=dict)


class RobotSession:
    """The protocol's state machine over one robot: HELLO first, RESET before OBSERVE / STEP, BYE ends the episode."""

    def __init__(
        self,
        info: RobotInfo,
        source: SensorSource,
        executor: MotionExecutor,
        episodes: EpisodeWorld | None = None,
        lidar: LidarOccupancy | None = None,
        config: ServerConfig | None = None,
    ) -> None:
        self.info = info
        self.source = source
        self.executor = executor
        self.episodes = episodes
        self.lidar = lidar
        self.config = config or ServerConfig()
        self._greeted = False
        self._episode: _Episode | None = None

    @property
    def in_episode(self) -> bool:
        """Between a RESET and its BYE."""
        return self._episode is not None

    # -- requests answered at once --------------------------------------------------------------------------------
    def answer(self, request: Message) -> Message:
        """The reply to any request but STEP (see :meth:`start_step`); an ERROR names what was wrong, and a fault
        of the robot's own parts (a sensor, the simulator) is an ERROR too: the session goes on."""
        try:
            return self._answer(request)
        except ProtocolError as error:
            return error_reply(request.request_id, str(error))
        except Exception as error:
            log.exception("%s failed", request.type)
            return error_reply(request.request_id, f"{request.type} failed on the robot: {one_line(error)}")

    def _answer(self, request: Message) -> Message:
        if request.type == "PING":
            return Message("PONG", request.request_id)
        if request.type == "HELLO":
            return self._hello(request)
        if not self._greeted:
            raise ProtocolError("type", "HELLO first", request.type)
        if request.type == "STOP":
            self.executor.stop()
            return Message("STOPPED", request.request_id)
        if request.type == "RESET":
            return self._reset(request)
        if self._episode is None:
            raise ProtocolError("type", "RESET before OBSERVE, STEP and BYE", request.type)
        if request.type == "OBSERVE":
            return self.observation(request.request_id)
        if request.type == "BYE":
            return self._bye(request)
        raise ProtocolError("type", "a request answered at once", request.type)

    def _hello(self, request: Message) -> Message:
        brain = RobotInfo.from_json(request.body)
        differs = mismatch(self.info, brain)
        if differs is not None:
            body = {"error": f"the brain's settings differ from the robot's: {differs}", "mismatch": asdict(differs)}
            return Message("ERROR", request.request_id, status="error", body=body)
        self._greeted = True
        return Message("WELCOME", request.request_id, body=self.info.to_json())

    def _reset(self, request: Message) -> Message:
        episode_id = str(request.body.get("episode_id", ""))
        if self.episodes is not None:
            try:
                self.episodes.start(episode_id, request.body)
            except KeyError:
                raise ProtocolError("body.episode_id", "an episode this robot knows", episode_id) from None
        self.executor.stop()
        if self.lidar is not None:
            self.lidar.reset()
        frame = self.source.read()
        self._episode = _Episode(frame.pose)
        if self.episodes is not None:
            self._episode.extra["labels"] = {str(k): v for k, v in self.episodes.labels().items()}
        log.info("episode %s: target %r, origin %s", episode_id, request.body.get("target"), frame.pose)
        return self._observation_of(request.request_id, frame)

    def _bye(self, request: Message) -> Message:
        measures = None if self.episodes is None else asdict(self.episodes.measures())
        self.executor.stop()
        self._episode = None
        return Message("GOODBYE", request.request_id, body={"measures": measures})

    # -- STEP: motion on a worker thread ----------------------------------------------------------------------------
    def check_step(self, request: Message) -> Action:
        """The action of a STEP request (ProtocolError if it may not run now)."""
        if not self._greeted or self._episode is None:
            raise ProtocolError("type", "HELLO and RESET before STEP", request.type)
        value = request.body.get("action")
        if isinstance(value, bool) or not isinstance(value, int) or value not in {int(a) for a in Action}:
            raise ProtocolError("body.action", "an action 0-3 (STOP, MOVE_FORWARD, TURN_LEFT, TURN_RIGHT)", value)
        return Action(value)

    def finish_step(self, request: Message, result: MotionResult) -> Message:
        """The OBSERVATION after a STEP's motion."""
        assert self._episode is not None
        self._episode.step += 1
        self._episode.collided = result.collided
        return self.observation(request.request_id)

    # -- observations -----------------------------------------------------------------------------------------------
    def observation(self, request_id: str) -> Message:
        return self._observation_of(request_id, self.source.read())

    def _observation_of(self, request_id: str, frame: SensorFrame) -> Message:
        assert self._episode is not None
        episode = self._episode
        pose = episode_pose(episode.origin, frame.pose)
        arrays: JsonObject = {"depth": depth_to_wire(frame.depth)}
        if self.config.rgb_encoding == "jpeg":
            arrays["rgb_jpeg"] = rgb_to_jpeg(frame.rgb, self.config.jpeg_quality)
        else:
            arrays["rgb"] = frame.rgb
        body: JsonObject = dict(episode.extra)
        episode.extra.clear()  # labels travel once, with the reset's observation
        if self.lidar is not None and frame.scan is not None:
            self.lidar.update(frame.scan, pose, frame.gimbal_yaw)
            window = self.lidar.window(pose)
            arrays["occupancy"] = window.cells
            body.update(occupancy_body(window))
        if frame.semantic is not None:
            arrays["semantic"] = frame.semantic
        return Message(
            "OBSERVATION",
            request_id,
            step=episode.step,
            sent=time.time(),
            stamp=frame.stamp,
            pose=pose,
            odom=frame.pose,
            intrinsics=frame.intrinsics,
            gimbal=(frame.gimbal_yaw, frame.gimbal_pitch),
            collided=episode.collided,
            body=body,
            arrays=arrays,
        )


class RobotServer:
    """A :class:`RobotSession` behind a ZMQ ROUTER socket bound at ``bind`` (CURVE with ``keys``).

    A non-loopback ``bind`` without ``keys`` is refused (:func:`~drivenav.wire.security.check_bind`). ``bind``
    may name port ``*`` (a free port; :attr:`endpoint` says which).
    """

    def __init__(self, session: RobotSession, bind: str, keys: Path | None = None) -> None:
        self.session = session
        self.config = session.config
        self._router = RouterSocket(bind, keys, self.config.max_message_bytes)
        self._replies: OrderedDict[str, Frames] = OrderedDict()
        self._motion: _Motion | None = None
        self._pool = ThreadPoolExecutor(max_workers=1, thread_name_prefix="drivenav-motion")
        self._last_heard = time.monotonic()
        self._socket = self._router.socket
        self._monitor = self._router.monitor
        self.endpoint = self._router.endpoint

    def serve(self, stop: threading.Event | None = None) -> None:
        """Answer requests until ``stop`` is set (or Ctrl-C); the robot is stopped on the way out."""
        stop = stop or threading.Event()
        poller = zmq.Poller()
        poller.register(self._socket, zmq.POLLIN)
        poller.register(self._monitor, zmq.POLLIN)
        log.info("serving the robot on %s%s", self.endpoint, " (CURVE)" if self._router.curve else "")
        try:
            while not stop.is_set():
                events = dict(poller.poll(self.config.poll_ms))
                if self._monitor in events:
                    self._log_socket_event()
                if self._socket in events:
                    self._receive()
                self._check_motion()
        finally:
            self.session.executor.stop()

    def close(self) -> None:
        self._pool.shutdown(wait=True)
        self._router.close()

    def _receive(self) -> None:
        """One message from a brain, answered; nothing in it can stop the server (an unexpected fault is logged
        and answered as an ERROR)."""
        identity, body = self._router.receive()
        self._last_heard = time.monotonic()
        try:
            self._answer(identity, body)
        except Exception as error:
            log.exception("a request could not be answered")
            self._send(
                identity, self._router.frames(error_reply(loose_id(body), f"the robot failed: {one_line(error)}"))
            )

    def _answer(self, identity: bytes, body: list[Any]) -> None:
        try:
            request = decode([f.buffer for f in body], REQUESTS)
        except ProtocolError as error:
            self._send(identity, self._router.frames(error_reply(loose_id(body), str(error))))
            return
        cached = self._replies.get(request.request_id)
        if cached is not None and request.type != "PING":
            self._send(identity, cached)
            return
        self._dispatch(identity, request)

    def _dispatch(self, identity: bytes, request: Message) -> None:
        motion = self._motion
        if request.type == "STEP":
            if motion is not None and motion.request.request_id == request.request_id:
                motion.identity = identity  # a retry of the step in progress: answer the new socket when done
                return
            if motion is not None:
                self._send(identity, self._router.frames(error_reply(request.request_id, "a STEP is in progress")))
                return
            self._start_step(identity, request)
            return
        if motion is not None and request.type not in ("PING", "STOP"):
            self._send(
                identity,
                self._router.frames(error_reply(request.request_id, f"{request.type} while a STEP is in progress")),
            )
            return
        self._reply(identity, request, self.session.answer(request))

    def _start_step(self, identity: bytes, request: Message) -> None:
        try:
            action = self.session.check_step(request)
        except ProtocolError as error:
            self._reply(identity, request, error_reply(request.request_id, str(error)))
            return
        future = self._pool.submit(self.session.executor.execute, action)
        self._motion = _Motion(request, identity, future)

    def _check_motion(self) -> None:
        motion = self._motion
        if motion is None:
            return
        if motion.future.done():
            self._motion = None
            try:
                reply = self.session.finish_step(motion.request, motion.future.result())
            except Exception as error:  # the executor failed: the brain hears it, the server keeps serving
                log.exception("motion failed")
                reply = error_reply(motion.request.request_id, f"the motion failed: {error}")
            self._reply(motion.identity, motion.request, reply)
            return
        silent = time.monotonic() - self._last_heard
        if silent > self.config.deadman_s and not motion.deadman_fired:
            log.warning("deadman: nothing from the brain for %.1f s while moving: stopping the robot", silent)
            self.session.executor.stop()
            motion.deadman_fired = True

    def _reply(self, identity: bytes, request: Message, reply: Message) -> None:
        frames = self._router.frames(reply)
        if request.type != "PING":
            self._replies[request.request_id] = frames
            while len(self._replies) > self.config.reply_cache:
                self._replies.popitem(last=False)
        self._send(identity, frames)

    def _send(self, identity: bytes, frames: Frames) -> None:
        self._router.send(identity, frames)

    def _log_socket_event(self) -> None:
        kind = self._router.connection_event()
        if kind == zmq.EVENT_DISCONNECTED and (self._motion is not None or self.session.in_episode):
            log.warning(
                "the brain disconnected mid-episode (a frame over max_message_bytes=%d drops a connection silently)",
                self.config.max_message_bytes,
            )
        elif kind == zmq.EVENT_DISCONNECTED:
            log.info("a brain disconnected")


@contextlib.contextmanager
def served(session: RobotSession, keys: Path | None = None, bind: str = "tcp://127.0.0.1:*") -> Iterator[str]:
    """``session`` served from a background thread for the duration (a free loopback port by default); yields the
    endpoint."""
    with in_background(RobotServer(session, bind, keys), "drivenav-robot-server") as endpoint:
        yield endpoint
