"""The evaluation runner: episodes through an environment and an agent, results appended kill-safely.

Each finished episode is one JSON line in ``DIR/episodes.jsonl``, appended, flushed and fsync'ed before the next
is written, so an interrupted run (even ``kill -9``) loses no finished episode; a rerun with the same ``--out``
skips finished episodes and never duplicates one. Results do not depend on the number of workers: each
episode's randomness is seeded from the run seed and the episode id alone.
"""

from __future__ import annotations

import json
import logging
import os
import traceback
import zlib
from collections.abc import Iterator
from concurrent.futures import ProcessPoolExecutor, as_completed
from contextlib import AbstractContextManager, nullcontext
from dataclasses import asdict, dataclass, field
from multiprocessing import get_context
from pathlib import Path
from typing import Any

import numpy as np
from numpy.typing import NDArray
from tqdm import tqdm

from drivenav.agent.base import Agent, PrivilegedInfo
from drivenav.agent.registry import make_agent
from drivenav.envs.embedded import EmbeddedEnv
from drivenav.envs.episode import Episode
from drivenav.envs.geodesic import GeodesicField, largest_component
from drivenav.envs.library import SceneLibrary
from drivenav.errors import InputError
from drivenav.eval import metrics
from drivenav.eval.report import summarize
from drivenav.eval.timings import to_columns
from drivenav.semantics.registry import ModelSpec
from drivenav.types import Action, Observation, SimConfig

log = logging.getLogger(__name__)

EPISODES_FILE = "episodes.jsonl"
SUMMARY_FILE = "summary.json"
RUN_FILE = "run.json"
TRACES_DIR = "traces"


@dataclass(frozen=True)
class RunSpec:
    """What a run directory was started with; a rerun must match it."""

    agent: str
    scenes: str
    seed: int
    max_steps: int
    models: ModelSpec = field(default_factory=ModelSpec)


@dataclass(frozen=True)
class Executor:
    """Where episodes run; records do not depend on it.

    ``local``: in this process for one worker, else a pool of ``workers`` processes. ``ray``: up to ``workers``
    Ray tasks at a time (default: the cluster's CPUs) on a private local instance, or on the cluster at
    ``ray_address``.
    """

    kind: str = "local"
    workers: int | None = None
    ray_address: str | None = None

    def __post_init__(self) -> None:
        if self.kind not in EXECUTORS:
            raise InputError("command line", "--executor", " or ".join(EXECUTORS), self.kind)
        if self.workers is not None and self.workers < 1:
            raise InputError("command line", "--workers", "a positive integer", self.workers)
        if self.ray_address is not None and self.kind != "ray":
            raise InputError("command line", "--ray-address", "only with --executor ray", self.ray_address)

    def session(self) -> AbstractContextManager[object]:
        """Around several runs: one Ray connection for all of them (nothing to hold for local runs)."""
        if self.kind != "ray":
            return nullcontext()
        from drivenav.eval.ray_executor import ray_session

        return ray_session(self.workers, self.ray_address)


EXECUTORS = ("local", "ray")


def episode_seed(run_seed: int, episode_id: str) -> int:
    """Per-episode seed from the run seed and the episode id (stable across processes and platforms)."""
    return zlib.crc32(f"{run_seed}:{episode_id}".encode())


def run_episode(
    env: EmbeddedEnv, agent: Agent, episode: Episode, run_seed: int, max_steps: int
) -> tuple[dict[str, Any], dict[str, Any]]:
    """Run one episode to STOP or the step budget; returns its record and its trace.

    An exception inside the episode ends it with ``stop_reason`` ``"error"`` (logged); it never escapes.
    """
    sim = env.config
    observation = env.reset(episode)
    navigable = largest_component(env.scene.navigable_grid(sim.agent_radius, sim.agent_height))
    goal_field = GeodesicField(navigable, env.scene.grid, episode.view_points_xy())
    labels = {obj.instance_id: obj.category for obj in env.scene.objects}
    agent.reset(episode.object_category, episode_seed(run_seed, episode.episode_id), labels)
    if agent.uses_privileged:
        agent.set_privileged(PrivilegedInfo(env.scene, navigable, goal_field, env.start_pose))
    goal_ids = np.array([goal.object_id for goal in episode.goals])
    target_seen = _shows(observation, goal_ids)
    positions = [(env.state.x, env.state.y)]
    yaws = [env.state.yaw]
    actions: list[int] = []
    collisions = 0
    called_stop = False
    error = ""
    while env.steps < max_steps and not called_stop:
        try:
            action = agent.act(observation)
            observation = env.step(action)
        except InputError:
            raise  # a user error (e.g. a replay that does not match the run) stops the run with its message
        except Exception as exc:  # an agent or world fault ends this episode only
            log.warning("episode %s: %s", episode.episode_id, exc)
            error = "".join(traceback.format_exception_only(type(exc), exc)).strip()
            break
        actions.append(int(action))
        target_seen = target_seen or _shows(observation, goal_ids)
        collisions += int(observation.collided)
        positions.append((env.state.x, env.state.y))
        yaws.append(env.state.yaw)
        called_stop = action == Action.STOP
    if error:
        stop_reason = "error"
    elif called_stop:
        stop_reason = agent.stop_reason or "agent_stop"
    else:
        stop_reason = "timeout"
    path = np.asarray(positions)
    distance_to_goal = goal_field.at(*positions[-1])
    geodesic = episode.geodesic_distance
    if not np.isfinite(geodesic):
        geodesic = goal_field.at(*positions[0])
    is_success = metrics.success(called_stop, distance_to_goal, sim.success_distance)
    path_length = metrics.path_length(path)
    record = {
        "episode_id": episode.episode_id,
        "scene_id": episode.scene_id,
        "object_category": episode.object_category,
        "canonical_category": episode.info.get("canonical_category", episode.object_category),
        "synonym": bool(episode.info.get("synonym", False)),
        "agent": agent.name,
        "success": int(is_success),
        "spl": round(metrics.spl(is_success, geodesic, path_length), 6),
        "steps": len(actions),
        "path_length": round(path_length, 4),
        "geodesic_distance": round(geodesic, 4),
        "distance_to_goal": round(distance_to_goal, 4) if np.isfinite(distance_to_goal) else None,
        "revisits": metrics.count_revisits(path, agent.segment_starts),
        "collisions": collisions,
        "stop_reason": stop_reason,
        "vlm_calls": agent.model_calls,
        "error": error,
        "failure_cause": failure_cause(is_success, stop_reason, target_seen),
        **agent.episode_stats(),
    }
    trace = {
        "episode_id": episode.episode_id,
        "scene_id": episode.scene_id,
        "positions": np.round(path, 4).tolist(),
        "yaws": np.round(yaws, 4).tolist(),
        "actions": actions,
        "segment_starts": list(agent.segment_starts),
        "events": agent.trace.to_json(),
        "step_ms": to_columns(agent.step_timings),
    }
    return record, trace


TARGET_SEEN_PIXELS = 150  # goal-instance pixels in one frame for the target to count as seen


def _shows(observation: Observation, goal_ids: NDArray[np.int64]) -> bool:
    """Whether the frame shows a goal instance clearly (ground truth, for the failure analysis only)."""
    if observation.semantic is None:
        return False
    return int(np.count_nonzero(np.isin(observation.semantic, goal_ids))) >= TARGET_SEEN_PIXELS


def failure_cause(success: bool, stop_reason: str, target_seen: bool) -> str:
    """Why an episode failed ("" for successes).

    ``false_positive_stop``: STOP away from every goal; ``missed_target``: a goal was in view at some step but
    not reached; otherwise the target was never in view and the cause is the stop reason: ``timeout``,
    ``no_frontier``, or ``target_never_seen`` (e.g. stuck or an error).
    """
    if success:
        return ""
    if stop_reason == "target_reached":
        return "false_positive_stop"
    if target_seen:
        return "missed_target"
    return stop_reason if stop_reason in ("timeout", "no_frontier") else "target_never_seen"


class _Worker:
    """Per-process state: the scene library, the environment and the agent, built once."""

    def __init__(self, spec: RunSpec, sim: SimConfig) -> None:
        self.spec = spec
        self.library = SceneLibrary(spec.scenes, spec.seed)
        self.env = EmbeddedEnv(self.library.load, sim)
        self.agent = make_agent(spec.agent, sim, spec.models)

    def run(self, episode: Episode) -> tuple[dict[str, Any], dict[str, Any]]:
        return run_episode(self.env, self.agent, episode, self.spec.seed, self.spec.max_steps)


_WORKER: _Worker | None = None


def _init_worker(spec: RunSpec, sim: SimConfig) -> None:
    global _WORKER
    _WORKER = _Worker(spec, sim)


def _run_in_worker(episode: Episode) -> tuple[dict[str, Any], dict[str, Any]]:
    assert _WORKER is not None
    return _WORKER.run(episode)


@dataclass(frozen=True)
class _EpisodeTask:
    """One episode for a process that may serve several runs (a Ray worker): the worker is rebuilt only when
    the run changes."""

    spec: RunSpec
    sim: SimConfig
    episode: Episode


def _run_task(task: _EpisodeTask) -> tuple[dict[str, Any], dict[str, Any]]:
    if _WORKER is None or (_WORKER.spec, _WORKER.env.config) != (task.spec, task.sim):
        _init_worker(task.spec, task.sim)
    return _run_in_worker(task.episode)


def read_finished(path: Path) -> list[dict[str, Any]]:
    """Records already in ``episodes.jsonl``; a torn last line (from a kill) is cut off the file."""
    if not path.exists():
        return []
    data = path.read_bytes()
    keep = data.rfind(b"\n") + 1
    if keep < len(data):
        with path.open("r+b") as handle:
            handle.truncate(keep)
    records = []
    for number, line in enumerate(data[:keep].splitlines(), start=1):
        if not line.strip():
            continue
        try:
            records.append(json.loads(line))
        except ValueError:
            raise InputError(path, f"line {number}", "one JSON object per line") from None
    return records


def _append(path: Path, record: dict[str, Any]) -> None:
    with path.open("a", encoding="utf-8") as handle:
        handle.write(json.dumps(record, sort_keys=True) + "\n")
        handle.flush()
        os.fsync(handle.fileno())


def _write_json_atomic(path: Path, payload: Any) -> None:
    tmp = path.with_suffix(path.suffix + ".tmp")
    tmp.write_text(json.dumps(payload, indent=2, sort_keys=True) + "\n", encoding="utf-8")
    os.replace(tmp, path)


def _check_run_spec(out: Path, spec: RunSpec) -> None:
    run_file = out / RUN_FILE
    if run_file.exists():
        previous = json.loads(run_file.read_text(encoding="utf-8"))
        previous.setdefault("models", asdict(ModelSpec()))
        for key, value in asdict(spec).items():
            if previous.get(key) != value:
                raise InputError(run_file, key, f"{previous.get(key)!r} (this directory's run) to resume", value)
    else:
        _write_json_atomic(run_file, asdict(spec))


def trace_path(out: Path, episode_id: str) -> Path:
    safe = "".join(ch if ch.isalnum() or ch in "-_." else "_" for ch in episode_id)
    return out / TRACES_DIR / f"{safe}.json"


def evaluate(
    episodes: list[Episode],
    spec: RunSpec,
    out: Path,
    executor: Executor | None = None,
    sim: SimConfig | None = None,
    show_progress: bool = True,
) -> dict[str, Any]:
    """Run every unfinished episode, append its record, and write ``summary.json``; returns the summary.

    A progress bar goes to standard error.
    """
    sim = sim or SimConfig(max_steps=spec.max_steps)
    out.mkdir(parents=True, exist_ok=True)
    _check_run_spec(out, spec)
    results = out / EPISODES_FILE
    done = {r["episode_id"] for r in read_finished(results)}
    todo = [e for e in episodes if e.episode_id not in done]
    (out / TRACES_DIR).mkdir(exist_ok=True)
    with tqdm(total=len(todo), desc=spec.agent, unit="ep", disable=not show_progress, mininterval=1.0) as bar:
        for record, trace in _run_all(todo, spec, sim, executor or Executor()):
            trace_path(out, record["episode_id"]).write_text(json.dumps(trace), encoding="utf-8")
            _append(results, record)
            bar.update(1)
    summary = summarize(read_finished(results))
    _write_json_atomic(out / SUMMARY_FILE, summary)
    return summary


def _run_all(
    todo: list[Episode], spec: RunSpec, sim: SimConfig, executor: Executor
) -> Iterator[tuple[dict[str, Any], dict[str, Any]]]:
    if not todo:
        return
    if executor.kind == "ray":
        from drivenav.eval.ray_executor import run_on_ray

        tasks = [_EpisodeTask(spec, sim, episode) for episode in todo]
        yield from run_on_ray(tasks, _run_task, executor.workers, executor.ray_address)
        return
    workers = executor.workers or 1
    if workers == 1:
        worker = _Worker(spec, sim)
        for episode in todo:
            yield worker.run(episode)
        return
    context = get_context("spawn")
    with ProcessPoolExecutor(workers, mp_context=context, initializer=_init_worker, initargs=(spec, sim)) as pool:
        futures = [pool.submit(_run_in_worker, episode) for episode in todo]
        for future in as_completed(futures):
            yield future.result()
