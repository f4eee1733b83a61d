"""Goal paths from the directions pipeline's single FMM solve and the low-level planner that follows them
(paper Sec. IV: "the low-level planner follows the farthest frontier point in the selected direction")."""

from __future__ import annotations

import itertools
import math

import numpy as np
import pytest
from numpy.typing import NDArray
from scipy import ndimage

from drivenav.agent.planner import LocalPlanner, heading_error, reached
from drivenav.directions.pipeline import DirectionPipeline
from drivenav.directions.synthetic import extract_frontiers, make_snapshot, rect
from drivenav.envs.embedded.env import EmbeddedEnv
from drivenav.envs.embedded.motion import turn
from drivenav.envs.embedded.procedural import generate_house
from drivenav.episode import Episode, world_to_habitat, yaw_to_quaternion
from drivenav.mapping.config import MappingConfig
from drivenav.mapping.occupancy import OccupancyMapper
from drivenav.mapping.types import Frontier, MapSnapshot
from drivenav.paper import DriveNavConfig
from drivenav.types import Action, Pose, SimConfig

RES = 0.05
DEG = math.pi / 180.0
SIM = SimConfig()
TURN = math.radians(SIM.turn_angle_deg)


def _scene(free: NDArray[np.bool_], explored: NDArray[np.bool_]) -> tuple[MapSnapshot, list[Frontier]]:
    snapshot = make_snapshot(free, explored, RES, inflation=0.15)
    return snapshot, extract_frontiers(snapshot)


def walled_room() -> tuple[MapSnapshot, list[Frontier]]:
    """Room x in [0.5, 5.5], y in [0.5, 6.5] with a wall at x = 3 from y = 0.5 up to y = 5, a closed 1 m box
    (explored, free inside, cut off) at x in [4, 5], y in [1, 2], and unexplored free space east of x = 5.5."""
    free = np.zeros((140, 160), np.bool_)
    rect(free, 0.5, 0.5, 7.5, 6.5)
    blocked = np.zeros_like(free)
    rect(blocked, 2.9, 0.5, 3.1, 5.0)
    rect(blocked, 3.9, 0.9, 5.1, 2.1)
    inside = np.zeros_like(free)
    rect(inside, 4.0, 1.0, 5.0, 2.0)
    free &= ~blocked | inside
    explored = np.zeros_like(free)
    rect(explored, 0.3, 0.3, 5.5, 6.7)
    return _scene(free, explored)


def corridor() -> tuple[MapSnapshot, list[Frontier]]:
    """A 1.2 m wide corridor along y = 2 from x = 0.5 to x = 8, fully explored."""
    free = np.zeros((80, 180), np.bool_)
    rect(free, 0.5, 1.4, 8.0, 2.6)
    explored = np.zeros_like(free)
    rect(explored, 0.3, 1.2, 8.2, 2.8)
    return _scene(free, explored)


def _on_traversable(snapshot: MapSnapshot, path: NDArray[np.float64]) -> bool:
    cells = snapshot.grid.world_to_cell(path)
    return bool(np.all(snapshot.navigable[cells[:, 0], cells[:, 1]]))


# ------------------------------------------------------------------------------------------ goal paths


def test_goal_path_bends_around_the_wall_and_stays_on_navigable_cells() -> None:
    snapshot, frontiers = walled_room()
    robot, goal = (1.5, 3.0), (4.5, 3.0)
    result = DirectionPipeline(DriveNavConfig()).update(snapshot, frontiers, robot, goals=[goal])
    (path,) = result.goal_paths
    assert path is not None
    assert tuple(path[0]) == robot
    assert math.dist(path[-1], goal) < RES
    assert max(path[:, 1]) > 5.0  # over the wall's end, not through it
    assert _on_traversable(snapshot, path)
    assert float(np.hypot(*np.diff(path, axis=0).T).sum()) > 5.0  # the straight line would be 3 m


def test_unreachable_goals_get_none_and_the_order_of_goals_is_kept() -> None:
    snapshot, frontiers = walled_room()
    enclosed, far_away, in_wall = (4.5, 1.5), (20.0, 20.0), (3.0, 2.0)
    goals = [enclosed, (1.5, 5.5), far_away, in_wall]
    result = DirectionPipeline(DriveNavConfig()).update(snapshot, frontiers, (1.5, 3.0), goals=goals)
    assert snapshot.navigable[tuple(snapshot.grid.world_to_cell(enclosed))]  # free, but cut off
    assert result.goal_paths[0] is None
    assert result.goal_paths[2] is None
    near, snapped = result.goal_paths[1], result.goal_paths[3]
    assert near is not None and math.dist(near[-1], (1.5, 5.5)) < RES
    assert snapped is not None and math.dist(snapped[-1], in_wall) <= 1.0  # snapped out of the wall
    assert snapped[-1, 0] < 2.9  # to the robot's side of the wall: the nearest navigable cell


def test_goals_do_not_change_the_frontier_paths_or_directions() -> None:
    snapshot, frontiers = walled_room()
    robot = (1.5, 3.0)
    plain = DirectionPipeline(DriveNavConfig()).update(snapshot, frontiers, robot)
    assert plain.goal_paths == ()
    with_goal = DirectionPipeline(DriveNavConfig()).update(snapshot, frontiers, robot, goals=[(4.5, 3.0)])
    assert plain.paths.keys() == with_goal.paths.keys()
    for fid, path in plain.paths.items():
        assert np.array_equal(path.path, with_goal.paths[fid].path)
        assert path.bearing == with_goal.paths[fid].bearing
    assert [d.bearing for d in plain.directions] == [d.bearing for d in with_goal.directions]
    assert with_goal.timings_ms["backtracking"] > 0.0


def test_goal_paths_without_frontiers_and_at_the_robot() -> None:
    snapshot, _ = corridor()
    result = DirectionPipeline(DriveNavConfig()).update(snapshot, [], (1.0, 2.0), goals=[(7.0, 2.0), (1.0, 2.0)])
    ahead, here = result.goal_paths
    assert ahead is not None and math.dist(ahead[-1], (7.0, 2.0)) < RES
    assert np.all(np.abs(ahead[:, 1] - 2.0) < 0.2)  # straight down the corridor
    assert here is not None and len(here) >= 2 and math.dist(here[-1], (1.0, 2.0)) < RES
    assert result.directions == ()


# ------------------------------------------------------------------------------------------ planner


def _line(*points: tuple[float, float]) -> NDArray[np.float64]:
    """A densely sampled polyline through ``points``."""
    pieces = [np.linspace(a, b, 40, endpoint=False) for a, b in itertools.pairwise(points)]
    return np.vstack([*pieces, np.array([points[-1]])])


def _towards(angle_deg: float, length: float = 3.0) -> NDArray[np.float64]:
    a = angle_deg * DEG
    return _line((0.0, 0.0), (length * math.cos(a), length * math.sin(a)))


def test_corridor_goal_ahead_gives_move_forward() -> None:
    snapshot, _ = corridor()
    result = DirectionPipeline(DriveNavConfig()).update(snapshot, [], (1.0, 2.0), goals=[(7.0, 2.0)])
    planner = LocalPlanner(SIM)
    assert planner.act(result.goal_paths[0], Pose(1.0, 2.0, 0.0), False) == Action.MOVE_FORWARD
    assert planner.act(result.goal_paths[0], Pose(1.0, 2.0, math.pi), False) in (Action.TURN_LEFT, Action.TURN_RIGHT)


@pytest.mark.parametrize(
    ("angle_deg", "expected"),
    [
        (90.0, Action.TURN_LEFT),
        (-90.0, Action.TURN_RIGHT),
        (14.0, Action.MOVE_FORWARD),
        (16.0, Action.TURN_LEFT),
        (-14.0, Action.MOVE_FORWARD),
        (-16.0, Action.TURN_RIGHT),
    ],
)
def test_turn_direction_and_the_half_turn_threshold(angle_deg: float, expected: Action) -> None:
    assert LocalPlanner(SIM).act(_towards(angle_deg), Pose(0.0, 0.0, 0.0), False) == expected


def test_heading_is_measured_from_the_current_yaw() -> None:
    pose = Pose(0.0, 0.0, 170.0 * DEG)
    assert heading_error(pose, (-1.0, -0.1)) == pytest.approx(15.71 * DEG, abs=0.01 * DEG)
    assert LocalPlanner(SIM).act(_towards(-170.0), pose, False) == Action.TURN_LEFT  # across the +-pi seam


def test_missing_or_degenerate_paths_and_reached() -> None:
    planner = LocalPlanner(SIM)
    pose = Pose(0.0, 0.0, 0.0)
    assert planner.act(None, pose, False) is None and planner.failure == "no_path"
    assert planner.act(np.zeros((1, 2)), pose, False) is None and planner.failure == "no_path"
    assert planner.act(_line((0.0, 0.0), (0.1, 0.0)), pose, False) is None and planner.failure == "at_goal"
    assert planner.act(_towards(0.0), pose, False) == Action.MOVE_FORWARD and planner.failure == ""
    assert reached(_towards(0.0), Pose(2.7, 0.1, 1.0), 0.5)
    assert not reached(_towards(0.0), Pose(2.0, 0.0, 0.0), 0.5)
    assert not reached(None, pose, 10.0)


def test_a_blocked_step_is_followed_by_an_escape_toward_the_path_side() -> None:
    planner = LocalPlanner(SIM)
    path = _towards(8.0)  # the path leads slightly to the left
    pose = Pose(0.0, 0.0, 0.0)
    assert planner.act(path, pose, False) == Action.MOVE_FORWARD
    escape = [planner.act(path, pose, collided=True)]
    pose = Pose(0.0, 0.0, turn(pose.yaw, Action.TURN_LEFT, TURN))
    escape.append(planner.act(path, pose, False))
    pose = Pose(0.0, 0.0, turn(pose.yaw, Action.TURN_LEFT, TURN))
    escape.append(planner.act(path, pose, False))
    assert escape == [Action.TURN_LEFT, Action.TURN_LEFT, Action.MOVE_FORWARD]
    # That step is blocked too: the escape goes on to the same side, further.
    again = [planner.act(path, pose, collided=True) for _ in range(4)]
    assert again == [Action.TURN_LEFT] * 4


def test_a_sliding_step_that_made_progress_needs_no_escape() -> None:
    planner = LocalPlanner(SIM)
    path = _towards(0.0)
    assert planner.act(path, Pose(0.0, 0.0, 0.0), False) == Action.MOVE_FORWARD
    assert planner.act(path, Pose(0.2, 0.0, 0.0), collided=True) == Action.MOVE_FORWARD


def _simulate_wall(planner: LocalPlanner, path: NDArray[np.float64], calls: int) -> list[Action | None]:
    """The robot turns as told but every forward step is blocked where it stands."""
    pose = Pose(0.0, 0.0, 0.0)
    collided = False
    actions: list[Action | None] = []
    for _ in range(calls):
        action = planner.act(path, pose, collided)
        actions.append(action)
        if action is None:
            break
        pose = Pose(0.0, 0.0, turn(pose.yaw, action, TURN))
        collided = action == Action.MOVE_FORWARD
    return actions


def test_repeated_blocked_steps_never_repeat_the_same_move_and_end_as_stuck() -> None:
    planner = LocalPlanner(SIM, stuck_steps=6)
    actions = _simulate_wall(planner, _towards(0.0), 200)
    assert actions[-1] is None and planner.failure == "stuck"
    moves = [a for a in actions if a is not None]
    assert moves.count(Action.MOVE_FORWARD) == 6
    for a, b in itertools.pairwise(moves):
        assert not (a == b == Action.MOVE_FORWARD)  # a blocked step is never retried as it was
    assert planner.act(_towards(0.0), Pose(0.0, 0.0, 0.0), False) == Action.MOVE_FORWARD  # history cleared


def test_stuck_after_k_forward_steps_without_progress_and_reset_clears_it() -> None:
    planner = LocalPlanner(SIM, stuck_steps=12, stuck_progress=0.15)
    path = _towards(0.0, 5.0)
    for k in range(12):  # the robot creeps 1 cm per step (e.g. pushing a soft obstacle), no collision reported
        assert planner.act(path, Pose(0.01 * k, 0.0, 0.0), False) == Action.MOVE_FORWARD
    assert planner.act(path, Pose(0.12, 0.0, 0.0), False) is None and planner.failure == "stuck"
    for k in range(11):
        assert planner.act(path, Pose(0.12 + 0.01 * k, 0.0, 0.0), False) == Action.MOVE_FORWARD
    planner.reset()  # a new goal: the evidence so far no longer counts
    for k in range(12):
        assert planner.act(path, Pose(0.01 * k, 0.0, 0.0), False) == Action.MOVE_FORWARD


def test_steady_progress_is_never_stuck() -> None:
    planner = LocalPlanner(SIM, stuck_steps=12)
    path = _towards(0.0, 20.0)
    for k in range(60):
        assert planner.act(path, Pose(0.25 * k, 0.0, 0.0), False) == Action.MOVE_FORWARD


def test_turning_in_place_forever_is_reported_as_spinning() -> None:
    planner = LocalPlanner(SIM, max_turns=12)
    actions = [planner.act(_towards(180.0), Pose(0.0, 0.0, 0.0), False) for _ in range(13)]
    assert actions[:12] == [Action.TURN_LEFT] * 12  # the caller never applied them
    assert actions[12] is None and planner.failure == "spinning"


# ------------------------------------------------------------------------------------------ end to end


def _start_episode(seed: int) -> tuple[EmbeddedEnv, Episode]:
    """An episode in procedural house ``seed`` starting at its most open navigable spot."""
    scene = generate_house(seed)
    navigable = scene.navigable_grid(SIM.agent_radius, SIM.agent_height)
    row, col = np.unravel_index(np.argmax(ndimage.distance_transform_edt(navigable)), navigable.shape)
    x, y = scene.grid.cell_to_world((row, col))
    episode = Episode("planner", scene.scene_id, world_to_habitat(x, y), yaw_to_quaternion(0.3), "chair", ())
    return EmbeddedEnv(lambda _: scene, SIM), episode


def _visible_goal(snapshot: MapSnapshot, robot: tuple[float, float]) -> tuple[float, float]:
    """The navigable cell 3-8 m from the robot with >= 0.35 m clearance that is farthest from it."""
    gx, gy = snapshot.grid.cell_centers()
    distance = np.hypot(gx - robot[0], gy - robot[1])
    clearance = ndimage.distance_transform_edt(~snapshot.obstacle) * snapshot.grid.resolution
    candidates = snapshot.navigable & (distance >= 3.0) & (distance <= 8.0) & (clearance >= 0.35)
    assert candidates.any()
    row, col = np.unravel_index(np.argmax(np.where(candidates, distance, -1.0)), distance.shape)
    x, y = snapshot.grid.cell_to_world((row, col))
    return float(x), float(y)


@pytest.mark.parametrize("seed", [3, 7])
def test_end_to_end_the_planner_drives_to_a_goal_in_a_house(seed: int) -> None:
    env, episode = _start_episode(seed)
    mapper = OccupancyMapper(MappingConfig.from_sim(SIM))
    pipeline = DirectionPipeline(DriveNavConfig())
    planner = LocalPlanner(SIM)
    observation = env.reset(episode)
    for _ in range(12):  # the start scan, so that the map covers the goal
        mapper.update(observation.depth, observation.intrinsics, observation.pose)
        observation = env.step(Action.TURN_LEFT)
    start = (observation.pose.x, observation.pose.y)
    goal = _visible_goal(mapper.snapshot(), start)
    assert math.dist(start, goal) >= 4.0
    for _ in range(80):
        pose = observation.pose
        if math.dist((pose.x, pose.y), goal) <= 0.5:
            break
        mapper.update(observation.depth, observation.intrinsics, pose)
        result = pipeline.update(mapper.snapshot(), mapper.frontiers(), (pose.x, pose.y), goals=[goal])
        action = planner.act(result.goal_paths[0], pose, observation.collided)
        assert action is not None, planner.failure
        observation = env.step(action)
    assert math.dist((observation.pose.x, observation.pose.y), goal) <= 0.5
