"""The floors' bookkeeping without a world: a floor's album spans the stay on it, and the floors known from heights
(a level within the tolerance, a new one only far from every known one)."""

from __future__ import annotations

from typing import cast

import numpy as np

from drivenav.agent.config import FloorsConfig
from drivenav.agent.explorer import Explorer
from drivenav.agent.floors import Floor, Floors
from drivenav.agent.state import BodyState
from drivenav.types import CameraIntrinsics, Observation, Pose

H, W = 24, 32


def observation(step: int) -> Observation:
    rgb = np.zeros((H, W, 3), np.uint8)
    depth = np.full((H, W), 2.0, np.float32)
    return Observation(rgb, depth, None, Pose(0.0, 0.0, 0.0), CameraIntrinsics.from_hfov(W, H, 79.0), step, False)


def floors(config: FloorsConfig) -> Floors:
    """Floors with one floor at level 0 (no maps: the album and the levels need none)."""
    first = Floor(0.0, cast(BodyState, None), cast(Explorer, None))
    return Floors(config, first, lambda: (cast(BodyState, None), cast(Explorer, None)), lambda floor: None, 500)


def test_the_album_spans_the_whole_stay_on_a_floor_evenly() -> None:
    config = FloorsConfig(album_every=10, album_size=4)
    f = floors(config)
    for step in range(200):
        f.look(observation(step))
    steps = [view.step for view in f.floor.album]
    assert len(steps) <= config.album_size
    assert steps[0] == 0 and steps[-1] >= 120  # from the start of the stay to its late part
    gaps = np.diff(steps)
    assert (gaps == gaps[0]).all()  # evenly
    assert f.floor.album_every == gaps[0]


def test_a_level_is_known_within_its_tolerance_and_a_new_one_only_far_from_all() -> None:
    f = floors(FloorsConfig(level_tolerance=0.3, new_level=2.0))
    assert f._level_at(0.25) == 0 and f._level_at(0.35) is None
    assert not f._new_level(1.5)  # a half landing is no floor
    assert f._new_level(2.9)
    assert f._add_level(2.9) == 1
    assert f._level_at(3.1) == 1 and not f._new_level(4.0)
