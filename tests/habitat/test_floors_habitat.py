"""Several floors through habitat-lab: multi-storey episodes run by the oracle directly in the embedded world and
through ``habitat.Env`` on ``DriveNavSim-v0`` (the stand-in with floors) give the same actions, the same success, SPL,
distance to goal and path length (in three dimensions, as habitat-lab's ``SPL`` sums it), and the same heights at
every step: ``Observation.pose.z`` (above the start) and ``world_pose().z``. The cross-floor episodes are reached in
both worlds, so the oracle climbed or descended the stairs through the adapter's geodesic and path finder. DRIVE-Nav,
its floors on, runs the storeyed episodes alike in both worlds too, and changes floors through habitat-lab.

Two sets: drivenav's episodes in homes of several storeys (``episodes generate --cross-floor 1``), exported in
ObjectNav v1's layout (as ``episodes export --format objectnav-v1`` writes it) and read by habitat-lab's own
``ObjectNav-v1`` reader under the HM3D v1 and the MP3D presets; and HM3D v1's multi-floor fixture
(``tests/data/hm3d-v1-floors``: starts 0.16 m above the ground floor as HM3D's navmesh has them, goals upstairs and
downstairs). Both run at 320x240 to keep the suite's time (the oracle does not look).
"""

from __future__ import annotations

from pathlib import Path

import pytest
from worlds import BothWorlds, NotedHeights, assert_same, export, settings_for, spec_of

from drivenav.benchmarks.generate import Storeys, generate_episodes
from drivenav.envs.base import Env
from drivenav.envs.embedded.library import SceneLibrary
from drivenav.envs.habitat.spec import HabitatSpec
from drivenav.episode import Episode
from drivenav.eval.episodes import load_episodes, save_episodes
from drivenav.eval.records import EpisodeRecord
from drivenav.eval.trace import EpisodeTrace
from drivenav.types import GEODESIC
from test_floor_stats import write_hm3d_floors

OVERRIDES = ("sim.success_distance=0.25", "sim.width=320", "sim.height=240")
STOREY = 2.4  # metres: the least floor-to-floor height; a height change this large is another floor
FIXTURE_EPISODES = ("0", "2")  # the fixture's floor changes: to the beds upstairs, to the sofa downstairs

Run = tuple[EpisodeRecord, EpisodeTrace, list[tuple[float, float]]]


@pytest.fixture(scope="module")
def data_dir(tmp_path_factory: pytest.TempPathFactory) -> Path:
    """Episodes in homes of several storeys, every one drafted in such a home needing a floor change (``episodes
    generate --scenes storeys:4 --num 4 --seed 1 --cross-floor 1``), read back from drivenav's own file and exported
    in ObjectNav v1's layout where the HM3D v1 and the MP3D presets read their ``val`` split."""
    folder = tmp_path_factory.mktemp("floors")
    path = folder / "episodes.json.gz"
    save_episodes(generate_episodes(SceneLibrary("storeys:4", 1), 4, 1, storeys=Storeys(1.0)), path)
    for benchmark in ("hm3d-v1", "mp3d"):
        export(load_episodes(path), folder / "data", benchmark)
    return folder / "data"


def run_both(spec: HabitatSpec, episodes: tuple[str, ...] = ()) -> list[tuple[Episode, Run, Run]]:
    """Each episode of the split (or those named), run by the oracle directly and through habitat.Env."""
    worlds = BothWorlds(spec, settings_for("oracle", spec.benchmark, *OVERRIDES))
    try:
        chosen = [e for e in spec.episodes() if not episodes or e.episode_id in episodes]
        return [(e, _noted(worlds, worlds.embedded, e), _noted(worlds, worlds.habitat, e)) for e in chosen]
    finally:
        worlds.close()


def _noted(worlds: BothWorlds, world: Env, episode: Episode) -> Run:
    noted = NotedHeights(world)
    record, trace = worlds.run(noted, episode)
    return record, trace, noted.heights


def assert_same_with_heights(episode: Episode, direct: Run, through: Run, where: str) -> None:
    """The same actions and metrics, the same heights at every step; a cross-floor episode reached on another
    floor."""
    assert_same(direct[:2], through[:2], where)
    assert through[2] == direct[2], where
    if episode.info.get("cross_floor"):
        assert direct[0].success == 1, where
        relative, _ = direct[2][-1]
        assert abs(relative) >= STOREY, where


@pytest.mark.parametrize("benchmark", ["hm3d-v1", "mp3d"])
def test_storeyed_episodes_run_alike_through_habitat_lab(data_dir: Path, benchmark: str) -> None:
    runs = run_both(spec_of(data_dir, benchmark))
    assert len(runs) == 4
    assert sum(bool(episode.info.get("cross_floor")) for episode, _, _ in runs) >= 2
    climbs = {episode.start_height == 0.0 for episode, _, _ in runs if episode.info.get("cross_floor")}
    assert climbs == {True, False}  # a climb and a descent
    for episode, direct, through in runs:
        assert_same_with_heights(episode, direct, through, f"{benchmark} episode {episode.episode_id}")


def test_hm3d_v1_multi_floor_episodes_run_alike_through_habitat_lab(tmp_path: Path) -> None:
    """HM3D's downstairs starts stand 0.16 m above the floor both worlds place them on: heights count from where the
    agent stands, 0 at the start in both worlds."""
    write_hm3d_floors(tmp_path)
    runs = run_both(spec_of(tmp_path, "hm3d-v1"), FIXTURE_EPISODES)
    assert [episode.episode_id for episode, _, _ in runs] == list(FIXTURE_EPISODES)
    for episode, direct, through in runs:
        assert_same_with_heights(episode, direct, through, f"HM3D v1 fixture episode {episode.episode_id}")
        (start, placed), (end, _) = direct[2][0], direct[2][-1]
        assert start == 0.0 and placed == pytest.approx(episode.start_height, abs=0.25)
        assert direct[0].success == 1 and abs(end) >= STOREY  # the fixture's goals lie on the other floor


def test_the_goals_heights_are_the_same_ground_truth_in_both_worlds(data_dir: Path) -> None:
    """The oracle reasoner's floor answer reads the heights of the goals' view points from the geodesic ground truth
    (docs/regimes.md): habitat's view points' ``y``, the embedded episode's view point heights."""
    spec = spec_of(data_dir, "hm3d-v1")
    worlds = BothWorlds(spec, settings_for("oracle", spec.benchmark, *OVERRIDES))
    try:
        for episode in spec.episodes():
            expected = tuple(sorted({height for *_, height in episode.view_points_xyz()}))
            for world in (worlds.embedded, worlds.habitat):
                world.reset(episode)
                geodesic = world.ground_truth(frozenset({GEODESIC})).geodesic
                assert geodesic is not None
                assert geodesic.goal_heights == pytest.approx(expected, abs=1e-5), episode.episode_id
            assert len(expected) >= 1
    finally:
        worlds.close()


def test_drive_nav_keeps_its_floors_through_habitat_lab(data_dir: Path) -> None:
    """DRIVE-Nav with the body's floors (on by default) on the same multi-storey episodes under the HM3D v1 preset:
    the same actions, metrics and heights in both worlds, and through habitat-lab too it takes the stairs: a floor
    change in some episode, from the pose's height the adapter carries."""
    spec = spec_of(data_dir, "hm3d-v1")
    settings = settings_for("drive-nav", spec.benchmark, *OVERRIDES, "sim.max_steps=300")
    worlds = BothWorlds(spec, settings)
    climbed = 0
    try:
        for episode in spec.episodes():
            direct, through = _noted(worlds, worlds.embedded, episode), _noted(worlds, worlds.habitat, episode)
            where = f"drive-nav, episode {episode.episode_id}"
            assert_same(direct[:2], through[:2], where)
            assert through[2] == direct[2], where
            climbed += max(abs(relative) for relative, _ in through[2]) >= STOREY
    finally:
        worlds.close()
    assert climbed >= 1
