"""DRIVE-Nav's decision loop in scripted embedded scenes (paper Sec. IV-A c), and every baseline end to end."""

from __future__ import annotations

import math

import pytest

from agent_scenes import carved_scene, episode_for, t_junction
from drivenav.agent.body import ExplorerAgent
from drivenav.agent.trace import DirectionSelected, EventT, InspectionStarted, ScanStarted, of_type
from drivenav.agents import make_agent
from drivenav.benchmarks.generate import generate_episodes
from drivenav.envs.embedded.env import EmbeddedEnv
from drivenav.envs.embedded.library import SceneLibrary
from drivenav.envs.embedded.scene import ObjectInstance, Scene
from drivenav.eval.runner import run_episode
from drivenav.eval.trace import EpisodeTrace
from drivenav.inspection import sweep_turns
from drivenav.methods import METHODS
from drivenav.settings import load_settings
from drivenav.types import Action, SimConfig

SIM = SimConfig()


def _run(scene: Scene, agent_name: str, start: tuple[float, float], yaw: float, category: str, text: str = ""):  # type: ignore[no-untyped-def]
    env = EmbeddedEnv(lambda _: scene, SIM)
    agent = make_agent(load_settings(agent_name))
    return run_episode(env, agent, episode_for(scene, start, yaw, category, text), 0, SIM.max_steps)


def _events(trace: EpisodeTrace, kind: type[EventT]) -> list[EventT]:
    return of_type(trace.events, kind)


def test_target_down_one_branch_is_reached_and_stop_issued() -> None:
    record, _ = _run(t_junction(target_on_left=True), "drive-nav", (12.0, 2.5), math.pi / 2, "plant")
    assert record.success == 1, record
    assert record.stop_reason == "target_reached"
    assert record.distance_to_goal is not None and record.distance_to_goal <= SIM.success_distance


def test_no_360_scan_after_the_start() -> None:
    record, trace = _run(t_junction(target_on_left=False), "drive-nav", (12.0, 2.5), math.pi / 2, "plant")
    scans = _events(trace, ScanStarted)
    assert [e.step for e in scans] == [0]
    assert record.success == 1


def test_junction_inspection_turns_only_toward_new_directions() -> None:
    """At the T the agent sweeps over the forward 240 deg directions lacking views, no more than needed."""
    _, trace = _run(t_junction(target_on_left=True), "drive-nav", (12.0, 2.5), math.pi / 2, "plant")
    actions = trace.actions
    start_yaw = trace.yaws[0]
    decisions = [e.step for e in _events(trace, DirectionSelected)]
    inspections = _events(trace, InspectionStarted)
    assert inspections, "reaching the T must reveal new directions"
    for event in inspections:
        step = event.step
        heading = trace.yaws[step] - start_yaw  # observations report yaw in the episode frame
        planned = list(event.target_yaws)
        minimum = sweep_turns(heading, planned, math.radians(SIM.turn_angle_deg))
        assert minimum <= 8  # a forward-240 sweep never needs a full turn
        decided = min(s for s in decisions if s >= step)
        sweep = actions[step:decided]
        assert all(a in (Action.TURN_LEFT, Action.TURN_RIGHT) for a in sweep)
        assert len(sweep) == minimum


def test_direction_360_turns_more_than_drive_nav() -> None:
    scene = t_junction(target_on_left=False)
    drive, _ = _run(scene, "drive-nav", (12.0, 2.5), math.pi / 2, "plant")
    full, full_trace = _run(scene, "direction-360", (12.0, 2.5), math.pi / 2, "plant")
    assert len(_events(full_trace, ScanStarted)) >= 2
    assert drive.steps < full.steps


def test_dead_end_triggers_reselection() -> None:
    # A corridor north with a short dead-end stub to the west and the real way on to the east.
    scene = carved_scene(
        "test/dead_end",
        [(11.25, 1.5, 12.75, 9.0), (8.0, 7.5, 12.75, 9.0), (11.25, 7.5, 20.0, 9.0), (18.5, 7.5, 20.0, 16.0)],
        [ObjectInstance(1, "plant", (19.25, 15.5), (0.5, 0.5, 1.2))],
    )
    record, trace = _run(scene, "drive-nav", (12.0, 2.0), math.pi / 2, "plant")
    assert len(_events(trace, DirectionSelected)) >= 2
    assert record.success == 1


def test_blocked_doorway_does_not_loop_forever() -> None:
    # The only exit of the room is blocked by a low bench the camera sees over: the space beyond stays a frontier
    # the agent cannot reach. Searching for something absent, it must give up rather than oscillate until timeout.
    scene = carved_scene(
        "test/blocked",
        [(2.0, 3.0, 10.0, 11.0), (9.9, 6.5, 11.0, 7.5), (11.0, 4.0, 17.0, 10.0)],
        [
            ObjectInstance(1, "bench", (10.45, 7.0), (0.5, 1.0, 0.5)),
            ObjectInstance(2, "plant", (4.5, 9.5), (0.5, 0.5, 1.2)),
        ],
    )
    record, _ = _run(scene, "drive-nav", (6.0, 7.0), 0.0, "plant", text="unicorn")
    assert record.stop_reason == "no_frontier"
    assert record.steps < 250


@pytest.mark.parametrize("name", sorted(m.name for m in METHODS))
def test_every_variant_runs_an_episode_to_the_end(name: str) -> None:
    library = SceneLibrary("procedural:1", 4)
    [episode] = generate_episodes(library, 1, seed=4)
    env = EmbeddedEnv(library.load, SIM)
    agent = make_agent(load_settings(name))
    assert isinstance(agent, ExplorerAgent)
    record, trace = run_episode(env, agent, episode, 0, 80)
    assert record.error == ""
    assert record.stop_reason in {"timeout", "target_reached", "no_frontier"}
    assert trace.segment_starts and trace.segment_starts[0] == 0
