"""Renderer geometry against hand-computed values (SimConfig pinhole: 640x480, hfov 79 deg, camera 0.88 m)."""

from __future__ import annotations

import math

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from drivenav.envs.embedded import palette
from drivenav.envs.embedded.bench import bench_sim, demo_house
from drivenav.envs.embedded.render import Renderer
from drivenav.envs.embedded.scene import Material, ObjectInstance, Room, Scene
from drivenav.grid import GridSpec
from drivenav.types import Pose, SimConfig

CFG = SimConfig()
INTR = CFG.intrinsics
FY = INTR.fy
CY = INTR.cy
H = CFG.camera_height
RES = 0.05
# Centre pixels: the optical axis passes between columns 319/320 and rows 239/240.
ROW, COL = 240, 320


def room(
    length_m: float = 6.0,
    width_m: float = 4.0,
    objects: tuple[ObjectInstance, ...] = (),
    ceiling: float = 2.6,
) -> Scene:
    """A rectangular room with one-cell walls: free space is x in [0.05, L-0.05], y in [0.05, W-0.05]."""
    rows, cols = round(width_m / RES), round(length_m / RES)
    structure = np.zeros((rows, cols), np.uint8)
    structure[0, :] = structure[-1, :] = Material.WALL
    structure[:, 0] = structure[:, -1] = Material.WALL
    grid = GridSpec(RES, (0.0, 0.0), (rows, cols))
    polygon = ((0.0, 0.0), (length_m, 0.0), (length_m, width_m), (0.0, width_m))
    return Scene("room", grid, structure, list(objects), [Room("kitchen", polygon)], ceiling_height=ceiling)


def render(scene: Scene, pose: Pose) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    return Renderer(scene, CFG).render(pose)


def floor_depth(v: int) -> float:
    return H * FY / (v - CY)


def test_shapes_and_dtypes() -> None:
    rgb, depth, sem = render(room(), Pose(2.0, 2.0, 0.3))
    assert rgb.shape == (480, 640, 3) and rgb.dtype == np.uint8
    assert depth.shape == (480, 640) and depth.dtype == np.float32
    assert sem.shape == (480, 640) and sem.dtype == np.int32


def test_wall_ahead_is_z_depth_not_ray_length() -> None:
    # Far wall's inner face at x = 5.95; agent 2.0 m before it, looking along +x.
    _, depth, _ = render(room(), Pose(3.95, 2.0, 0.0))
    assert depth[ROW, COL] == pytest.approx(2.0, abs=1e-4)
    # Column 0 looks 39.5 deg off axis: its ray is 2.6 m long but its z-depth is still 2.0.
    phi = math.atan((INTR.cx - 0) / INTR.fx)
    assert 2.0 / math.cos(phi) > 2.5
    assert depth[ROW, 0] == pytest.approx(2.0, abs=1e-4)
    assert np.allclose(depth[ROW], 2.0, atol=1e-4)


@settings(max_examples=30, deadline=None)
@given(x=st.floats(1.5, 5.8), y=st.floats(5.5, 6.5))
def test_fronto_parallel_wall_has_constant_depth(x: float, y: float) -> None:
    # The room is wide enough that every column of the horizon row meets the far wall (x = 5.95).
    scene = room(length_m=6.0, width_m=12.0)
    _, depth, _ = render(scene, Pose(x, y, 0.0))
    expected = min(max(5.95 - x, CFG.min_depth), CFG.max_depth)
    assert np.allclose(depth[ROW], expected, atol=1e-3)


def test_floor_rows_match_pinhole_formula() -> None:
    _, depth, sem = render(room(length_m=12.0), Pose(1.0, 2.0, 0.0))
    for v in (320, 350, 400, 479):
        assert depth[v, COL] == pytest.approx(floor_depth(v), rel=1e-5)
    # Rows near the horizon see the floor beyond 5 m: clipped.
    v_far = 260
    assert floor_depth(v_far) > 5.0 and depth[v_far, COL] == pytest.approx(5.0)
    assert (sem == 0).all()


def test_ceiling_depth() -> None:
    _, depth, _ = render(room(length_m=12.0, ceiling=2.6), Pose(1.0, 2.0, 0.0))
    assert depth[0, COL] == pytest.approx((2.6 - H) * FY / (CY - 0), rel=1e-5)


def test_depth_clip_limits() -> None:
    _, near, _ = render(room(), Pose(5.7, 2.0, 0.0))  # wall 0.25 m ahead
    assert near[ROW, COL] == pytest.approx(CFG.min_depth)
    far_rgb, far, _ = render(room(length_m=12.0), Pose(1.0, 2.0, 0.0))  # wall 10.95 m ahead
    assert far[ROW, COL] == pytest.approx(CFG.max_depth)
    assert near.min() >= CFG.min_depth and far.max() <= CFG.max_depth
    assert far_rgb[ROW, COL].max() > 60  # far surfaces are still drawn in RGB, only depth is clipped


def test_object_occludes_wall_in_depth_and_semantics() -> None:
    box = ObjectInstance(7, "chair", (3.2, 2.0), (0.4, 0.4, 1.5))  # front face at x = 3.0
    _, depth, sem = render(room(objects=(box,)), Pose(2.0, 2.0, 0.0))
    assert sem[ROW, COL] == 7
    assert depth[ROW, COL] == pytest.approx(1.0, abs=1e-4)
    assert set(np.unique(sem)) == {0, 7}


def test_short_object_shows_wall_above_and_its_top() -> None:
    # Box 0.5 m tall, footprint x in [3.0, 3.4]; wall at 5.95 (3.95 m ahead).
    box = ObjectInstance(3, "table", (3.2, 2.0), (0.4, 0.4, 0.5))
    _, depth, sem = render(room(objects=(box,)), Pose(2.0, 2.0, 0.0))
    # Row 239 looks slightly up: it passes above the box and meets the wall.
    assert sem[239, COL] == 0 and depth[239, COL] == pytest.approx(3.95, abs=1e-3)
    # Row 355 looks down with slope k = -(355 - cy)/fy: it enters the box's top face (z = 0.5).
    k = (CY - 355) / FY
    d_top = (0.5 - H) / k
    assert 1.0 < d_top < 1.4
    assert sem[355, COL] == 3 and depth[355, COL] == pytest.approx(d_top, rel=1e-4)
    # Low rows hit the box's front face at d = 1.0.
    assert sem[430, COL] == 3 and depth[430, COL] == pytest.approx(1.0, abs=1e-4)


def test_object_behind_wall_is_hidden() -> None:
    scene = room(length_m=8.0)
    scene.structure[:, 80] = Material.WALL  # wall at x in [4.0, 4.05]
    scene.objects.append(ObjectInstance(5, "sofa", (5.0, 2.0), (0.8, 2.0, 2.5)))
    for yaw in (-0.3, 0.0, 0.3):
        _, depth, sem = render(scene, Pose(2.0, 2.0, yaw))
        assert (sem == 0).all()
        assert depth[ROW, COL] <= 2.0 / math.cos(yaw) + 1e-3


def test_rotated_box_corner_depth() -> None:
    box = ObjectInstance(9, "cabinet", (4.0, 2.0), (0.5, 0.5, 2.0), yaw=math.pi / 4)
    _, depth, sem = render(room(objects=(box,)), Pose(2.0, 2.0, 0.0))
    corner = 2.0 - 0.25 * math.sqrt(2.0)
    assert sem[ROW, COL] == 9
    assert depth[ROW, COL] == pytest.approx(corner, abs=0.01)


def test_left_is_left() -> None:
    # An object at +y of an agent facing +x is on the agent's left, i.e. in the left half of the image.
    box = ObjectInstance(4, "plant", (3.5, 2.8), (0.3, 0.3, 1.5))
    _, _, sem = render(room(objects=(box,)), Pose(2.0, 2.0, 0.0))
    cols = np.flatnonzero((sem == 4).any(axis=0))
    assert cols.size > 0 and cols.max() < INTR.cx


def test_mounted_object_floats() -> None:
    picture = ObjectInstance(2, "picture", (5.9, 2.0), (0.04, 0.8, 0.5), elevation=1.3)
    _, _, sem = render(room(objects=(picture,)), Pose(3.95, 2.0, 0.0))
    rows = np.flatnonzero(sem[:, COL] == 2)
    # Seen between heights 1.3 and 1.8 on the plane x = 5.88 (1.93 m ahead).
    d = 5.88 - 3.95
    assert rows.min() == pytest.approx(CY - (1.8 - H) * FY / d, abs=1.5)
    assert rows.max() == pytest.approx(CY - (1.3 - H) * FY / d, abs=1.5)
    assert sem[ROW, COL] == 0


def test_outside_grid_is_opaque_unknown() -> None:
    structure = np.zeros((40, 40), np.uint8)  # no walls at all: the grid border is the limit
    scene = Scene("open", GridSpec(RES, (0.0, 0.0), (40, 40)), structure)
    rgb, depth, _ = render(scene, Pose(1.0, 1.0, 0.0))
    assert depth[ROW, COL] == pytest.approx(1.0, abs=1e-4)
    assert tuple(rgb[ROW, COL]) < tuple(c + 1 for c in palette.UNKNOWN_COLOR)


def test_rgb_floor_wall_ceiling_distinct() -> None:
    rgb, _, _ = render(room(), Pose(2.0, 2.0, 0.0))
    floor = rgb[470, 100:540].reshape(-1, 3).mean(axis=0)
    wall = rgb[ROW, 100:540].reshape(-1, 3).mean(axis=0)
    ceiling = rgb[5, 100:540].reshape(-1, 3).mean(axis=0)
    assert np.abs(floor - wall).sum() > 60
    assert ceiling.sum() > wall.sum() > floor.sum()


def test_palette_is_stable_and_separated() -> None:
    core = ["chair", "bed", "sofa", "toilet", "tv", "plant", "table", "refrigerator", "sink", "bathtub"]
    colors = [palette.category_color(c) for c in core]
    for i in range(len(colors)):
        for j in range(i + 1, len(colors)):
            assert sum(abs(a - b) for a, b in zip(colors[i], colors[j], strict=True)) > 60
    unlisted = palette.category_color("grand piano")
    assert unlisted == palette.category_color(" Grand Piano ")
    assert all(0 <= c <= 255 for c in unlisted)
    assert palette.floor_color("kitchen") != palette.floor_color("bedroom")
    for name in ("", "kitchen", "bathroom", "bedroom", "living room", "hallway", "office", "attic", "gym"):
        floor = palette.floor_color(name)
        assert sum(abs(a - b) for a, b in zip(floor, palette.WALL_COLOR, strict=True)) > 90, name
    assert palette.floor_pattern(" Zen Garden ") == palette.floor_pattern("zen garden")  # unknown rooms: by name
    assert palette.floor_pattern("bathroom") != palette.floor_pattern("bedroom")  # tiles in wet rooms, planks else


def test_demo_house_semantics_match_instances() -> None:
    scene = demo_house()
    ids = {o.instance_id for o in scene.objects}
    _, _, sem = render(scene, Pose(7.8, 1.0, 0.5))
    seen = set(np.unique(sem)) - {0}
    assert seen and seen <= ids


def test_bench_reports_fields() -> None:
    result = bench_sim(frames=5, scene=room())
    assert result["width"] == 640 and result["height"] == 480 and result["frames"] == 5
    assert isinstance(result["fps"], float) and result["fps"] > 0


@settings(max_examples=25, deadline=None)
@given(st.floats(0.0, 1.0), st.floats(0.0, 1.0), st.floats(-math.pi, math.pi))
def test_geometry_only_gives_the_full_frames_depth_and_semantics(fx: float, fy: float, yaw: float) -> None:
    scene = demo_house()
    rows, cols = scene.grid.shape
    res = scene.grid.resolution
    pose = Pose(scene.grid.origin[0] + fx * cols * res, scene.grid.origin[1] + fy * rows * res, yaw)
    renderer = Renderer(scene, CFG)
    _, depth, sem = renderer.render(pose)
    depth_only, sem_only = renderer.render_geometry(pose)
    np.testing.assert_array_equal(depth_only, depth)
    np.testing.assert_array_equal(sem_only, sem)
