"""Perception and reasoning regimes (docs/regimes.md): the embedded detector's presets, the oracle reasoner and
scorer, the grid of ``bench ablations --regimes`` and its table."""

from __future__ import annotations

import argparse
import json
import math
from pathlib import Path

import numpy as np
import pytest
from tests.test_embedded_reasoner import LABELS, SOFA, TOILET, Box, frame, view

from drivenav.analysis.ablation_data import MethodEntry
from drivenav.analysis.regimes import (
    REGIMES,
    Cell,
    RegimeReport,
    decomposition,
    format_regimes,
    orderings,
    parse_regimes,
    regime_args,
)
from drivenav.cli import main
from drivenav.envs.vocabulary import VOCABULARY
from drivenav.errors import InputError
from drivenav.semantics.embedded_detector import REGIMES as DETECTOR_PRESETS
from drivenav.semantics.embedded_detector import EmbeddedGrounder, regime_grounder
from drivenav.semantics.ground_truth import GroundTruthGrounder
from drivenav.semantics.model_spec import DETECTOR_REGIMES, ModelSpec
from drivenav.semantics.oracle import OracleReasoner, OracleScorer, goal_distance, sight_progress
from drivenav.semantics.protocols import Candidate, View
from drivenav.semantics.registry import check_models, model_requirements, scorer_requirements
from drivenav.settings import load_settings
from drivenav.types import GEODESIC, SEMANTIC, CameraIntrinsics, GroundTruth, Observation, Pose


class PointGoal:
    """A geodesic oracle in an open plane: Euclidean distance to one goal point, infinite inside a wall strip
    ``x > wall`` (the episode starts at ``start``); the goal is seen from ``heights``."""

    def __init__(
        self,
        goal: tuple[float, float],
        start: Pose | None = None,
        wall: float = math.inf,
        heights: tuple[float, ...] = (0.0,),
    ) -> None:
        self.goal, self._start, self.wall, self.heights = goal, start or Pose(0.0, 0.0, 0.0), wall, heights

    @property
    def start_pose(self) -> Pose:
        return self._start

    def distance(self, pose: Pose) -> float:
        if pose.x > self.wall:
            return math.inf
        return math.hypot(pose.x - self.goal[0], pose.y - self.goal[1])

    def forward(self, pose: Pose) -> tuple[Pose, bool]:
        return pose, False

    @property
    def goal_heights(self) -> tuple[float, ...]:
        return self.heights


def oracle(geodesic: PointGoal | None, goal: str = "sofa") -> OracleReasoner:
    reasoner = OracleReasoner()
    reasoner.begin_episode(goal, GroundTruth(LABELS, VOCABULARY, geodesic))
    return reasoner


def toward(label: int, *points: tuple[float, float], turn: float = 0.0, boxes: tuple[Box, ...] = ()) -> Candidate:
    """A candidate whose frontiers lie at ``points`` (a view showing ``boxes``)."""
    frontiers = tuple(Pose(x, y, 0.0) for x, y in points)
    return Candidate(label, turn, turn, 3.0, 60, view(label, *boxes), frontiers=frontiers)


# ----------------------------------------------------------------------------------------------- detector presets


def test_the_presets_order_how_readily_a_rare_phrasing_is_found() -> None:
    rare, near = 0.32, 0.86  # "settee" and "couch" for a sofa (embedded_detector's docstring)
    found = {name: DETECTOR_PRESETS[name].semantic_probability(rare, True) for name in ("strong", "paper", "weak")}
    assert found["strong"] > 0.99  # as readily as the category's own name
    assert found["paper"] == pytest.approx(0.40, abs=0.01)
    assert found["weak"] < 0.15
    assert DETECTOR_PRESETS["weak"].semantic_probability(near, True) < DETECTOR_PRESETS["paper"].semantic_probability(
        near, True
    )
    assert DETECTOR_PRESETS["strong"].semantic_probability(0.73, False) == pytest.approx(
        DETECTOR_PRESETS["paper"].semantic_probability(0.73, False) / 2
    )


def test_small_and_far_objects_are_missed_as_before_by_the_strong_preset_and_sooner_by_the_weak() -> None:
    for pixels, depth in ((150, 2.0), (300, 3.0), (900, 4.5)):
        paper = DETECTOR_PRESETS["paper"].visibility_probability(pixels, depth)
        assert DETECTOR_PRESETS["strong"].visibility_probability(pixels, depth) == paper
        assert DETECTOR_PRESETS["weak"].visibility_probability(pixels, depth) < paper


def test_each_regime_builds_its_grounder_and_paper_is_the_default() -> None:
    assert ModelSpec().detector_regime == "paper"
    assert set(DETECTOR_REGIMES) == {"exact", *DETECTOR_PRESETS}
    assert isinstance(regime_grounder("exact"), GroundTruthGrounder)
    weak = regime_grounder("weak")
    assert isinstance(weak, EmbeddedGrounder) and weak.config == DETECTOR_PRESETS["weak"]


def test_the_regime_is_a_setting_checked_by_name_and_only_for_the_embedded_detector() -> None:
    assert load_settings("drive-nav", options={"models.detector_regime": "weak"}).models.detector_regime == "weak"
    with pytest.raises(InputError, match=r"models\.detector_regime"):
        load_settings("drive-nav", overrides=["models.detector_regime=perfect"])
    with pytest.raises(InputError, match="--detector-regime"):
        check_models(ModelSpec(detector="ground-truth", detector_regime="strong"), connect=False)


# ----------------------------------------------------------------------------------------------- the oracle


def test_the_oracle_follows_the_frontier_nearest_the_goal_by_geodesic() -> None:
    reasoner = oracle(PointGoal((10.0, 0.0)))
    near, far = toward(1, (2.0, 5.0), (8.0, 1.0)), toward(2, (5.0, 0.0), turn=0.1)
    selection = reasoner.select_direction("sofa", [far, near])
    assert selection.label == 1 and not selection.target_visible  # 8,1 lies 2.24 m from the goal, 5,0 5 m
    assert goal_distance(PointGoal((10.0, 0.0)), near.frontiers) == pytest.approx(math.sqrt(5.0))


def test_the_oracle_reads_frontiers_in_the_episode_frame_and_skips_walls() -> None:
    start = Pose(10.0, 0.0, math.pi)  # the episode's +x is the world's -x
    geodesic = PointGoal((0.0, 0.0), start, wall=12.0)
    ahead, behind = toward(1, (8.0, 0.0)), toward(2, (-1.0, 0.0), (-3.0, 0.0))
    assert oracle(geodesic).select_direction("sofa", [behind, ahead]).label == 1  # world (2, 0): 2 m
    assert goal_distance(geodesic, behind.frontiers) == pytest.approx(11.0)  # world x 11; x 13 lies in the wall
    assert goal_distance(geodesic, (Pose(-3.0, 0.0, 0.0),)) == math.inf


def test_the_oracle_says_the_truth_about_the_target_in_view() -> None:
    reasoner = oracle(PointGoal((10.0, 0.0)))
    shows = toward(3, (0.0, 9.0), boxes=(SOFA,))
    selection = reasoner.select_direction("couch", [toward(1, (9.0, 0.0)), shows])
    assert selection.target_visible and selection.label == selection.target_label == 3
    assert (
        not oracle(PointGoal((10.0, 0.0)))
        .select_direction("sofa", [toward(3, (0.0, 9.0), boxes=(TOILET,))])
        .target_visible
    )


def test_oracle_verification_prompts_and_hints_come_from_the_truth() -> None:
    reasoner = oracle(PointGoal((10.0, 0.0)), goal="sofa")
    assert reasoner.verify("sofa", frame((200, 300, 100, 300), SOFA), []).judgement == "sure"
    assert reasoner.verify("sofa", frame((250, 400, 300, 400), TOILET), []).judgement == "not"
    assert reasoner.verify("sofa", frame((0, 10, 0, 10), SOFA, with_semantic=False), []).judgement == "uncertain"
    assert reasoner.propose_prompt("sofa", view(1, TOILET), "", []).phrase == "sofa"
    second = reasoner.propose_prompt("sofa", view(1), "", ["sofa"]).phrase
    assert second in VOCABULARY.synonyms("sofa")
    shares = VOCABULARY.room_shares("toilet")
    assert reasoner.category_hints("toilet").room == max(shares, key=lambda room: shares[room])
    assert reasoner.judge_floor("sofa", []).guess == "unsure"
    assert [call.kind for call in reasoner.calls][-1] == "judge_floor"


def test_the_oracle_says_whether_the_floor_its_views_were_taken_on_holds_a_goal() -> None:
    def judged(start_height: float, goal_heights: tuple[float, ...], *view_heights: float) -> str:
        """The oracle's floor answer for an episode started at ``start_height``, views at heights above the start."""
        reasoner = oracle(PointGoal((10.0, 0.0), Pose(0.0, 0.0, 0.0, start_height), heights=goal_heights))
        blank = view(1)
        views = [View(1, blank.rgb, None, Pose(0.0, 0.0, 0.0, z), 0.0, 0.0, 0) for z in view_heights]
        return reasoner.judge_floor("sofa", views).guess

    assert judged(3.0, (0.0,), 0.0) == "other"  # upstairs, the goal on the ground floor
    assert judged(3.0, (0.0,), 0.0, -3.0) == "this"  # the last view is the floor's: down there
    assert judged(3.0, (0.0, 3.1), 0.0) == "this"  # one of two goals on this floor
    assert judged(0.0, (1.2,), 0.0) == "this"  # a view point 1.2 m up is still this floor's (half a storey)
    assert judged(0.0, (1.25,), 0.0) == "other"
    assert judged(0.0, (), 0.0) == "other"  # no goal anywhere
    assert judged(3.0, (0.0,)) == "unsure"  # no views
    reasoner = oracle(None)
    assert reasoner.judge_floor("sofa", [view(1)]).guess == "unsure"  # no goal heights without a geodesic truth


def test_without_a_geodesic_the_oracle_chooses_as_the_embedded_reasoner() -> None:
    selection = oracle(None).select_direction("sofa", [toward(1, (1.0, 0.0)), toward(2, (2.0, 0.0), turn=0.2)])
    assert selection.label in (1, 2) and selection.note.startswith("embedded score")


def test_the_oracle_scorer_values_looking_along_the_geodesic() -> None:
    geodesic = PointGoal((10.0, 0.0))
    assert sight_progress(geodesic, Pose(0.0, 0.0, 0.0)) == pytest.approx(1.0)
    assert sight_progress(geodesic, Pose(0.0, 0.0, math.pi)) == 0.0
    assert sight_progress(geodesic, Pose(0.0, 0.0, math.pi / 2)) == 0.0  # sideways: every point ahead is farther
    assert sight_progress(geodesic, Pose(0.0, 0.0, math.pi / 3)) == pytest.approx(0.5, abs=0.05)  # cos 60 deg
    assert sight_progress(PointGoal((10.0, 0.0), wall=0.2), Pose(0.0, 0.0, 0.0)) == 0.0  # a wall ahead
    scorer = OracleScorer()
    scorer.begin_episode(GroundTruth(geodesic=PointGoal((0.0, 0.0), Pose(5.0, 0.0, math.pi))))
    intrinsics = CameraIntrinsics(4, 4, 2.0, 2.0, 2.0, 2.0)
    rgb, depth = np.zeros((4, 4, 3), np.uint8), np.ones((4, 4), np.float32)
    facing = Observation(rgb, depth, None, Pose(0.0, 0.0, 0.0), intrinsics, 0, False)
    assert scorer.score("sofa", facing) == pytest.approx(1.0)  # the episode's heading is the world's -x, to the goal
    scorer.begin_episode(None)
    assert scorer.score("sofa", facing) == 0.0 and len(scorer.calls) == 1


def test_the_oracle_asks_the_world_for_its_privileged_inputs() -> None:
    assert model_requirements(ModelSpec(reasoner="oracle")) == {GEODESIC, SEMANTIC}
    assert model_requirements(ModelSpec()) == {SEMANTIC}
    assert scorer_requirements(ModelSpec(scorer="oracle")) == {GEODESIC}
    assert scorer_requirements(ModelSpec()) == {SEMANTIC}


# ----------------------------------------------------------------------------------------------- the grid


def test_regime_names_and_the_options_they_set() -> None:
    assert parse_regimes("all") == list(REGIMES)
    assert parse_regimes("paper, exploration-bound,paper") == ["paper", "exploration-bound"]
    with pytest.raises(InputError, match="--regimes"):
        parse_regimes("paper,perfect")
    bound = REGIMES["exploration-bound"]
    assert (bound.reasoner, bound.scorer, bound.detector_regime) == ("oracle", "oracle", "exact")
    assert REGIMES["paper"].options() == {"reasoner": "embedded", "scorer": "embedded", "detector_regime": "paper"}
    args = argparse.Namespace(reasoner=None, scorer=None, detector_regime=None, seed=3)
    assert vars(regime_args(args, "oracle-reasoner")) == {
        **vars(args),
        "reasoner": "oracle",
        "scorer": "oracle",
        "detector_regime": "paper",
    }
    with pytest.raises(InputError, match="--scorer"):
        regime_args(argparse.Namespace(reasoner=None, scorer="embedded", detector_regime=None), "paper")


def _entry(sr: float) -> MethodEntry:
    return MethodEntry(10, 0, sr, sr / 2, 100.0, 1.0, (0.0, 1.0), (0.0, 1.0), 0.0, 1.0, 1.0, {})


def test_orderings_that_hold_and_those_that_flip() -> None:
    cells = {
        "paper": {"a": Cell(_entry(0.6), None), "b": Cell(_entry(0.5), None), "c": Cell(_entry(0.1), None)},
        "oracle-reasoner": {"a": Cell(_entry(0.6), None), "b": Cell(_entry(0.7), None), "c": Cell(_entry(0.1), None)},
    }
    report = RegimeReport("abc", 10, "test", {r: REGIMES[r] for r in cells}, cells)
    held, flipped = orderings(report)
    assert flipped == ["`a` above `b` in `paper`; below in `oracle-reasoner`"]
    assert held == ["`a` above `c` in every regime", "`b` above `c` in every regime"]


def test_the_failures_are_taken_apart_into_exploration_reasoning_and_perception() -> None:
    rates = {"exploration-bound": 0.8, "exact-detector": 0.7, "paper": 0.75}
    cells = {r: {"a": Cell(_entry(sr), None)} for r, sr in rates.items()}
    report = RegimeReport("abc", 10, "test", {r: REGIMES[r] for r in cells}, cells)
    assert decomposition(report, "a") == pytest.approx((20.0, 10.0, -5.0))
    assert "| `a` | 20.0 | +10.0 | -5.0 | 75.0 |" in format_regimes(report)
    del cells["paper"]
    assert decomposition(report, "a") is None


def test_bench_ablations_runs_the_regimes_into_one_table_and_resumes(tmp_path: Path) -> None:
    argv = ["bench", "ablations", "--benchmark", "v2", "--episodes", "1", "--methods", "drive-nav,nearest-frontier"]
    argv += ["--regimes", "paper,exploration-bound", "--out", str(tmp_path), "--workers", "1"]
    assert main(argv) == 0
    data = json.loads((tmp_path / "regimes.json").read_text())
    assert list(data["cells"]) == ["paper", "exploration-bound"]
    assert data["regimes"]["exploration-bound"]["detector_regime"] == "exact"
    assert data["cells"]["paper"]["nearest-frontier"]["paired"]["reference"] == "drive-nav"
    run = tmp_path / "regimes" / "exploration-bound" / "runs" / "drive-nav"
    record = json.loads((run / "episodes.jsonl").read_text().splitlines()[0])
    assert record["privileged"] == ["geodesic", "semantic"]
    settings = json.loads((run / "run.json").read_text())
    assert "exact" in json.dumps(settings)
    table = (tmp_path / "regimes.md").read_text()
    assert "| `nearest-frontier` | `exploration-bound` | 1 | " in table
    before = (run / "episodes.jsonl").read_text()
    assert main(argv) == 0  # resumed: nothing run again
    assert (run / "episodes.jsonl").read_text() == before
    assert main([*argv, "--reasoner", "oracle"]) == 2
