"""The body's floors end to end: an agent climbs to a target upstairs, descends to one downstairs, and goes up and
back down in the two-storey test building, keeping a map per floor in which the other floor's walls never appear;
with floors off it keeps one map."""

from __future__ import annotations

import math
from dataclasses import replace

import numpy as np
import pytest
from tests.floor_scenes import RES, STOREY, building_episode, two_floors

from drivenav.agent.body import ExplorerAgent
from drivenav.agents import make_agent
from drivenav.envs.embedded.building import Building, Storey
from drivenav.envs.embedded.env import EmbeddedEnv
from drivenav.envs.embedded.scene import Material, ObjectInstance
from drivenav.episode import Episode
from drivenav.semantics.protocols import FloorJudgement
from drivenav.settings import load_settings
from drivenav.types import Action, Pose, SimConfig

SIM = SimConfig()
Rect = tuple[float, float, float, float]
UPPER_WALL: Rect = (4.0, 4.4, 6.0, 4.5)  # x0, y0, x1, y1: a wall only upstairs
LOWER_WALL: Rect = (4.0, 0.5, 6.0, 0.6)  # and one only downstairs
OVERRIDES = ["models.reasoner=embedded", "models.detector=ground-truth"]


def walled() -> Building:
    """The test building with a wall on each floor that the other lacks."""
    building = two_floors()
    storeys = []
    for storey, wall in zip(building.storeys, (LOWER_WALL, UPPER_WALL), strict=True):
        structure = storey.plan.structure.copy()
        x0, y0, x1, y1 = wall
        structure[round(y0 / RES) : round(y1 / RES), round(x0 / RES) : round(x1 / RES)] = Material.WALL
        storeys.append(Storey(replace(storey.plan, structure=structure), storey.elevation))
    return replace(building, storeys=tuple(storeys))


def episode(building: Building, start: tuple[float, float, float], category: str) -> Episode:
    return building_episode(building, start, category, episode_id=category)


def wall_cells_in_map(agent: ExplorerAgent, floor: int, wall: Rect, start: Pose) -> int:
    """Obstacle cells of the agent's map of ``floor`` inside ``wall`` (world frame) ."""
    assert agent.floors is not None
    mapper = agent.floors.floors[floor].state.mapper
    obstacle = mapper.snapshot().obstacle
    x0, y0, x1, y1 = wall
    count = 0
    for x in np.arange(x0 + 0.025, x1, 0.05):
        for y in np.arange(y0 + 0.025, y1, 0.05):
            local = start.inverse().compose(Pose(float(x), float(y), 0.0))
            row, col = mapper.grid.cell_at(local.x, local.y)
            count += int(obstacle[row, col])
    return count


def drive(env: EmbeddedEnv, agent: ExplorerAgent, episode: Episode) -> None:
    """Run the episode to STOP or the step budget, leaving the agent's episode state in place."""
    observation = env.reset(episode)
    agent.reset(episode.object_category, 0, env.ground_truth(agent.requires))
    for _ in range(SIM.max_steps):
        action = agent.act(observation)
        observation = env.step(action)
        if action == Action.STOP:
            return


@pytest.mark.parametrize(
    ("start", "target", "other_floors_wall", "level"),
    [((1.0, 4.0, 0.0), "bed", UPPER_WALL, STOREY), ((7.3, 4.2, STOREY), "chair", LOWER_WALL, -STOREY)],
)
def test_an_agent_changes_floors_and_maps_each_floor_apart(
    start: tuple[float, float, float], target: str, other_floors_wall: Rect, level: float
) -> None:
    """The agent reaches a target on the other floor by the stairs (up, then down); the map of the floor it set
    off from holds none of the other floor's wall, though it looked up and down the stairwell on its way."""
    building = walled()
    env = EmbeddedEnv(lambda _: building, SIM)
    agent = make_agent(load_settings("drive-nav", overrides=OVERRIDES))
    assert isinstance(agent, ExplorerAgent)
    drive(env, agent, episode(building, start, target))
    assert env.measures().success == 1, agent.stop_reason
    assert agent.floors is not None and len(agent.floors.floors) == 2
    first, reached = agent.floors.floors  # the start's floor, then the floor the stairs led to
    assert first.level == 0.0 and reached.level == pytest.approx(level, abs=0.05)
    assert wall_cells_in_map(agent, 0, other_floors_wall, env.start_pose) == 0
    assert reached.state.mapper.snapshot().explored.sum() > 0  # the floor reached has a map of its own
    arrival = next(e.step for e in agent.trace.events if e.kind == "floor_reached")
    scans = [e.step for e in agent.trace.events if e.kind == "scan"]
    assert scans == [0, arrival]  # the floor reached begins with a scan, announced when it begins


@pytest.mark.parametrize(
    ("yaw_deg", "start"), [(15.0, (1.0, 1.5, 0.0)), (45.0, (1.0, 4.0, 0.0)), (45.0, (1.0, 1.5, 0.0))]
)
def test_an_agent_facing_no_multiple_of_a_turn_along_the_flight_still_climbs_it(
    yaw_deg: float, start: tuple[float, float, float]
) -> None:
    """Started 15 degrees off the flight's axis, the agent can face its heading only to within 15 degrees and drifts
    6.5 cm sideways a step: it keeps to the flight's centre line at the foot and climbs to the bed (before, it
    drifted off the foot into the flight's open side and gave the stairs up in each of these three)."""
    building = walled()
    env = EmbeddedEnv(lambda _: building, SIM)
    agent = make_agent(load_settings("drive-nav", overrides=OVERRIDES))
    assert isinstance(agent, ExplorerAgent)
    drive(env, agent, building_episode(building, start, "bed", "bed", yaw=math.radians(yaw_deg)))
    assert env.measures().success == 1, agent.stop_reason
    assert [e.kind for e in agent.trace.events if e.kind.startswith("floor_")] == ["floor_set_off", "floor_reached"]


def test_with_floors_off_the_agent_keeps_one_map() -> None:
    building = walled()
    env = EmbeddedEnv(lambda _: building, SIM)
    agent = make_agent(load_settings("drive-nav", overrides=[*OVERRIDES, "agent.floors.enabled=false"]))
    assert isinstance(agent, ExplorerAgent)
    drive(env, agent, episode(building, (1.0, 4.0, 0.0), "bed"))
    assert agent.floors is None


def test_an_agent_judging_the_target_upstairs_goes_up_and_comes_back_down(monkeypatch: pytest.MonkeyPatch) -> None:
    """Told at its first question that the plant is on another floor, the agent climbs, explores the upper floor,
    finds nothing left there, and comes back down by the stairs it knows to find the plant: each floor's map holds
    none of the other floor's wall."""
    lower, upper = walled().storeys
    plant = ObjectInstance(3, "plant", (7.4, 2.5), (0.3, 0.3, 0.6))  # downstairs, behind the flight from the start
    hidden = Storey(replace(lower.plan, objects=[*lower.plan.objects, plant]), lower.elevation)
    building = replace(walled(), storeys=(hidden, upper))
    env = EmbeddedEnv(lambda _: building, SIM)
    far = ["agent.floors.min_floor_steps=0", "agent.floors.near_way=0"]  # set off at once, by a way however far
    agent = make_agent(load_settings("drive-nav", overrides=[*OVERRIDES, *far]))
    assert isinstance(agent, ExplorerAgent)
    task = episode(building, (1.0, 4.0, 0.0), "plant")
    observation = env.reset(task)
    agent.reset(task.object_category, 0, env.ground_truth(agent.requires))
    assert agent.state is not None
    monkeypatch.setattr(agent.state.reasoner, "judge_floor", lambda goal, views: FloorJudgement("other"))
    for _ in range(SIM.max_steps):
        action = agent.act(observation)
        observation = env.step(action)
        if action == Action.STOP:
            break
    assert env.measures().success == 1, agent.stop_reason
    assert agent.floors is not None and agent.floors.changes == 2  # up, then down again
    assert wall_cells_in_map(agent, 0, UPPER_WALL, env.start_pose) == 0
    assert wall_cells_in_map(agent, 1, LOWER_WALL, env.start_pose) == 0
    assert wall_cells_in_map(agent, 1, UPPER_WALL, env.start_pose) > 0  # the upper floor's own wall is mapped
