"""ApexNav on the agent body (Zhang et al., RA-L 2025): frontier scores, the statistic and the mode switch on hand-made
value maps, the open asymmetric TSP on hand-solved cases, target-centric fusion on a hand-computed sequence with
negative evidence, the value map written onto the frame's free cells, the category question of every reasoner, and
determinism."""

from __future__ import annotations

import itertools
import math
import subprocess
import sys
from collections.abc import Sequence
from pathlib import Path

import numpy as np
import pytest

from agent_scenes import episode_for, t_junction
from drivenav.agent.config import FusionConfig
from drivenav.agent.explorers.apexnav.frontiers import (
    FrontierCells,
    Statistic,
    blocked_cells,
    centroids,
    high_value,
    piece_score,
    pieces,
)
from drivenav.agent.explorers.apexnav.tsp import cost_matrix, open_tour
from drivenav.agent.fusion import ObjectFusion, cell_keys
from drivenav.agents import make_agent
from drivenav.envs.embedded.env import EmbeddedEnv
from drivenav.errors import InputError
from drivenav.eval.runner import run_episode
from drivenav.grid import GridSpec
from drivenav.mapping.types import Frontier, MapSnapshot, Rays
from drivenav.mapping.value_map import ValueMap, ValueMapConfig
from drivenav.semantics.answers import AnswerError, parse_hints
from drivenav.semantics.embedded import EmbeddedReasoner
from drivenav.semantics.embedded_scorer import EmbeddedScorer
from drivenav.semantics.fake_vlm_server import FAKE_SIMILAR, start_fake_server
from drivenav.semantics.geometric import GeometricReasoner
from drivenav.semantics.openai_backend import OpenAIReasoner
from drivenav.semantics.protocols import CategoryHints, ScorePrompt
from drivenav.semantics.replay import RecordingReasoner, ReplayReasoner
from drivenav.settings import load_settings
from drivenav.types import CameraIntrinsics, GroundTruth, Pose, SimConfig
from frames import observation_of

RES = 0.05
GRID = GridSpec(RES, (0.0, 0.0), (60, 60))
SIM = SimConfig()


# ----------------------------------------------------------------------------------------------- hand-made maps


def cell_centre(row: int, col: int) -> tuple[float, float]:
    return (col + 0.5) * RES, (row + 0.5) * RES


def frontier_at(frontier_id: int, cells: Sequence[tuple[int, int]]) -> Frontier:
    rc = np.array(cells, dtype=np.int64)
    points = np.array([cell_centre(r, c) for r, c in cells])
    return Frontier(frontier_id, points, rc, (float(points[0, 0]), float(points[0, 1])), 10.0)


def open_snapshot(blocked: Sequence[tuple[int, int]] = ()) -> MapSnapshot:
    explored = np.ones(GRID.shape, dtype=np.bool_)
    navigable = np.ones(GRID.shape, dtype=np.bool_)
    for row, col in blocked:
        navigable[row, col] = False
    return MapSnapshot(GRID, np.zeros(GRID.shape, dtype=np.bool_), explored, navigable)


def score_of(frontier: Frontier, value: np.ndarray, snapshot: MapSnapshot) -> float:
    return piece_score(centroids(frontier.points, 0.65), value, blocked_cells(snapshot), snapshot.grid, 0.1)


def test_a_frontier_scores_the_largest_value_of_the_five_by_five_cells_around_its_centre() -> None:
    value = np.zeros(GRID.shape)
    snapshot = open_snapshot(blocked=[(31, 10)])
    first = frontier_at(0, [(10, 9), (10, 10), (10, 11)])  # centroid: cell (10, 10)
    value[12, 12] = 0.9  # the window's corner (+2, +2): counted
    value[10, 13] = 0.99  # three cells off: outside the 5 x 5 window
    second = frontier_at(1, [(30, 10)])
    value[31, 10] = 0.95  # inside the window, but an obstacle or its inflation: left out
    value[28, 10] = 0.3
    assert score_of(first, value, snapshot) == 0.9
    assert score_of(second, value, snapshot) == 0.3
    assert score_of(frontier_at(2, [(50, 50)]), value, snapshot) == 0.0  # nothing seen around it


def test_a_long_frontier_is_split_and_scores_its_best_piece() -> None:
    row = [(5, c) for c in range(10, 50)]  # 2 m: two pieces of 1 m, each within 0.65 m of its centroid
    parts = pieces(frontier_at(0, row).points, 0.65)
    assert sorted(len(p) for p in parts) == [20, 20]
    value = np.zeros(GRID.shape)
    value[5, 40] = 0.7  # the middle cell of the far piece (cells 30..49): inside its window
    value[5, 29] = 0.8  # the piece boundary: in neither piece's window
    assert score_of(frontier_at(0, row), value, open_snapshot()) == 0.7


def test_the_statistic_and_the_switch_on_hand_computed_scores() -> None:
    spread = Statistic.of(np.array([0.9, 0.3, 0.3]))
    assert spread.mean == pytest.approx(0.5) and spread.ratio == pytest.approx(1.8)
    assert spread.sigma == pytest.approx(math.sqrt(0.08))  # population: ((0.4^2 + 2 * 0.2^2) / 3) ** 0.5
    assert spread.semantic(0.015, 1.10)
    assert high_value(np.array([0.9, 0.3, 0.3]), spread, 1.10, 0.90) == [0]  # >= max(0.55, 0.81)
    flat = Statistic.of(np.array([0.30, 0.31, 0.305]))
    assert flat.sigma < 0.015 and not flat.semantic(0.015, 1.10)  # no spread: geometric
    even = Statistic.of(np.array([1.0, 1.0, 1.0, 0.9]))
    assert even.sigma > 0.015 and even.ratio < 1.10 and not even.semantic(0.015, 1.10)  # nothing stands out
    pair = np.array([0.6, 0.58, 0.1, 0.1])
    assert high_value(pair, Statistic.of(pair), 1.10, 0.90) == [0, 1]  # >= max(0.4235, 0.54)
    assert Statistic.of(np.zeros(3)).ratio == 0.0


def test_the_switch_on_a_hand_made_value_map() -> None:
    value = np.zeros(GRID.shape)
    frontiers = [frontier_at(i, [(10 + 15 * i, 30)]) for i in range(3)]
    for i, level in enumerate((0.2, 0.2, 0.6)):
        value[10 + 15 * i, 31] = level
    snapshot = open_snapshot()
    scores = np.array([score_of(f, value, snapshot) for f in frontiers])
    assert scores.tolist() == [0.2, 0.2, 0.6]
    statistic = Statistic.of(scores)
    assert statistic.semantic(0.015, 1.10) and high_value(scores, statistic, 1.10, 0.90) == [2]
    value[40, 31] = 0.21  # the third barely above the others: no spread, so the nearest frontier
    scores = np.array([score_of(f, value, snapshot) for f in frontiers])
    assert not Statistic.of(scores).semantic(0.015, 1.10)


def test_frontiers_are_the_same_until_a_fifth_of_their_cells_changed() -> None:
    before = FrontierCells.of([frontier_at(0, [(5, c) for c in range(10)]), frontier_at(1, [(20, 20)])], RES)
    eight = FrontierCells.of([frontier_at(0, [(5, c) for c in range(8)] + [(6, 0), (6, 1)])], RES)
    seven = FrontierCells.of([frontier_at(0, [(5, c) for c in range(7)] + [(6, 0), (6, 1), (6, 2)])], RES)
    assert eight.matches(before, 0.2).tolist() == [[True, False]]
    assert seven.matches(before, 0.2).tolist() == [[False, False]]


# ----------------------------------------------------------------------------------------------- TSP


def line_matrix(xs: Sequence[float]) -> np.ndarray:
    """Frontiers on a line through the robot at 0: path lengths are distances along it."""
    x = np.array(xs)
    return cost_matrix(np.abs(x), np.abs(x[:, None] - x[None, :]), 1e4, 1e5)


def test_the_cost_matrix_is_apexnavs() -> None:
    matrix = cost_matrix(np.array([2.0, np.inf]), np.array([[0.0, 3.0], [9.0, 0.0]]), 1e4, 1e5)
    assert matrix.tolist() == [[1e5, 2.0, 1e4], [0.0, 1e5, 3.0], [0.0, 3.0, 1e5]]  # no return, symmetric, failed


def test_the_tour_on_a_hand_solved_case() -> None:
    """Frontiers at -2, 1.5, 3, 4.5, 6 m: the nearest first (1.5) costs 1.5 x 3 + 1.5 + 8 = 14 m; the far one
    first (-2) costs 2 + 3.5 + 1.5 x 3 = 10 m, the best open tour, as no return is paid."""
    assert open_tour(line_matrix([1.5, -2.0, 3.0, 4.5, 6.0]), 100.0, 50) == [2, 1, 3, 4, 5]
    assert open_tour(line_matrix([2.0, -1.0, 5.0, 3.0]), 100.0, 50) == [2, 1, 4, 3]  # 1 + 3 + 1 + 2 = 7 m
    assert open_tour(line_matrix([3.0, -1.0]), 100.0, 50) == [2, 1]  # two: the nearer first, no solver
    assert open_tour(line_matrix([3.0]), 100.0, 50) == [1]


def test_the_tour_is_the_enumerated_optimum_on_a_random_case() -> None:
    points = np.random.default_rng(4).random((6, 2)) * 10.0
    between = np.hypot(*(points[:, None] - points[None, :]).transpose(2, 0, 1))
    matrix = cost_matrix(np.hypot(*points.T), between, 1e4, 1e5)

    def length(order: Sequence[int]) -> float:
        return float(matrix[0, order[0]] + sum(matrix[a, b] for a, b in itertools.pairwise(order)))

    best = min(itertools.permutations(range(1, 7)), key=length)
    tour = open_tour(matrix, 100.0, 50)
    assert length(tour) == pytest.approx(length(best), abs=0.01) and sorted(tour) == [1, 2, 3, 4, 5, 6]
    assert [open_tour(matrix, 100.0, 50) for _ in range(3)] == [tour] * 3


@pytest.mark.parametrize(
    "choice",
    [["--agent", "apexnav"], ["--agent", "drive-nav", "--set", "explorer.name=apexnav"]],
    ids=["agent", "set"],
)
def test_without_ortools_apexnav_is_one_line_naming_the_extra(choice: list[str], tmp_path: Path) -> None:
    """However ApexNav is chosen, the line names the setting that chose it (explorer.name), not an option that was
    perhaps not given."""
    args = ["eval", *choice, "--episodes", "1", "--out", str(tmp_path / "run")]
    code = f"import sys; sys.modules['ortools'] = None\nfrom drivenav.cli import main\nsys.exit(main({args!r}))"
    result = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, timeout=300, check=False)
    lines = [line for line in result.stderr.splitlines() if line.strip()]
    assert result.returncode == 2 and len(lines) == 1, result.stderr
    assert "pip install 'drivenav[apexnav]'" in lines[0] and "ortools not installed" in lines[0]
    assert "explorer.name" in lines[0] and "--agent" not in lines[0]


# ----------------------------------------------------------------------------------------------- fusion


def block(row: int, col: int, size: int = 2) -> np.ndarray:
    """The lattice keys of a ``size`` x ``size`` block of map cells from ``(row, col)``."""
    points = np.array([cell_centre(row + i, col + j) for i in range(size) for j in range(size)])
    return cell_keys(points, RES)


def test_fusion_on_a_hand_computed_sequence_with_negative_evidence() -> None:
    fusion = ObjectFusion(FusionConfig(), labels=2, resolution=RES)
    cells = block(40, 40)  # 0.1 m x 0.1 m: one evidence voxel
    fusion.begin_frame()
    first = fusion.detect(cells, 10, 0, 0.8, step=1)
    assert (first.target.confidence, first.target.points, first.target.detections) == (0.8, 10, 1)
    assert fusion.accepted(0.45) == []  # one detection is not enough
    fusion.begin_frame()
    same = fusion.detect(block(41, 41), 30, 0, 0.4, step=2)  # overlapping cells: the same object
    assert same is first and first.target.confidence == pytest.approx((10 * 0.8 + 30 * 0.4) / 40)  # 0.5
    fusion.detect(cells, 20, 1, 0.6, step=2)  # a confusable object's label on it
    assert first.slots[1].confidence == 0.6 and first.leading_label() == 0  # int(40 * 0.5) = 20 > int(20 * 0.6)
    assert fusion.accepted(0.45) == [first] and fusion.accepted(0.55) == []

    fusion.begin_frame()  # in view and not detected: each label it was seen as gets m points of evidence
    seen = fusion.seen_cells(np.array([cell_centre(41, 41)]))
    fusion.evidence(seen, frame_score=0.2)
    # The object's cells (rows and columns 40-42 at 5 cm) lie in four 0.1 m voxels; the depth point's voxel and its
    # four neighbours (0.1 m away, within 0.11 m; the diagonal one is 0.14 m away) hold three of them.
    m = 3
    assert len(first.voxels) == 4
    assert first.target.confidence == pytest.approx((40 * 0.5 + m * 0.2) / (40 + m))
    assert first.slots[1].confidence == pytest.approx((20 * 0.6) / (20 + m))
    assert first.target.detections == 2 and first.target.points == 40 + m
    fusion.begin_frame()
    fusion.evidence(seen, frame_score=-0.3)  # a negative cosine counts 0
    assert first.target.confidence == pytest.approx((40 * 0.5 + m * 0.2) / (40 + 2 * m))
    assert (fusion.accepted(0.45) == [first]) == (first.target.confidence >= 0.45)


def test_fusion_keeps_objects_apart_and_ranks_them() -> None:
    fusion = ObjectFusion(FusionConfig(), labels=2, resolution=RES)
    a, _ = (fusion.detect(block(10, 10), 10, 0, 0.7, step) for step in (1, 2))
    b, _ = (fusion.detect(block(10, 14), 10, 0, 0.9, step) for step in (1, 2))  # 0.1 m apart: > 0.08 m
    c = fusion.detect(block(30, 30), 50, 1, 0.9, 1)
    fusion.detect(block(30, 30), 10, 0, 0.9, 2)
    fusion.detect(block(30, 30), 10, 0, 0.9, 3)
    assert a is not b and len(fusion.objects) == 3
    assert c.leading_label() == 1  # int(50 * 0.9) = 45 beats the target's int(20 * 0.9) = 18
    assert fusion.accepted(0.45) == [b, a]  # highest target confidence first; c looks more like the other object
    fusion.begin_frame()
    fusion.detect(block(10, 10), 10, 0, 0.7, 4)
    fusion.evidence(fusion.seen_cells(np.array([cell_centre(10, 10), cell_centre(10, 14)])), 0.0)
    assert a.target.points == 30 and b.target.points > 20  # joined this frame: no negative evidence for a


# ----------------------------------------------------------------------------------------------- value map


def test_the_value_map_is_written_onto_the_cells_the_rays_saw_free() -> None:
    grid = GridSpec(RES, (-5.0, -5.0), (200, 200))
    intrinsics = CameraIntrinsics.from_hfov(64, 48, 79.0)
    rays = Rays(Pose(0.0, 0.0, 0.0), np.linspace(-0.6, 0.6, 61), np.full(61, 2.0))
    rays.ranges[:30] = 1.0  # the right half of the fan stops at 1 m
    value_map = ValueMap(grid, 5.0, ValueMapConfig(min_confidence=0.0, decision_threshold=0.0))
    value_map.update_rays(0.8, rays, intrinsics)
    assert value_map.value[grid.cell_at(1.5, 0.3)] == 0.8  # left of the axis, within 2 m
    assert value_map.confidence[grid.cell_at(1.5, -0.3)] == 0.0  # right of it, beyond its 1 m
    assert value_map.value[grid.cell_at(2.5, 0.0)] == 0.0  # beyond every ray
    before = value_map.value.copy()
    value_map.update_rays(0.1, rays, intrinsics)  # same cells, same confidences: the mean of the two
    assert value_map.value[grid.cell_at(1.5, 0.3)] == pytest.approx(0.45)
    assert np.isfinite(value_map.value).all() and (value_map.value[before == 0.0] <= 0.1).all()


def test_the_embedded_scorer_reads_the_room_of_apexnavs_prompt() -> None:
    labels = np.zeros((48, 64), np.int32)
    labels[10:40, 10:50] = 7
    truth = GroundTruth({7: "bathtub"})
    scorer = EmbeddedScorer()
    scorer.begin_episode(truth)
    observation = observation_of(np.zeros((48, 64, 3), np.uint8), labels)
    alone = scorer.score("toilet", observation)
    with_room = scorer.score(
        "toilet", observation, ScorePrompt("Seems like there is a {room} or a {target} ahead?", "bathroom")
    )
    assert with_room > alone  # a bathtub is nearer "bathroom" than "toilet"
    assert (
        scorer.score("toilet", observation, ScorePrompt("Seems like there is a {target} ahead?", "bathroom")) == alone
    )


# ----------------------------------------------------------------------------------------------- the category question


class TableEmbedder:
    """Cosines from a table (1 for a text with itself, 0 for pairs not listed)."""

    def __init__(self, table: dict[tuple[str, str], float]) -> None:
        self.table = {frozenset(pair): value for pair, value in table.items()}

    def similarity(self, a: str, b: str) -> float:
        return 1.0 if a == b else self.table.get(frozenset((a, b)), 0.0)


class Vocabulary:
    room_types = ("kitchen", "bathroom")

    def canonical(self, name: str) -> str | None:
        return {"couch": "sofa"}.get(name, name if name in self.categories() else None)

    def synonyms(self, category: str) -> tuple[str, ...]:
        return ("couch",) if category == "sofa" else ()

    def categories(self) -> list[str]:
        return ["sofa", "armchair", "bed", "chair", "sink", "toilet"]


def test_the_embedded_reasoner_answers_from_the_vocabularys_embeddings() -> None:
    cosines = {("sofa", "armchair"): 0.65, ("sofa", "chair"): 0.6, ("sofa", "bed"): 0.5, ("sofa", "sink"): 0.2}
    cosines |= {("sofa", "toilet"): 0.1, ("sofa", "kitchen"): 0.3, ("sofa", "bathroom"): 0.2}
    cosines |= {("toilet", "bathroom"): 0.79, ("toilet", "sink"): 0.52}
    reasoner = EmbeddedReasoner(TableEmbedder(cosines))  # type: ignore[arg-type]
    reasoner.begin_episode("couch", GroundTruth({}, Vocabulary()))
    hints = reasoner.category_hints("couch")  # a synonym: the category's neighbours, its own left out
    assert hints == CategoryHints(
        ("armchair", "chair", "bed", "sink"), round(0.25 + 0.4 * (0.65 - 0.3) / 0.7, 2), "everywhere"
    )
    assert hints.threshold == 0.45 and [c.kind for c in reasoner.calls] == ["category_hints"]
    toilet = reasoner.category_hints("toilet")
    assert toilet.room == "bathroom" and toilet.similar[0] == "sink"  # 0.79 >= 0.5
    reasoner.begin_episode("couch", None)
    assert reasoner.category_hints("couch") == CategoryHints.unknown()  # no vocabulary, no knowledge


def test_every_reasoner_answers_the_category_question(tmp_path: Path) -> None:
    assert GeometricReasoner().category_hints("bed") == CategoryHints((), 0.45, "everywhere")
    url, stop = start_fake_server("ok", lifetime=30.0)
    try:
        path = tmp_path / "calls.jsonl"
        recorder = RecordingReasoner(OpenAIReasoner(url, "fake-vlm"), path)
        hints = recorder.category_hints("chair")
        assert hints == CategoryHints(tuple(n for n in FAKE_SIMILAR if n != "chair"), 0.45, "everywhere")
        assert [c.kind for c in recorder.calls] == ["category_hints"] and recorder.calls[0].outcome == "ok"
        garbage_url, stop_garbage = start_fake_server("garbage", lifetime=30.0)
        assert OpenAIReasoner(garbage_url, "fake-vlm", retries=0).category_hints("chair") == CategoryHints.unknown(
            fallback=True
        )
        stop_garbage()
    finally:
        stop()
    replay = ReplayReasoner(path)
    assert replay.category_hints("chair") == hints and replay.calls[0].outcome == "replayed"


@pytest.mark.parametrize(
    ("answer", "problem"),
    [
        ('{"similar_objects": "chair", "threshold": 0.5, "room": "kitchen"}', "list of object names"),
        ('{"similar_objects": ["a", "b", "c", "d", "e", "f"], "threshold": 0.5, "room": "kitchen"}', "at most 5"),
        ('{"similar_objects": ["a"], "threshold": 0.9, "room": "kitchen"}', "between 0.25 and 0.65"),
        ('{"similar_objects": ["a"], "threshold": true, "room": "kitchen"}', "between 0.25 and 0.65"),
        ('{"similar_objects": ["a"], "threshold": 0.5, "room": ""}', "at most 4 words"),
    ],
)
def test_a_malformed_category_answer_says_what_is_wrong(answer: str, problem: str) -> None:
    with pytest.raises(AnswerError, match=problem):
        parse_hints(answer, "bed")


def test_a_category_answer_is_cleaned() -> None:
    names = '["Couch", "bed", "couch", "Bench", "chair"]'
    answer = f'Sure. {{"similar_objects": {names}, "threshold": 0.6, "room": "Living  room"}}'
    assert parse_hints(answer, "BED") == CategoryHints(("couch", "bench", "chair"), 0.6, "living room")


def test_fusion_with_verification_is_refused() -> None:
    with pytest.raises(InputError, match=r"agent\.verify.*agent\.fusion\.enabled"):
        load_settings("apexnav", overrides=["agent.verify=true"])


# ----------------------------------------------------------------------------------------------- episodes


def run_apexnav(agent_settings_overrides: Sequence[str] = ()) -> tuple[object, list[int], object]:
    scene = t_junction(target_on_left=True)
    agent = make_agent(load_settings("apexnav", overrides=list(agent_settings_overrides)))
    episode = episode_for(scene, (12.0, 2.5), math.pi / 2, "plant")
    record, trace = run_episode(EmbeddedEnv(lambda _: scene, SIM), agent, episode, 0, 300)
    return record, list(trace.actions), agent


def test_the_same_episode_gives_the_same_actions_twice() -> None:
    first, first_actions, _ = run_apexnav()
    _, second_actions, _ = run_apexnav()
    assert first_actions == second_actions
    assert first.success == 1 and first.explorer is not None  # type: ignore[attr-defined]
    counters = first.explorer.counters  # type: ignore[attr-defined]
    assert {"decisions", "tsp_solves", "dormant_frontiers", "settled", "goals_skipped"} <= set(counters)
    assert first.stats.vlm_calls_by_kind == {"category_hints": 1, "score": first.steps}  # type: ignore[attr-defined]
    assert first.body.targets_accepted >= 1  # type: ignore[attr-defined]


def test_a_category_is_asked_once_per_agent() -> None:
    scene = t_junction(target_on_left=True)
    agent = make_agent(load_settings("apexnav", overrides=["sim.max_steps=30"]))
    made = []
    build = agent._reasoner_factory  # type: ignore[attr-defined]
    agent._reasoner_factory = lambda: made.append(build()) or made[-1]  # type: ignore[attr-defined]
    env = EmbeddedEnv(lambda _: scene, SIM)
    episode = episode_for(scene, (12.0, 2.5), math.pi / 2, "plant")
    records = [run_episode(env, agent, episode, 0, 30)[0] for _ in range(2)]
    assert [[c.outcome for c in r.calls if c.kind == "category_hints"] for r in made] == [["ok"], ["cached"]]
    assert [r.stats.vlm_calls_by_kind["category_hints"] for r in records] == [1, 1]


def test_fusion_is_a_body_switch_of_any_method() -> None:
    scene = t_junction(target_on_left=True)
    settings = load_settings("nearest-frontier", overrides=["agent.fusion.enabled=true"])
    agent = make_agent(settings)
    episode = episode_for(scene, (12.0, 2.5), math.pi / 2, "plant")
    record, _ = run_episode(EmbeddedEnv(lambda _: scene, SIM), agent, episode, 0, 300)
    assert record.success == 1 and record.stats.vlm_calls_by_kind.get("category_hints") == 1
    assert record.explorer is not None and record.explorer.name == "greedy"
