"""The embedded world's floors: walking surfaces and their graph, motion up and down stairs with habitat-sim's
collision rule, geodesic distances through the stairs, the env's heights, and the oracle between floors."""

from __future__ import annotations

import math

import numpy as np
import pytest
from tests.floor_scenes import FLIGHT, STOREY, building_episode, two_floors

from drivenav.agent.oracle import OracleAgent
from drivenav.envs.embedded.building import Building, Storey
from drivenav.envs.embedded.env import EmbeddedEnv
from drivenav.envs.embedded.geodesic import GeodesicField, largest_component
from drivenav.envs.embedded.goals import scene_goals
from drivenav.envs.embedded.levels import MAX_STEP, LevelField, Levels
from drivenav.envs.embedded.terrain import terrain_of
from drivenav.types import GEODESIC, Action, Pose, SimConfig

SIM = SimConfig()


@pytest.fixture(scope="module")
def levels() -> Levels:
    return Levels(two_floors(), SIM.agent_radius, SIM.agent_height)


def test_one_storey_is_the_floor_plans_navigable_grid_and_distances() -> None:
    """On one storey the surfaces give exactly ``Scene.navigable_grid``, and the graph's Fast Marching agrees with
    scikit-fmm's within a centimetre."""
    plan = two_floors().storeys[0].plan
    one = Levels(Building("test/one", (Storey(plan, 0.0),)), SIM.agent_radius, SIM.agent_height)
    navigable = plan.navigable_grid(SIM.agent_radius, SIM.agent_height)
    assert np.array_equal(one.navigable[0], navigable)
    goal = (7.0, 4.0)
    ours = LevelField(one, [(*goal, 0.0)]).distances[0]
    reference = GeodesicField(largest_component(navigable), plan.grid, [goal]).distances
    finite = np.isfinite(reference)
    assert np.array_equal(np.isfinite(ours), finite)
    assert np.max(np.abs(ours[finite] - reference[finite])) < 0.01


def test_the_flight_joins_the_two_floors_into_one_reachable_area(levels: Levels) -> None:
    reachable = levels.reachable
    assert reachable[0].sum() > 0 and reachable[1].sum() > 0
    assert np.array_equal(reachable, levels.navigable)  # every navigable cell: one connected building
    on_flight = levels.node_at(4.0, 2.5, FLIGHT.base + FLIGHT.rise * 2.0 / FLIGHT.run)
    assert on_flight is not None and on_flight.layer == 0


def test_beside_the_high_part_of_the_flight_is_no_place_to_stand(levels: Levels) -> None:
    """A drop of a metre or more at the flight's open side: no cell at its foot's height within the agent's radius
    of the flight's high part, and none on the ramp within it of the edge."""
    assert levels.node_at(5.5, 1.85, 0.0) is None  # the floor beside the flight where it is 2.5 m up
    assert levels.node_at(5.5, 2.1, 2.5) is None  # the ramp's edge 0.1 m from that drop
    assert levels.node_at(5.5, 1.5, 0.0) is not None  # 0.5 m away from it


def test_upstairs_the_stairwell_and_its_railing_are_no_place_to_stand(levels: Levels) -> None:
    assert levels.node_at(4.0, 2.5, STOREY) is None  # over the opening
    assert levels.node_at(4.0, 3.1, STOREY) is None  # at the railing
    assert levels.node_at(4.0, 3.6, STOREY) is not None
    assert levels.node_at(7.0, 2.5, STOREY) is not None  # where the flight arrives


def test_forward_steps_climb_the_flight_without_collisions(levels: Levels) -> None:
    """MOVE_FORWARD up the flight: each step advances 0.25 m in plan and rises with the ramp, the squared 3-D move
    is never short of the intended one (habitat-sim's rule: no collision on stairs), and the agent arrives on the
    upper floor."""
    x, y, z = 1.5, 2.5, 0.0
    for _ in range(24):
        (nx, ny, nz), collided = levels.forward(x, y, z, 0.0, SIM.forward_step)
        assert not collided
        assert nx - x == pytest.approx(SIM.forward_step) and ny == y
        assert nz >= z
        x, y, z = nx, ny, nz
    assert x > FLIGHT.foot[0] + FLIGHT.run and z == STOREY


def test_forward_steps_descend_the_flight(levels: Levels) -> None:
    x, y, z = 7.0, 2.5, STOREY
    for _ in range(24):
        (x, y, z), collided = levels.forward(x, y, z, math.pi, SIM.forward_step)
        assert not collided
    assert z == 0.0 and x < FLIGHT.foot[0]


def test_a_step_into_a_wall_collides_and_a_step_off_the_side_of_the_flight_is_refused(levels: Levels) -> None:
    (x, y, z), collided = levels.forward(7.7, 2.5, STOREY, 0.0, SIM.forward_step)
    assert collided and x < 7.95 - SIM.agent_radius + 0.05
    height = FLIGHT.base + FLIGHT.rise * 3.0 / FLIGHT.run  # 3 m up the run, 2.2 m above the floor
    (x, y, z), collided = levels.forward(5.0, 2.5, height, -math.pi / 2.0, SIM.forward_step)
    assert not collided and y == pytest.approx(2.25)  # across the 1 m wide flight
    (x, y, z), collided = levels.forward(x, y, z, -math.pi / 2.0, SIM.forward_step)
    assert collided and z > 2.0 and y > 2.0  # stopped at its edge, still on the flight


def test_geodesic_distance_up_the_stairs_is_measured_in_three_dimensions(levels: Levels) -> None:
    """From the foot to the top the distance is the ramp's 3-D length, not its plan length."""
    top = (FLIGHT.foot[0] + FLIGHT.run + 0.3, 2.5, STOREY)
    field = LevelField(levels, [top])
    ramp = math.hypot(FLIGHT.run, FLIGHT.rise)
    distance = field.at(FLIGHT.foot[0] - 0.3, 2.5, 0.0)
    assert distance == pytest.approx(ramp + 0.6, rel=0.02)
    assert distance > FLIGHT.run + 0.6 + 1.0  # the plan length would be 1.6 m shorter


def test_a_goal_upstairs_is_far_from_the_point_below_it(levels: Levels) -> None:
    field = LevelField(levels, [(7.0, 4.0, STOREY)])
    assert field.at(7.0, 4.0, STOREY) == pytest.approx(0.0, abs=0.06)
    below = field.at(7.0, 4.0, 0.0)  # straight below, on the ground floor: round by the stairs
    assert below > 9.0


def test_view_points_lie_on_their_objects_floor() -> None:
    building = two_floors()
    goals = scene_goals(building, SIM)
    assert {vp.height for goal in goals.goals["bed"] for vp in goal.view_points} == {STOREY}
    assert {vp.height for goal in goals.goals["chair"] for vp in goal.view_points} == {0.0}
    assert goals.goals["bed"][0].position[1] == pytest.approx(STOREY + 0.3)


def test_the_env_reports_heights_and_the_oracle_climbs_to_a_goal_upstairs() -> None:
    building = two_floors()
    env = EmbeddedEnv(lambda _: building, SIM)
    episode = building_episode(building, (1.0, 4.0, 0.0), "bed")
    observation = env.reset(episode)
    assert env.world_pose().z == 0.0 and observation.pose.z == 0.0
    oracle = OracleAgent(SIM)
    truth = env.ground_truth(frozenset({GEODESIC}))
    assert truth.geodesic is not None and truth.geodesic.goal_heights == (STOREY,)  # the bed's floor
    oracle.reset("bed", 0, truth)
    for _ in range(300):
        action = oracle.act(observation)
        observation = env.step(action)
        if action == Action.STOP:
            break
    measures = env.measures()
    assert measures.success == 1 and measures.spl is not None and measures.spl > 0.9
    assert env.world_pose().z == STOREY and observation.pose.z == STOREY
    assert measures.geodesic_distance is not None and measures.path_length is not None
    assert measures.path_length >= measures.geodesic_distance * 0.98


def test_a_start_upstairs_is_placed_on_the_upper_floor() -> None:
    building = two_floors()
    env = EmbeddedEnv(lambda _: building, SIM)
    env.reset(building_episode(building, (7.0, 4.0, STOREY), "chair"))
    assert env.world_pose() == Pose(7.0, 4.0, 0.0, STOREY)
    with pytest.raises(ValueError, match="not navigable"):
        env.reset(building_episode(building, (4.0, 2.5, STOREY), "chair"))  # over the stairwell


def test_the_terrain_of_a_floor_plan_is_the_one_floor_world() -> None:
    plan = two_floors().storeys[0].plan
    terrain = terrain_of(plan, SIM)
    assert terrain.reachable.shape == (1, *plan.grid.shape)
    assert terrain.place(3.0, 4.0, 5.0) == 0.0  # heights are not read on one floor
    assert pytest.approx(0.2) == MAX_STEP
