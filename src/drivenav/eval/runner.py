"""The evaluation runner: episodes through any world and an agent, results appended kill-safely.

Each finished episode is one :class:`~drivenav.eval.records.EpisodeRecord` line in ``DIR/episodes.jsonl``,
appended, flushed and fsync'ed before the next is written, so an interrupted run (even ``kill -9``) loses no
finished episode; a rerun with the same ``--out`` skips finished episodes and never duplicates one (it runs again
those that failed to start: :func:`~drivenav.eval.rundir.start_up_failures`). Results do
not depend on the number of workers: each episode's randomness is seeded from the run seed and the episode id.

The world is built in each worker from a picklable :class:`~drivenav.envs.base.EnvSpec`; its measures give the
Habitat metrics, the trajectory gives steps and revisits. Ground truth reaches only the agents that ask for it.
"""

from __future__ import annotations

import logging
import time
import zlib
from collections.abc import Iterator, Mapping, Sequence
from dataclasses import dataclass, field, replace
from pathlib import Path
from typing import Any

import numpy as np
from numpy.typing import NDArray
from tqdm import tqdm
from tqdm.contrib.logging import logging_redirect_tqdm

from drivenav import metrics
from drivenav.agent.base import Agent, BodyCounters, ModelCounters
from drivenav.agents import make_agent
from drivenav.envs.base import Env, EnvSpec, EpisodeMeasures
from drivenav.episode import Episode
from drivenav.errors import InputError, RunStoppedError, one_line
from drivenav.eval.executor import Executor
from drivenav.eval.records import ERROR, EpisodeRecord, checked_measures, failure_cause
from drivenav.eval.report import Summary, Throughput, rate_kept, summarize
from drivenav.eval.rundir import SUMMARY_FILE, RunDirectory, lost_to_a_server
from drivenav.eval.timings import to_columns
from drivenav.eval.trace import EpisodeError, EpisodeTrace
from drivenav.plugins import is_part_failure, plugin_in_traceback, stop_signals_marked
from drivenav.semantics.model_spec import ModelSpec
from drivenav.settings import Settings
from drivenav.types import SEMANTIC, Action, Observation

log = logging.getLogger(__name__)

FAIL_FAST_EPISODES = 4  # a run stops when its first max(workers, this) episodes all fail with one exception type


@dataclass(frozen=True)
class RunSpec:
    """What a run is: the world and the resolved settings (agent, models, seed, budgets); a rerun must match."""

    env: EnvSpec
    settings: Settings = field(default_factory=Settings)

    @property
    def agent(self) -> str:
        return self.settings.run.agent

    @property
    def seed(self) -> int:
        return self.settings.run.seed

    @property
    def max_steps(self) -> int:
        return self.settings.sim.max_steps


def build_agent(spec: RunSpec) -> Agent:
    """The run's agent (an unknown name is an :class:`InputError` on ``--agent``)."""
    return make_agent(spec.settings)


def check_world_supports(spec: RunSpec, agent: Agent) -> None:
    """Refuse, before any episode, an agent that needs ground truth the world cannot give."""
    missing = sorted(agent.requires - spec.env.provides)
    if missing:
        offered = ", ".join(sorted(spec.env.provides)) or "no ground truth"
        raise InputError(
            "command line",
            "--agent",
            f"an agent the {spec.env.name} world can run (it provides {offered})",
            f"{spec.agent}, which needs {', '.join(missing)}",
        )


def episode_seed(run_seed: int, episode_id: str) -> int:
    """Per-episode seed from the run seed and the episode id (stable across processes and platforms)."""
    return zlib.crc32(f"{run_seed}:{episode_id}".encode())


@dataclass
class _Trajectory:
    """What the runner sees of an episode: world-frame poses and the actions taken."""

    positions: list[tuple[float, float]] = field(default_factory=list)
    yaws: list[float] = field(default_factory=list)
    heights: list[float] = field(default_factory=list)
    actions: list[int] = field(default_factory=list)

    def add(self, env: Env) -> None:
        pose = env.world_pose()
        self.positions.append((pose.x, pose.y))
        self.yaws.append(pose.yaw)
        self.heights.append(pose.z)

    def points(self) -> NDArray[np.float64]:
        """The positions as ``(T, 2)``, or ``(T, 3)`` with their heights where the agent left height 0 (a building's
        floors: paths on two floors are never near each other)."""
        planar = np.asarray(self.positions, dtype=np.float64).reshape(-1, 2)
        if not any(self.heights):
            return planar
        return np.column_stack([planar, np.asarray(self.heights, dtype=np.float64)])


def _observed(observation: Observation, agent: Agent) -> Observation:
    """The observation as the agent may see it: ground-truth instance ids only for agents that ask."""
    if SEMANTIC in agent.requires or observation.semantic is None:
        return observation
    return replace(observation, semantic=None)


def _drive(env: Env, agent: Agent, episode: Episode, run_seed: int, max_steps: int, path: _Trajectory) -> bool:
    """Reset and step the episode to STOP or the step budget; whether the agent called STOP."""
    observation = env.reset(episode)
    truth = env.ground_truth(agent.requires) if agent.requires else None
    agent.reset(episode.object_category, episode_seed(run_seed, episode.episode_id), truth)
    path.add(env)
    while len(path.actions) < max_steps:
        action = agent.act(_observed(observation, agent))
        observation = env.step(action)
        path.actions.append(int(action))
        path.add(env)
        if action == Action.STOP:
            return True
    return False


def run_episode(
    env: Env, agent: Agent, episode: Episode, run_seed: int, max_steps: int, parts: Mapping[str, str] | None = None
) -> tuple[EpisodeRecord, EpisodeTrace]:
    """Run one episode to STOP or the step budget; returns its record and its trace.

    An exception from the agent, its models or the world ends this episode with ``stop_reason`` ``"error"``
    and the traceback in the trace; it never escapes (a user error, :class:`InputError`, stops the run). So do a
    ``SystemExit`` and a ``KeyboardInterrupt`` that no stop signal raised (a plug-in's own); a real Ctrl-C stops the
    run (:func:`~drivenav.plugins.is_part_failure`). The record names the plug-in whose code raised it, if any (one
    of ``parts``, the run's parts by entry-point group, where given: :func:`run_parts`).
    """
    path = _Trajectory()
    error: EpisodeError | None = None
    called_stop = False
    try:
        called_stop = _drive(env, agent, episode, run_seed, max_steps, path)
    except (InputError, RunStoppedError):
        raise  # e.g. a replay that does not match the run, a robot gone: the run stops with its message
    except BaseException as exc:
        if not is_part_failure(exc):
            raise
        error = episode_error(exc, parts)
    measures = EpisodeMeasures()  # a failed reset measured nothing
    if path.positions:
        try:
            measures = checked_measures(env.measures())
        except BaseException as exc:  # a world gone with its measures (a robot's link), or out of range: the first
            if not is_part_failure(exc):
                raise
            error = error or episode_error(exc, parts)
    if error is not None:
        stop_reason = ERROR
    elif called_stop:
        stop_reason = agent.stop_reason or "agent_stop"
    else:
        stop_reason = "timeout"
    record = _record(episode, agent, path, measures, stop_reason, error)
    return record, _trace(episode, agent, path, error)


def episode_error(exc: BaseException, parts: Mapping[str, str] | None = None) -> EpisodeError:
    """The error that ended an episode: its type, its message naming the plug-in (of ``parts`` where given) whose
    code raised it, if any, and its traceback."""
    error = EpisodeError.of(exc)
    return replace(error, message=described(exc, error.message, parts))


def described(exc: BaseException, message: str, parts: Mapping[str, str] | None = None) -> str:
    """``message`` about ``exc``, followed by the plug-in (of ``parts`` where given) whose code raised it, if any."""
    plugin = plugin_in_traceback(exc, parts)
    return " ".join(part for part in (message, f"(raised by {plugin})" if plugin else "") if part)


def run_parts(spec: RunSpec) -> dict[str, str]:
    """The parts a run uses, by entry-point group: its world, explorer and models."""
    models = spec.settings.models
    return {
        "drivenav.worlds": spec.env.name,
        "drivenav.explorers": spec.settings.explorer.name,
        "drivenav.reasoners": models.reasoner,
        "drivenav.grounders": models.detector,
        "drivenav.segmenters": models.segmenter,
        "drivenav.scorers": models.scorer,
    }


def _record(
    episode: Episode,
    agent: Agent,
    path: _Trajectory,
    measures: EpisodeMeasures,
    stop_reason: str,
    error: EpisodeError | None,
) -> EpisodeRecord:
    """The episode's record: what it was, what the world measured, what the agent did (paper Sec. V metrics)."""
    calls, stats = _model_use(agent, started=bool(path.positions))
    positions = path.points()
    retraced_revisits, retraced_m = metrics.retraced(positions)
    return EpisodeRecord(
        episode_id=episode.episode_id,
        scene_id=episode.scene_id,
        object_category=episode.object_category,
        canonical_category=str(episode.info.get("canonical_category", episode.object_category)),
        synonym=bool(episode.info.get("synonym", False)),
        agent=agent.name,
        success=measures.success,
        spl=measures.spl,
        steps=len(path.actions),
        path_length=measures.path_length,
        geodesic_distance=measures.geodesic_distance,
        distance_to_goal=measures.distance_to_goal,
        revisits=metrics.count_revisits(positions, agent.segment_starts),
        retraced_revisits=retraced_revisits,
        retraced_m=round(retraced_m, 4),
        collisions=measures.collisions,
        stop_reason=stop_reason,
        vlm_calls=calls,
        error=error.summary() if error is not None else "",
        failure_cause=failure_cause(measures.success, stop_reason, measures.target_seen),
        privileged=tuple(sorted(agent.requires)),
        stats=stats,
        body=agent.body_counters() if path.positions else BodyCounters(),
        explorer=agent.explorer_counters(),
    )


def _trace(episode: Episode, agent: Agent, path: _Trajectory, error: EpisodeError | None) -> EpisodeTrace:
    """The episode's trace: the poses rounded to 0.1 mm (and 1e-4 rad; heights where the agent left height 0),
    the agent's events and step timings."""
    positions = np.round(np.asarray(path.positions, dtype=np.float64).reshape(-1, 2), 4).tolist()
    heights = np.round(path.heights, 4).tolist() if any(path.heights) else []
    return EpisodeTrace(
        episode_id=episode.episode_id,
        scene_id=episode.scene_id,
        positions=tuple((float(x), float(y)) for x, y in positions),
        yaws=tuple(float(yaw) for yaw in np.round(path.yaws, 4).tolist()),
        heights=tuple(float(z) for z in heights),
        actions=tuple(path.actions),
        segment_starts=tuple(agent.segment_starts),
        events=tuple(agent.trace.events),
        step_ms=to_columns(agent.step_timings),
        error=error,
    )


def _model_use(agent: Agent, started: bool) -> tuple[int, ModelCounters]:
    """The episode's model calls and statistics (none for an episode that failed before the agent started)."""
    if not started:
        return 0, ModelCounters()
    return agent.model_calls, agent.episode_stats()


class _Worker:
    """Per-process state: the world and the agent, built once."""

    def __init__(self, spec: RunSpec) -> None:
        self.spec = spec
        self.env = spec.env.build(spec.settings.sim)
        self.agent = build_agent(spec)

    def run(self, episode: Episode) -> tuple[EpisodeRecord, EpisodeTrace]:
        """One episode; then the agent releases its episode state before the next scene loads. An exception there
        never replaces the episode's result: it is logged (the next episode's reset starts the agent anew)."""
        try:
            return run_episode(self.env, self.agent, episode, self.spec.seed, self.spec.max_steps, run_parts(self.spec))
        finally:
            try:
                self.agent.end_episode()
            except BaseException as exc:
                if not is_part_failure(exc):
                    raise
                why = described(exc, one_line(exc), run_parts(self.spec))
                log.warning("episode %r: the agent failed to end it: %s", episode.episode_id, why)


_WORKER: _Worker | None = None


def _worker_for(spec: RunSpec) -> _Worker:
    """This process's worker for ``spec`` (rebuilt when a process, e.g. a Ray worker, serves another run)."""
    global _WORKER
    if _WORKER is None or _WORKER.spec != spec:
        if _WORKER is not None:
            _WORKER.env.close()
        _WORKER = _Worker(spec)
    return _WORKER


def _in_process(executor: Executor, episodes: int) -> bool:
    """Whether :func:`run_all` runs the episodes in this process (one worker, no Ray)."""
    return executor.kind != "ray" and min(executor.workers or 1, episodes) == 1


def preflight(spec: RunSpec, executor: Executor, episodes: int) -> None:
    """Build the run's world, agent and models once here, before any worker starts, and refuse an agent that needs
    ground truth the world cannot give. A world or model that cannot start stops the run with one line
    (:class:`RunStoppedError`), not with one error record per episode. A run in this process keeps what was built."""
    try:
        worker = _worker_for(spec)
        worker.agent.start_models()
    except InputError:
        raise
    except BaseException as exc:
        if not is_part_failure(exc):
            raise
        raise RunStoppedError(
            f"the {spec.env.name} world or the {spec.agent} agent cannot start: "
            f"{described(exc, one_line(exc), run_parts(spec))}"
        ) from exc
    check_world_supports(spec, worker.agent)
    if not _in_process(executor, episodes):
        _release_worker()


def _release_worker() -> None:
    global _WORKER
    if _WORKER is not None:
        _WORKER.env.close()
        _WORKER = None


@dataclass(frozen=True)
class EpisodeTask:
    """One episode of one run, as sent to a pool process or a Ray task."""

    spec: RunSpec
    episode: Episode


def run_task(task: EpisodeTask) -> tuple[EpisodeRecord, EpisodeTrace]:
    """Run one episode in this process, building the world and the agent on first use."""
    return _worker_for(task.spec).run(task.episode)


def evaluate(
    episodes: Sequence[Episode],
    spec: RunSpec,
    out: Path,
    executor: Executor | None = None,
    show_progress: bool = True,
    served: ModelSpec | None = None,
) -> Summary:
    """Run every unfinished episode, append its record, and write ``summary.json``; returns the summary.

    The run directory is locked for the run (a second evaluation into it is refused) and must have been
    started with the same settings and episodes (else an :class:`InputError` names the first difference).
    A progress bar goes to standard error. ``served``: the models the workers use instead of the spec's (its
    detector served to them all, ``eval --share-detector``); the run directory records the spec's. Ctrl-C stops the
    run (a plug-in's own ``KeyboardInterrupt`` ends only its episode: :func:`~drivenav.plugins.stop_signals_marked`).
    """
    with stop_signals_marked():
        return _evaluate(episodes, spec, out, executor or Executor(), show_progress, served)


def _evaluate(
    episodes: Sequence[Episode],
    spec: RunSpec,
    out: Path,
    executor: Executor,
    show_progress: bool,
    served: ModelSpec | None,
) -> Summary:
    """:func:`evaluate`, its stop signals marked."""
    recorded = spec
    if served is not None:
        spec = replace(spec, settings=replace(spec.settings, models=served))
    preflight(spec, executor, len(episodes))
    with RunDirectory.open(out, recorded.env, recorded.settings, episodes) as run:
        done = run.finished
        todo = [e for e in episodes if e.episode_id not in done]
        label = f"{spec.agent} (resuming)" if done else spec.agent
        bar = tqdm(
            total=len(episodes), initial=len(done), desc=label, unit="ep", disable=not show_progress, mininterval=1.0
        )
        first: list[EpisodeRecord] = []
        rate = _Rate(time.perf_counter())
        with bar, logging_redirect_tqdm():
            for record, trace in run_all(todo, spec, executor):
                run.save(record, trace)
                _advance(bar, rate.add(record))
                _stop_if_failing_alike(first, record, max(executor.workers or 1, FAIL_FAST_EPISODES), out)
        records = run.records()
        summary = summarize(records, rate.throughput()) if todo else rate_kept(summarize(records), out / SUMMARY_FILE)
        run.write_summary(summary)
    if summary.errors:
        log.warning(
            "%d of %d episodes ended in an error; tracebacks are under 'error' in %s",
            summary.errors,
            summary.episodes,
            out / "traces",
        )
    lost = sum(lost_to_a_server(r) for r in records)
    if lost:
        log.warning(
            "%d of them were lost to a server (no reply, or a restart): rerun the same command to run them", lost
        )
    return summary


def _stop_if_failing_alike(first: list[EpisodeRecord], record: EpisodeRecord, count: int, out: Path) -> None:
    """Collect this session's first ``count`` records; if they all ended in one exception type, stop the run
    (:class:`RunStoppedError`): the same missing package or broken world would fail every episode. Errors after a
    success are only recorded."""
    if len(first) >= count:
        return
    first.append(record)
    kinds = {r.error.split(":", 1)[0] if r.stop_reason == ERROR else "" for r in first}
    if len(first) == count and len(kinds) == 1 and "" not in kinds:
        where = f"records in {out / 'episodes.jsonl'}, tracebacks under traces/"
        raise RunStoppedError(
            f"the first {count} episodes all ended in {record.error.splitlines()[0]} ({where}); "
            "fix it and rerun the same command to resume"
        )


@dataclass
class _Rate:
    """This session's episodes and frames since ``start`` (``time.perf_counter``), for the bar and the summary."""

    start: float
    episodes: int = 0
    frames: int = 0

    def add(self, record: EpisodeRecord) -> Throughput:
        self.episodes += 1
        self.frames += record.steps
        return self.throughput()

    def throughput(self) -> Throughput:
        return Throughput(self.episodes, self.frames, time.perf_counter() - self.start)


def _advance(bar: tqdm[Any], rate: Throughput) -> None:
    """One more episode on the bar, with the session's rate; the last one is drawn by closing the bar only (else
    its line prints twice)."""
    bar.set_postfix_str(rate.line(), refresh=False)
    if bar.total is not None and bar.n + 1 >= bar.total:
        bar.n += 1
    else:
        bar.update(1)


def run_all(todo: Sequence[Episode], spec: RunSpec, executor: Executor) -> Iterator[tuple[EpisodeRecord, EpisodeTrace]]:
    """Every episode's record and trace, in completion order, on ``executor``."""
    if not todo:
        return
    tasks = [EpisodeTask(spec, episode) for episode in todo]
    if executor.kind == "ray":
        from drivenav.eval.ray_executor import run_on_ray

        yield from run_on_ray(tasks, run_task, executor.workers, executor.ray_address, _task_key)
        return
    workers = min(executor.workers or 1, len(tasks))
    if workers == 1:
        for task in tasks:
            yield run_task(task)
        return
    from drivenav.eval.pool import run_in_pool

    yield from run_in_pool(tasks, run_task, workers, _task_key)


def _task_key(task: EpisodeTask) -> str:
    return task.episode.episode_id
