"""Integration: frames of the embedded renderer mapped by the occupancy mapper agree with the scene."""

from __future__ import annotations

import math

import numpy as np
from scipy import ndimage

from drivenav.envs.embedded.render import Renderer
from drivenav.envs.embedded.scene import Material, ObjectInstance, Scene
from drivenav.grid import GridSpec
from drivenav.mapping.config import MappingConfig
from drivenav.mapping.occupancy import OccupancyMapper
from drivenav.types import Pose, SimConfig

SIM = SimConfig(width=320, height=240)


def test_scanned_rendered_room_matches_the_scene() -> None:
    rows, cols = 120, 160  # 8 m x 6 m, one-cell walls
    structure = np.zeros((rows, cols), np.uint8)
    structure[[0, -1], :] = structure[:, [0, -1]] = Material.WALL
    table = ObjectInstance(1, "table", (5.5, 2.0), (1.2, 0.8, 0.75))
    scene = Scene("room", GridSpec(0.05, (0.0, 0.0), (rows, cols)), structure, [table])
    renderer = Renderer(scene, SIM)
    mapper = OccupancyMapper(MappingConfig.from_sim(SIM))
    for spot in [(2.5, 3.0), (5.5, 4.0)]:
        for k in range(12):
            pose = Pose(*spot, k * math.pi / 6.0)
            _, depth, _ = renderer.render(pose)
            mapper.update(depth, SIM.intrinsics, pose)
    snap = mapper.snapshot()
    # Both grids have 5 cm cells; the mapper's (grown) grid is the scene's shifted by whole cells.
    offset = np.round(-np.array(snap.grid.origin)[::-1] / 0.05).astype(int)
    window = (slice(offset[0], offset[0] + rows), slice(offset[1], offset[1] + cols))
    truth_obstacle = scene.obstacle_grid(SIM.agent_height)
    near_truth = ndimage.binary_dilation(truth_obstacle, np.ones((3, 3), bool))
    mapped = snap.obstacle[window]
    assert snap.obstacle.sum() == mapped.sum()  # nothing mapped outside the room
    assert (mapped <= near_truth).all()  # every obstacle cell within a cell of a true one
    truth_nav = scene.navigable_grid(SIM.agent_radius, SIM.agent_height)
    nav = snap.navigable[window]
    assert (nav & ~truth_nav).sum() <= 0.01 * nav.sum()
    assert (nav & truth_nav).sum() >= 0.9 * truth_nav.sum()
    assert mapper.frontiers() == []
