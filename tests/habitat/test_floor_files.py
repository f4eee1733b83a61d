"""Episodes on several floors as habitat-lab's dataset readers take them: HM3D v1's multi-floor episodes (the
fixture of ``tests/test_floor_stats.py``) through habitat-lab's own ``ObjectNav-v1`` reader, and drivenav's episodes
in homes of several storeys exported in both layouts, with their heights and floor information."""

from __future__ import annotations

from pathlib import Path
from typing import Any

import habitat
import pytest
from worlds import SIM_OVERRIDE, export

from drivenav.benchmarks.generate import Storeys, generate_episodes
from drivenav.envs.embedded.library import SceneLibrary
from drivenav.envs.habitat.config import habitat_config
from drivenav.envs.habitat.spec import HabitatSpec
from drivenav.episode import Episode
from drivenav.types import SimConfig
from test_floor_stats import write_hm3d_floors

FLOOR_KEYS = ("start_floor", "goal_floors", "cross_floor")


def habitat_episodes(spec: HabitatSpec) -> list[Any]:
    """The split's episodes as the run's habitat-lab dataset reads them (``habitat.Env`` is given this dataset)."""
    config = habitat_config(spec, SimConfig())
    return list(habitat.make_dataset(config.habitat.dataset.type, config=config.habitat.dataset).episodes)


def view_point_heights(episode: Any) -> list[float]:
    return [float(view.agent_state.position[1]) for goal in episode.goals for view in goal.view_points]


def test_hm3d_v1_floors_through_habitat_labs_reader(tmp_path: Path) -> None:
    """Starts at 0.16 m and 2.9 m, goals on the other floor: habitat-lab reads them as drivenav does."""
    write_hm3d_floors(tmp_path)
    spec = HabitatSpec("hm3d-v1", "val", str(tmp_path), (SIM_OVERRIDE,))
    found = habitat_episodes(spec)
    assert [float(e.start_position[1]) for e in found] == [0.16, 2.9, 2.9, 0.16]
    assert [sorted(set(view_point_heights(e))) for e in found] == [[2.9], [2.9], [0.16], [0.16, 2.9]]
    for theirs, ours in zip(found, spec.episodes(), strict=True):
        assert list(theirs.start_position) == list(ours.start_position)
        assert view_point_heights(theirs) == [vp.height for g in ours.goals for vp in g.view_points]
        assert theirs.info == ours.info and not set(FLOOR_KEYS) & set(theirs.info)


@pytest.fixture(scope="module")
def storeyed() -> list[Episode]:
    return generate_episodes(SceneLibrary("storeys:3", 0), 12, 5, storeys=Storeys(0.5))


@pytest.mark.parametrize("benchmark", ["hm3d-v1", "hm3d-ovon"])
def test_storeyed_exports_keep_heights_and_floor_info(storeyed: list[Episode], benchmark: str, tmp_path: Path) -> None:
    """Each layout's reader (habitat-lab's ObjectNav-v1, drivenav's HM3D-OVON) gives every start and view point
    height to habitat-lab's 5 decimals, and ``info``'s floor keys as generated."""
    found = habitat_episodes(export(storeyed, tmp_path, benchmark))
    by_start = {tuple(round(v, 5) for v in e.start_position): e for e in storeyed}
    assert len(found) == len(by_start) == len(storeyed)
    for theirs in found:
        ours = by_start[tuple(float(v) for v in theirs.start_position)]
        heights = [round(vp.height, 5) for g in ours.goals for vp in g.view_points]
        assert view_point_heights(theirs) == heights
        assert {k: theirs.info.get(k) for k in FLOOR_KEYS} == {k: ours.info.get(k) for k in FLOOR_KEYS}
    assert {e.info.get("cross_floor") for e in found} == {True, False, None}
