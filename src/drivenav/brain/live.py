"""One live episode on a robot (``drivenav run --env robot``): a progress line per step, Ctrl-C stops the robot.

The episode is an ordinary run directory (``episodes.jsonl``, the trace, ``summary.json``, a top-down picture of
the trace), so everything that reads runs reads it; a real robot's metrics are ``null``.
"""

from __future__ import annotations

import signal
import sys
import time
from collections.abc import Iterator
from contextlib import contextmanager
from dataclasses import dataclass
from pathlib import Path
from typing import TextIO

from drivenav.agent.base import Agent
from drivenav.agent.trace import DetectionEvent, DirectionSelected
from drivenav.envs.base import EpisodeMeasures
from drivenav.envs.robot import RobotEnv, RobotSpec
from drivenav.episode import Episode, world_to_habitat, yaw_to_quaternion
from drivenav.eval.records import EpisodeRecord
from drivenav.eval.report import summarize
from drivenav.eval.rundir import RunDirectory
from drivenav.eval.runner import RunSpec, build_agent, check_world_supports, run_episode
from drivenav.types import Action, GroundTruth, Observation, Pose, SimConfig
from drivenav.viz.episode import trace_picture
from drivenav.viz.saved_trace import SavedTrace


class OperatorStopError(Exception):
    """The operator pressed Ctrl-C: the robot was told to stop and the episode ends here."""


def live_episode(target: str, episode_id: str | None = None) -> Episode:
    """An episode on a robot: no scene the brain knows, no goals, the start wherever the robot stands."""
    return Episode(
        episode_id=episode_id or time.strftime("live-%Y%m%d-%H%M%S"),
        scene_id="robot",
        start_position=world_to_habitat(0.0, 0.0),
        start_rotation=yaw_to_quaternion(0.0),
        object_category=target,
        goals=(),
    )


def progress_line(step: int, action: Action, agent: Agent) -> str:
    """Step, action, the agent's latest event, the last direction the reasoner chose (why it was asked, whether it
    answered or a fallback chose, among how many) and the latest detection."""
    events = agent.trace.events
    activity = events[-1].kind if events else "start"
    selected = next((e for e in reversed(events) if isinstance(e, DirectionSelected)), None)
    detection = next((e for e in reversed(events) if isinstance(e, DetectionEvent)), None)
    parts = [f"step {step:4d}", f"{action.name:<12}", f"last event {activity}"]
    if selected is not None:
        answer = "fallback" if selected.fallback else "answered"
        parts.append(f"direction {selected.label} ({selected.reason}, {answer}, of {len(selected.candidates)})")
    if detection is not None:
        parts.append(f"seen {detection.phrase!r} {detection.score:.2f} at step {detection.step}")
    return " | ".join(parts)


@dataclass
class LiveEnv:
    """A :class:`RobotEnv` that prints a progress line per step and stops the robot on the operator's Ctrl-C."""

    env: RobotEnv
    agent: Agent
    out: TextIO = sys.stderr
    interrupted: bool = False

    @property
    def config(self) -> SimConfig:
        return self.env.config

    def reset(self, episode: Episode) -> Observation:
        return self.env.reset(episode)

    def step(self, action: Action) -> Observation:
        if self.interrupted:
            self.env.stop()
            raise OperatorStopError("stopped by the operator (Ctrl-C); the robot was told to stop")
        observation = self.env.step(action)
        print(progress_line(observation.step, action, self.agent), file=self.out, flush=True)
        return observation

    def world_pose(self) -> Pose:
        return self.env.world_pose()

    def measures(self) -> EpisodeMeasures:
        return self.env.measures()

    def ground_truth(self, kinds: frozenset[str]) -> GroundTruth:
        return self.env.ground_truth(kinds)

    def close(self) -> None:
        self.env.close()


@contextmanager
def operator_stop(live: LiveEnv) -> Iterator[None]:
    """Ctrl-C during the episode marks it interrupted (the next step stops the robot) instead of killing the
    brain mid-message."""

    def interrupt(signum: int, frame: object) -> None:
        live.interrupted = True

    previous = signal.signal(signal.SIGINT, interrupt)
    try:
        yield
    finally:
        signal.signal(signal.SIGINT, previous)


def run_live(spec: RunSpec, target: str, out: Path, episode_id: str | None = None) -> tuple[EpisodeRecord, Path | None]:
    """Run one live episode towards ``target`` on the robot of ``spec``, save it in the run directory ``out``
    (``episode_id``: the id its RESET carries, by default ``live-DATE-TIME``) and draw its trace; returns the record
    and the picture (None for an episode that ended before its start, e.g. a RESET the robot refused)."""
    assert isinstance(spec.env, RobotSpec)
    agent = build_agent(spec)
    check_world_supports(spec, agent)
    episode = live_episode(target, episode_id)
    env = spec.env.build(spec.settings.sim)
    live = LiveEnv(env, agent)
    try:
        with RunDirectory.open(out, spec.env, spec.settings, [episode]) as run, operator_stop(live):
            record, trace = run_episode(live, agent, episode, spec.seed, spec.max_steps)
            run.save(record, trace)
            run.write_summary(summarize(run.records()))
    finally:
        env.close()
    if not trace.positions:
        return record, None
    return record, trace_picture(episode, SavedTrace.of(trace, episode), record, out / "viz")
