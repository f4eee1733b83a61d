"""VLFM (``vlfm``, :mod:`drivenav.agent.explorers.vlfm.explorer`): the frontier choice on a scripted value map
(value first, the last frontier kept, cycles avoided), and whole embedded episodes -- a cue seen in the start scan
steers the first frontier, and the registry's ``vlfm`` finds the target with the embedded scorer."""

from __future__ import annotations

import math
from functools import partial

import numpy as np
import pytest

from agent_scenes import carved_scene, episode_for, t_junction
from drivenav.agent.body import ExplorerAgent
from drivenav.agent.explorers import explorer_entry
from drivenav.agent.explorers.vlfm.explorer import Ranked, ValueMemory, VlfmExplorer, best_acyclic, kept, rank
from drivenav.agent.trace import DirectionSelected, ScanStarted
from drivenav.agents import make_agent
from drivenav.directions.types import FrontierPath
from drivenav.envs.embedded.env import EmbeddedEnv
from drivenav.envs.embedded.scene import ObjectInstance
from drivenav.errors import InputError
from drivenav.eval.runner import run_episode
from drivenav.grid import GridSpec
from drivenav.mapping.types import Frontier
from drivenav.mapping.value_map import UNSEEN_VALUE, ValueMap, ValueMapConfig
from drivenav.semantics.protocols import ModelCall
from drivenav.semantics.registry import make_grounder
from drivenav.settings import explorer_section, load_settings
from drivenav.types import SEMANTIC, Action, GroundTruth, Observation, SimConfig

SIM = SimConfig()
CONFIG = ValueMapConfig()


def _frontier(frontier_id: int, point: tuple[float, float]) -> Frontier:
    points = np.array([point])
    return Frontier(frontier_id, points, np.zeros((1, 2), dtype=np.int64), point, 2.0)


def _path(frontier_id: int, target: tuple[float, float], travel_time: float) -> FrontierPath:
    return FrontierPath(frontier_id, target, travel_time, np.array([(0.0, 0.0), target]), target, 0.0, target)


def _scripted_map() -> ValueMap:
    """A 10 m map whose cells around (3, 0) hold 0.9, around (-3, 0) 0.2 and around (0, 3) 0.2; (0, -3) unseen."""
    value_map = ValueMap(GridSpec(0.05, (-5.0, -5.0), (200, 200)), 5.0)
    for (x, y), value in (((3.0, 0.0), 0.9), ((-3.0, 0.0), 0.2), ((0.0, 3.0), 0.2)):
        row, col = value_map.grid.cell_at(x, y)
        value_map.value[row - 5 : row + 5, col - 5 : col + 5] = value
        value_map.confidence[row - 5 : row + 5, col - 5 : col + 5] = 0.6
    return value_map


def _ranked() -> Ranked:
    frontiers = [_frontier(i, p) for i, p in enumerate(((-3.0, 0.0), (0.0, -3.0), (3.0, 0.0), (0.0, 3.0)))]
    paths = [
        _path(0, (-2.5, 0.0), 2.5),
        _path(1, (0.0, -2.5), 1.0),
        _path(2, (2.5, 0.0), 6.0),
        _path(3, (0.0, 2.5), 4.0),
    ]
    return rank(_scripted_map(), frontiers, paths)


def test_frontiers_rank_by_value_then_by_path_length() -> None:
    ranked = _ranked()
    assert [path.frontier_id for path, _, _ in ranked] == [2, 0, 3, 1]  # the far 0.9 first; 0.2 tie: shorter path
    assert [value for _, _, value in ranked] == pytest.approx([0.9, 0.2, 0.2, UNSEEN_VALUE])
    assert ranked[0][1] == (3.0, 0.0)  # valued at the frontier's point, not at its path's end


def test_the_last_frontier_is_kept_while_its_value_holds() -> None:
    ranked = _ranked()
    assert kept(ranked, ValueMemory(), CONFIG) is None  # nothing pursued yet
    assert kept(ranked, ValueMemory((-2.7, 0.2), 0.2), CONFIG) == 1  # within 0.5 m, value unchanged
    assert kept(ranked, ValueMemory((-2.7, 0.2), 0.205), CONFIG) == 1  # fell by less than 0.01
    assert kept(ranked, ValueMemory((-2.7, 0.2), 0.215), CONFIG) is None  # fell by more than 0.01
    assert kept(ranked, ValueMemory((-2.4, 0.0), 0.2), CONFIG) is None  # the frontier point moved 0.6 m


def test_a_choice_made_before_from_the_same_place_is_not_repeated() -> None:
    ranked = _ranked()
    here, top_two = (0.0, 0.0), (0.9, 0.2)
    memory = ValueMemory()
    assert best_acyclic(ranked, memory, here, top_two) == 0
    memory.history.add((here, (3.0, 0.0), top_two))
    assert best_acyclic(ranked, memory, here, top_two) == 1
    assert best_acyclic(ranked, memory, (0.25, 0.0), top_two) == 0  # elsewhere it is a new choice
    assert best_acyclic(ranked, memory, here, (0.8, 0.2)) == 0  # so it is with other values
    memory.history.update((here, point, top_two) for _, point, _ in ranked)
    distances = [math.dist(point, here) for _, point, _ in ranked]
    assert best_acyclic(ranked, memory, here, top_two) == int(np.argmax(distances))  # all cyclic: the farthest


class _SeesInstance:
    """A scorer that answers 1 when enough pixels of one instance are in view, else 0."""

    name = "sees-instance"

    def __init__(self, instance_id: int) -> None:
        self.instance_id = instance_id
        self.calls: list[ModelCall] = []

    def begin_episode(self, truth: GroundTruth | None) -> None:
        self.calls = []

    def score(self, goal: str, observation: Observation) -> float:
        self.calls.append(ModelCall("score", 0.0, "ok"))
        semantic = observation.semantic
        return float(semantic is not None and np.count_nonzero(semantic == self.instance_id) > 50)


@pytest.mark.parametrize("cue_x", [9.0, 15.0])
def test_a_cue_seen_in_the_start_scan_steers_the_first_frontier(cue_x: float) -> None:
    """An east-west corridor, the robot in its middle facing the wall: both ends are frontiers at the same distance.
    A sofa the scorer likes stands 3 m to one side; VLFM heads that way first, whichever side it is on."""
    plant = ObjectInstance(1, "plant", (2.6, 12.0), (0.4, 0.4, 1.0))
    sofa = ObjectInstance(2, "sofa", (cue_x, 12.5), (0.8, 0.4, 0.8))
    scene = carved_scene("test/cue", [(2.0, 11.25, 22.0, 12.75)], [plant, sofa])
    settings = load_settings("vlfm")
    agent = ExplorerAgent(
        SIM,
        settings.agent,
        settings.paper,
        settings.mapping,
        "vlfm",
        explorer_entry("vlfm"),
        explorer_section(settings, "vlfm"),
        grounder_factory=partial(make_grounder, settings.models),
        scorer_factory=partial(_SeesInstance, 2),
        requires=frozenset({SEMANTIC}),
    )
    env = EmbeddedEnv(lambda _: scene, SIM)
    record, trace = run_episode(env, agent, episode_for(scene, (12.0, 12.0), math.pi / 2, "plant"), 0, 60)
    assert [Action(a) for a in trace.actions[:12]] == [Action.TURN_LEFT] * 12  # the initial turn in place
    x_after = trace.positions[30][0]
    assert (x_after < 11.0) if cue_x < 12.0 else (x_after > 13.0), trace.positions[12:31]
    if cue_x < 12.0:  # the plant is that way too
        assert record.success == 1 and record.stop_reason == "target_reached"


def test_vlfm_finds_the_target_with_the_embedded_scorer() -> None:
    scene = t_junction(target_on_left=True)
    env = EmbeddedEnv(lambda _: scene, SIM)
    agent = make_agent(load_settings("vlfm"))
    assert isinstance(agent, ExplorerAgent) and agent.explorer_type is VlfmExplorer and SEMANTIC in agent.requires
    record, trace = run_episode(env, agent, episode_for(scene, (12.0, 2.5), math.pi / 2, "plant"), 0, SIM.max_steps)
    assert record.success == 1 and record.stop_reason == "target_reached", record
    assert [Action(a) for a in trace.actions[:12]] == [Action.TURN_LEFT] * 12
    assert [e.step for e in trace.events if isinstance(e, ScanStarted)] == [0]
    assert not [e for e in trace.events if isinstance(e, DirectionSelected)]  # no reasoner decision
    assert trace.segment_starts[:2] == (0, 12)  # the first frontier is chosen when the turn is done
    stats = agent.episode_stats()
    assert stats.vlm_calls_by_kind == {"score": record.steps}  # one image-text score per step, nothing else
    assert record.vlm_calls == record.steps


def test_the_vlfm_explorer_needs_a_scorer_and_the_old_switches_are_gone() -> None:
    """VLFM is an explorer (``explorer.name=vlfm``), not a switch of DRIVE-Nav's agent: the switches that made it
    one are refused with one line naming them."""
    with pytest.raises(InputError, match=r"agent\.value_map"):
        make_agent(load_settings("drive-nav", overrides=["agent.value_map=true"]))
    settings = load_settings("vlfm")
    with pytest.raises(ValueError, match="scorer"):
        ExplorerAgent(SIM, settings.agent, settings.paper, settings.mapping, "vlfm", explorer_entry("vlfm"))
