"""Mapping and directions together on frames rendered by the embedded world (paper Sec. IV-A a-b)."""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np

from drivenav.benchmarks.generate import generate_episodes
from drivenav.directions import DirectionPipeline
from drivenav.envs.embedded.env import EmbeddedEnv
from drivenav.envs.embedded.library import SceneLibrary
from drivenav.mapping.config import MappingConfig
from drivenav.mapping.occupancy import OccupancyMapper
from drivenav.paper import DriveNavConfig
from drivenav.types import Action, SimConfig
from drivenav.viz.directions import draw_directions


def test_start_scan_in_a_house_gives_labelled_directions(tmp_path: Path) -> None:
    sim = SimConfig()
    library = SceneLibrary("procedural:1", 2)
    [episode] = generate_episodes(library, 1, seed=2)
    env = EmbeddedEnv(library.load, sim)
    mapper = OccupancyMapper(MappingConfig.from_sim(sim))
    pipeline = DirectionPipeline(DriveNavConfig())
    observation = env.reset(episode)
    labels_seen: list[set[int]] = []
    for _ in range(12):  # the 360 deg start scan: twelve 30 deg turns
        mapper.update(observation.depth, observation.intrinsics, observation.pose)
        snapshot = mapper.snapshot()
        frontiers = mapper.frontiers()
        result = pipeline.update(snapshot, frontiers, (observation.pose.x, observation.pose.y))
        labels_seen.append({d.label for d in result.directions})
        observation = env.step(Action.TURN_LEFT)
    assert result.directions, "a scan inside a house must reveal at least one direction"
    for direction in result.directions:
        assert 0.0 <= direction.bearing < 2.0 * math.pi
    # Every backtracked path stays on cells the map knows to be free.
    for path in result.paths.values():
        cells = snapshot.grid.world_to_cell(np.asarray(path.path).reshape(-1, 2))
        assert not snapshot.obstacle[cells[:, 0], cells[:, 1]].any()
    # Labels persist: the last scan step keeps labels from earlier steps rather than renaming everything.
    assert labels_seen[-1] & set().union(*labels_seen[:-1])
    picture = tmp_path / "directions.png"
    draw_directions(snapshot, frontiers, result, (observation.pose.x, observation.pose.y), picture)
    assert picture.stat().st_size > 1000
