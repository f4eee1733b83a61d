"""Benchmark v3 and the multi-storey homes it stands on: frozen bytes, HM3D v1's mix of floors, episodes that still
fit today's homes, and homes whose every storey is reachable by stairs of real size."""

from __future__ import annotations

import hashlib
import math
from collections import Counter
from dataclasses import replace
from pathlib import Path

import numpy as np
import pytest

from drivenav.benchmarks.benchmark import BENCHMARK_V3, BENCHMARKS, generate_benchmark
from drivenav.benchmarks.generate import Storeys, generate_episodes
from drivenav.benchmarks.ovon_episodes import SPLITS
from drivenav.cli import main
from drivenav.envs.embedded.building import Building
from drivenav.envs.embedded.goals import scene_goals
from drivenav.envs.embedded.levels import MAX_STEP
from drivenav.envs.embedded.library import SceneLibrary
from drivenav.envs.embedded.storeys import generate_storeyed_home
from drivenav.envs.embedded.terrain import LevelTerrain, terrain_of
from drivenav.eval.episodes import load_episodes, validate_for_scenes
from drivenav.types import SimConfig

V3_SHA256 = "0d17d48d02087ee40244cdfbaa29c54aaa98b13bdc28077bbf19703e436dccc3"  # docs/benchmarks.md
SIM = SimConfig()


@pytest.fixture(scope="module")
def v3(tmp_path_factory: pytest.TempPathFactory) -> Path:
    out = tmp_path_factory.mktemp("v3") / "v3.json.gz"
    assert main(["benchmark", "generate", "--version", "v3", "--out", str(out)]) == 0
    return out


def test_benchmark_v3_is_frozen_with_hm3d_v1s_mix_of_floors(v3: Path) -> None:
    assert BENCHMARKS["v3"] is BENCHMARK_V3
    assert hashlib.sha256(v3.read_bytes()).hexdigest() == V3_SHA256
    episodes = load_episodes(v3)
    assert [e.episode_id for e in episodes] == [str(i) for i in range(300)]
    assert Counter(e.info["split"] for e in episodes) == dict.fromkeys(SPLITS, 100)
    assert len({e.scene_id for e in episodes}) == 50
    several = [e for e in episodes if "cross_floor" in e.info]
    cross = [e for e in several if e.info["cross_floor"]]
    assert 0.55 <= len(several) / 300 <= 0.65  # HM3D val: 65 % in multi-storey buildings (ASCENT)
    assert 0.20 <= len(cross) / 300 <= 0.25  # HM3D v1 val: 20.6 %
    for e in several:
        assert e.info["cross_floor"] == (e.info["start_floor"] not in e.info["goal_floors"])


def test_benchmark_v3_episodes_fit_todays_homes(v3: Path) -> None:
    """The frozen episodes still fit the generated homes (starts and view points on their floors, distances within
    10 %), and generating the definition again gives the same episodes (a prefix)."""
    frozen = load_episodes(v3)
    library = SceneLibrary(BENCHMARK_V3.scenes, BENCHMARK_V3.seed)
    validate_for_scenes(frozen[:24], library, v3, SIM)
    assert generate_benchmark(replace(BENCHMARK_V3, frozen=None), 9) == frozen[:9]


def test_an_episode_that_needs_a_floor_change_starts_on_a_floor_without_its_target(v3: Path) -> None:
    episodes = load_episodes(v3)
    library = SceneLibrary(BENCHMARK_V3.scenes, BENCHMARK_V3.seed)
    episode = next(e for e in episodes if e.info.get("cross_floor"))
    building = library.load(episode.scene_id)
    assert isinstance(building, Building)
    start = building.storey_at(episode.start_height)
    assert episode.start_height == building.storeys[start].elevation
    goal_floors = {building.storey_of(goal.object_id) for goal in episode.goals}
    assert start not in goal_floors and sorted(goal_floors) == episode.info["goal_floors"]
    assert all(vp.height != episode.start_height for goal in episode.goals for vp in goal.view_points)


@pytest.mark.parametrize("seed", [0, 4, 9, 13, 144])
def test_a_generated_home_has_reachable_storeys_and_stairs_of_real_size(seed: int) -> None:
    """Every storey on one grid, 2.8-3.2 m apart; risers of 15-20 cm under habitat's 0.2 m climb, slopes under
    45 degrees; every navigable cell of every storey reachable from the others; no object on the stairs, over a
    stairwell or at either end of the stairs."""
    building = generate_storeyed_home(seed)
    gaps = np.diff(building.elevations)
    assert np.all((gaps >= 2.8) & (gaps <= 3.2))
    assert len(building.stairs) == len(building.storeys) - 1
    for stair in building.stairs:
        assert stair.flights[-1].top == pytest.approx(building.storeys[stair.lower + 1].elevation)
        for flight in stair.flights:
            assert 0.15 <= flight.riser <= MAX_STEP
            assert math.degrees(math.atan(flight.slope)) < 45.0
    terrain = terrain_of(building, SIM)
    assert isinstance(terrain, LevelTerrain)
    assert np.array_equal(terrain.reachable, terrain.levels.navigable)
    for j, storey in enumerate(building.storeys):
        keep_out = building.stair_cells[j] | building.holes[j]
        for obj in storey.plan.objects:
            row, col = building.grid.cell_at(*obj.center)
            assert not keep_out[row, col], (j, obj)


def test_cross_floor_episodes_on_request() -> None:
    """``Storeys(cross_floor=1)`` makes every episode drafted in a home of several storeys need a floor change;
    ``0`` none; a one-floor scene set gives the episodes it always gave."""
    library = SceneLibrary("storeys:6", 7)
    several = {i for i in library.scene_ids if len(generate_storeyed_home(int(i.split("_")[-1])).storeys) > 1}
    assert several
    for share, expected in ((1.0, True), (0.0, False)):
        episodes = generate_episodes(library, 12, 7, SIM, Storeys(share))
        assert all(e.info["cross_floor"] is expected for e in episodes if e.scene_id in several)
    homes = SceneLibrary("homes:3", 7)
    assert generate_episodes(homes, 6, 7, SIM, Storeys(1.0)) == generate_episodes(homes, 6, 7, SIM)


def test_view_points_of_a_generated_home_lie_on_their_objects_floors() -> None:
    building = generate_storeyed_home(4)
    goals = scene_goals(building, SIM)
    for category, instances in goals.goals.items():
        for goal in instances:
            elevation = building.storeys[building.storey_of(goal.object_id)].elevation
            assert {vp.height for vp in goal.view_points} == {elevation}, category
