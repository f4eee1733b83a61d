"""Simulator benchmark (``drivenav bench sim``) and the hand-built demo house it falls back to."""

from __future__ import annotations

import importlib
import statistics
import time

import numpy as np
from numpy.typing import NDArray

from drivenav.envs.embedded.building import Building, storeys_of
from drivenav.envs.embedded.render import Renderer
from drivenav.envs.embedded.scene import Material, ObjectInstance, Room, Scene
from drivenav.envs.embedded.terrain import terrain_of
from drivenav.grid import GridSpec
from drivenav.types import Pose, SimConfig

Box = tuple[float, float, float, float]

_RES = 0.05
_ORIGIN = (-0.5, -0.5)
_WALL = 0.1  # wall thickness, metres

# Rooms of the demo house: name, (xmin, ymin, xmax, ymax).
_ROOMS = (
    ("living room", (0.0, 0.0, 7.0, 5.0)),
    ("kitchen", (7.0, 0.0, 12.0, 5.0)),
    ("bedroom", (0.0, 5.0, 6.0, 9.0)),
    ("bathroom", (6.0, 5.0, 9.0, 9.0)),
    ("hallway", (9.0, 5.0, 12.0, 9.0)),
)
# Interior walls (x0, y0, x1, y1) and door openings (x0, y0, x1, y1) cut through them.
_INNER_WALLS = ((0.0, 5.0, 12.0, 5.1), (7.0, 0.0, 7.1, 5.0), (6.0, 5.0, 6.1, 9.0), (9.0, 5.0, 9.1, 9.0))
_DOORS = ((7.0, 2.0, 7.1, 2.9), (4.0, 5.0, 4.9, 5.1), (10.0, 5.0, 10.9, 5.1), (9.0, 7.0, 9.1, 7.9))
# category, centre, size (sx, sy, sz), yaw, elevation
_OBJECTS: tuple[tuple[str, tuple[float, float], tuple[float, float, float], float, float], ...] = (
    ("sofa", (2.0, 0.6), (2.0, 0.9, 0.8), 0.0, 0.0),
    ("tv", (2.0, 4.85), (1.2, 0.08, 0.7), 0.0, 0.9),
    ("cabinet", (2.0, 4.75), (1.6, 0.45, 0.5), 0.0, 0.0),
    ("table", (2.0, 2.2), (1.0, 0.6, 0.45), 0.0, 0.0),
    ("chair", (4.6, 1.0), (0.6, 0.6, 0.9), 0.5, 0.0),
    ("chair", (5.2, 3.6), (0.7, 0.7, 0.9), -0.4, 0.0),
    ("plant", (6.6, 0.5), (0.4, 0.4, 1.1), 0.0, 0.0),
    ("lamp", (0.4, 0.4), (0.3, 0.3, 1.5), 0.0, 0.0),
    ("bookshelf", (0.3, 3.0), (0.35, 1.2, 1.9), 0.0, 0.0),
    ("picture", (3.6, 0.12), (0.8, 0.04, 0.6), 0.0, 1.3),
    ("counter", (11.6, 1.4), (0.6, 2.2, 0.9), 0.0, 0.0),
    ("sink", (11.6, 1.0), (0.5, 0.6, 0.15), 0.0, 0.9),
    ("cabinet", (11.72, 1.4), (0.35, 2.0, 0.7), 0.0, 1.5),
    ("oven", (11.6, 2.9), (0.6, 0.7, 0.9), 0.0, 0.0),
    ("refrigerator", (11.5, 4.4), (0.7, 0.7, 1.8), 0.0, 0.0),
    ("dining table", (9.0, 2.5), (1.6, 0.9, 0.75), 0.0, 0.0),
    ("chair", (8.5, 1.7), (0.45, 0.45, 0.9), 0.0, 0.0),
    ("chair", (9.5, 1.7), (0.45, 0.45, 0.9), 0.0, 0.0),
    ("chair", (8.5, 3.3), (0.45, 0.45, 0.9), 0.0, 0.0),
    ("chair", (9.5, 3.3), (0.45, 0.45, 0.9), 0.0, 0.0),
    ("clock", (9.0, 4.88), (0.3, 0.04, 0.3), 0.0, 1.8),
    ("bed", (1.2, 7.8), (1.6, 2.0, 0.6), 0.0, 0.0),
    ("nightstand", (2.4, 8.6), (0.45, 0.4, 0.55), 0.0, 0.0),
    ("dresser", (4.5, 8.6), (1.2, 0.45, 0.9), 0.0, 0.0),
    ("mirror", (4.5, 8.88), (0.6, 0.03, 0.8), 0.0, 1.1),
    ("desk", (5.6, 6.5), (0.6, 1.2, 0.75), 0.0, 0.0),
    ("chair", (5.05, 6.5), (0.45, 0.45, 0.9), 0.3, 0.0),
    ("lamp", (0.4, 5.5), (0.3, 0.3, 1.5), 0.0, 0.0),
    ("plant", (3.0, 5.4), (0.4, 0.4, 0.9), 0.0, 0.0),
    ("toilet", (8.6, 8.5), (0.4, 0.65, 0.75), 0.0, 0.0),
    ("sink", (6.5, 8.6), (0.5, 0.45, 0.85), 0.0, 0.0),
    ("bathtub", (8.1, 5.8), (1.5, 0.75, 0.55), 0.0, 0.0),
    ("towel", (6.13, 7.0), (0.04, 0.5, 0.6), 0.0, 1.0),
    ("cabinet", (11.65, 7.0), (0.5, 1.0, 1.0), 0.0, 0.0),
    ("washing machine", (11.5, 8.5), (0.6, 0.6, 0.85), 0.0, 0.0),
    ("picture", (10.5, 8.88), (0.7, 0.03, 0.5), 0.0, 1.4),
)


def _fill(structure: NDArray[np.uint8], grid: GridSpec, box: Box, value: int) -> None:
    """Set the cells whose centres lie in the world rectangle ``(x0, y0, x1, y1)`` (centres never lie on
    multiples of the 5 cm resolution, so boundaries are unambiguous)."""
    x0, y0, x1, y1 = box
    gx, gy = grid.cell_centers()
    structure[(gx >= x0) & (gx <= x1) & (gy >= y0) & (gy <= y1)] = value


def _door(structure: NDArray[np.uint8], grid: GridSpec, box: Box) -> None:
    """Cut a door opening and mark one wall thickness on each side of it as door frame."""
    x0, y0, x1, y1 = box
    vertical = (x1 - x0) < (y1 - y0)  # opening through a wall that runs along y
    if vertical:
        jambs = ((x0, y0 - _WALL, x1, y0), (x0, y1, x1, y1 + _WALL))
    else:
        jambs = ((x0 - _WALL, y0, x0, y1), (x1, y0, x1 + _WALL, y1))
    for jamb in jambs:
        _fill(structure, grid, jamb, Material.DOOR_FRAME)
    _fill(structure, grid, box, Material.FREE)


def demo_house() -> Scene:
    """A 12 m x 9 m five-room house (living room, kitchen, bedroom, bathroom, hallway) with 36 objects."""
    grid = GridSpec(_RES, _ORIGIN, (200, 260))
    structure = np.full(grid.shape, Material.UNKNOWN, np.uint8)
    _fill(structure, grid, (0.0, 0.0, 12.0, 9.0), Material.WALL)
    _fill(structure, grid, (_WALL, _WALL, 12.0 - _WALL, 9.0 - _WALL), Material.FREE)
    for wall in _INNER_WALLS:
        _fill(structure, grid, wall, Material.WALL)
    for door in _DOORS:
        _door(structure, grid, door)
    rooms = [Room(name, ((x0, y0), (x1, y0), (x1, y1), (x0, y1))) for name, (x0, y0, x1, y1) in _ROOMS]
    objects = [
        ObjectInstance(i + 1, cat, centre, size, yaw, elev) for i, (cat, centre, size, yaw, elev) in enumerate(_OBJECTS)
    ]
    return Scene("demo_house", grid, structure, objects, rooms, source="drivenav.envs.embedded.bench.demo_house")


def bench_scene() -> Scene:
    """The procedural house of seed 0 when the generator is available and works, else :func:`demo_house`."""
    try:
        scene = importlib.import_module("drivenav.envs.embedded.procedural").generate_house(seed=0)
    except Exception:  # the generator is optional here: any failure falls back to the demo house
        return demo_house()
    return scene if isinstance(scene, Scene) else demo_house()


def sample_poses(scene: Scene | Building, config: SimConfig, count: int, seed: int = 0) -> list[Pose]:
    """``count`` random navigable world poses of ``scene`` (uniform cell, uniform yaw; in a building, over every
    floor and stair, at the surface's height)."""
    rng = np.random.default_rng(seed)
    if isinstance(scene, Building):
        terrain = terrain_of(scene, config)
        layered = np.argwhere(terrain.reachable)
        cells, heights = layered[:, 1:], terrain.heights[layered[:, 0], layered[:, 1], layered[:, 2]]
    else:
        cells = np.argwhere(scene.navigable_grid(config.agent_radius, config.agent_height))
        heights = np.zeros(len(cells))
    if len(cells) == 0:
        raise ValueError(f"scene {scene.scene_id} has no navigable cell")
    picked = rng.integers(0, len(cells), count)
    xy = scene.grid.cell_to_world(cells[picked])
    yaws = rng.uniform(-np.pi, np.pi, count)
    return [
        Pose(float(x), float(y), float(yaw), float(z)) for (x, y), yaw, z in zip(xy, yaws, heights[picked], strict=True)
    ]


def bench_sim(
    frames: int = 300, scene: Scene | Building | None = None, config: SimConfig | None = None
) -> dict[str, object]:
    """Rendering throughput (RGB + depth + semantic per frame) on one thread, JIT compile time excluded."""
    config = config or SimConfig()
    scene = scene or bench_scene()
    renderer = Renderer(scene, config)
    poses = sample_poses(scene, config, frames)
    for pose in poses[:3]:  # compile (or load from cache) and warm up
        renderer.render(pose)
    times = []
    for pose in poses:
        start = time.perf_counter()
        renderer.render(pose)
        times.append(time.perf_counter() - start)
    total = sum(times)
    storeys = storeys_of(scene)
    return {
        "width": config.width,
        "height": config.height,
        "fps": frames / total,
        "ms_per_frame": 1000.0 * statistics.median(times),
        "ms_per_frame_mean": 1000.0 * total / frames,
        "frames": frames,
        "scene_id": scene.scene_id,
        "objects": sum(len(storey.plan.objects) for storey in storeys),
        "storeys": len(storeys),
        "threads": 1,
    }
