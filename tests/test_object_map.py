"""Mask projection and the object map (Sec. IV-C): hand-computed geometry, merging, failed-position memory."""

from __future__ import annotations

import math
import warnings

import numpy as np
import pytest

from drivenav.envs.embedded.render import render_views
from drivenav.envs.embedded.scene import Material, ObjectInstance, Room, Scene
from drivenav.envs.vocabulary import VOCABULARY
from drivenav.grid import GridSpec
from drivenav.mapping.kernels import project_depth
from drivenav.mapping.objects import ObjectMap, nearest_point, project_mask
from drivenav.semantics.ground_truth import GroundTruthGrounder
from drivenav.types import CameraIntrinsics, GroundTruth, Observation, Pose, SimConfig

# A toy pinhole: pixel (v, u) = (30, 40) is on the optical axis; one pixel is 1/40 rad-ish at unit depth.
INTR = CameraIntrinsics(width=81, height=61, fx=40.0, fy=40.0, cx=40.0, cy=30.0)
CAM_H, MIN_D, MAX_D = 0.88, 0.5, 5.0


def project(mask: np.ndarray, depth: np.ndarray, pose: Pose, **kwargs: int) -> np.ndarray:
    return project_mask(mask, depth, INTR, pose, camera_height=CAM_H, min_depth=MIN_D, max_depth=MAX_D, **kwargs)


def box(rows: slice, cols: slice, z: float) -> tuple[np.ndarray, np.ndarray]:
    """A mask over ``rows`` x ``cols`` and a depth image reading ``z`` there (NaN elsewhere)."""
    mask = np.zeros((INTR.height, INTR.width), np.bool_)
    mask[rows, cols] = True
    depth = np.full(mask.shape, np.nan, np.float32)
    depth[mask] = z
    return mask, depth


def test_box_straight_ahead() -> None:
    # Columns 38..42 at 3 m: lateral offsets 3 * (40 - u) / 40 in [-0.15, 0.15]; the left column is at +y.
    mask, depth = box(slice(20, 31), slice(38, 43), 3.0)
    xy = project(mask, depth, Pose(0.0, 0.0, 0.0))
    assert xy.shape == (55, 2)
    assert np.allclose(xy[:, 0], 3.0)
    assert xy[:, 1].min() == pytest.approx(-0.15) and xy[:, 1].max() == pytest.approx(0.15)
    left_column = project(*box(slice(20, 31), slice(38, 39), 3.0), Pose(0.0, 0.0, 0.0))
    assert np.allclose(left_column, [3.0, 0.15])


def test_box_to_the_left_at_a_known_yaw() -> None:
    # Facing +y from (1, 2). Columns 16..24 at 2 m are 2 * (40 - u) / 40 = 0.8..1.2 m left of the heading,
    # and left of +y is -x: world x = 1 - left in [-0.2, 0.2], y = 2 + 2 = 4.
    mask, depth = box(slice(25, 36), slice(16, 25), 2.0)
    xy = project(mask, depth, Pose(1.0, 2.0, math.pi / 2))
    assert np.allclose(xy[:, 1], 4.0)
    assert xy[:, 0].min() == pytest.approx(-0.2) and xy[:, 0].max() == pytest.approx(0.2)
    assert np.median(xy[:, 0]) == pytest.approx(0.0)


def test_invalid_depth_and_floor_are_ignored() -> None:
    # On the optical-axis row, where an unfiltered inf reading would make inf * 0 = NaN (and warn).
    mask, depth = box(slice(30, 31), slice(30, 39), 2.0)
    depth[30, 30:38] = [np.nan, np.inf, -np.inf, 0.0, -1.0, MIN_D, MAX_D, MAX_D - 0.005]
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        xy = project(mask, depth, Pose(0.0, 0.0, 0.0))
    assert np.allclose(xy, [[2.0, 2.0 * (40 - 38) / 40]])
    # Row 50 looks down at -0.5 rad-ish: at z = 0.88 / 0.5 = 1.76 m it sees the floor (height 0).
    floor_mask, floor_depth = box(slice(50, 51), slice(40, 41), 1.76)
    assert project(floor_mask, floor_depth, Pose(0.0, 0.0, 0.0)).shape == (0, 2)
    assert project(floor_mask, floor_depth, Pose(0.0, 0.0, 0.0), min_height=-1).shape == (1, 2)


def test_large_masks_are_subsampled() -> None:
    mask, depth = box(slice(0, 61), slice(0, 81), 2.0)
    xy = project(mask, depth, Pose(0.0, 0.0, 0.0), max_points=1000)
    assert 900 <= xy.shape[0] <= 1000
    assert xy[:, 1].max() - xy[:, 1].min() > 3.5  # still spans the whole image width (+-2 m)


def test_mask_shape_must_match_depth() -> None:
    with pytest.raises(ValueError):
        project(np.ones((3, 3), np.bool_), np.ones((61, 81), np.float32), Pose(0.0, 0.0, 0.0))


@pytest.mark.parametrize(
    ("v", "u", "z", "pose"), [(10, 5, 1.3, Pose(0.3, -0.7, 2.1)), (25, 70, 4.2, Pose(-1, 2, -0.8))]
)
def test_same_convention_as_the_occupancy_kernel(v: int, u: int, z: float, pose: Pose) -> None:
    mask, depth = box(slice(v, v + 1), slice(u, u + 1), z)
    (point,) = project(mask, depth, pose)
    grid = GridSpec(0.05, (-6.0, -6.0), (240, 240))
    obstacle = np.zeros(grid.shape, np.bool_)
    project_depth(
        depth,
        np.array([v], np.int64),
        np.array([u], np.int64),
        np.array([INTR.fx, INTR.fy, INTR.cx, INTR.cy, CAM_H]),
        np.array([MIN_D, MAX_D, 0.01, -10.0, 10.0]),
        np.array([pose.x, pose.y, pose.yaw]),
        np.array([*grid.origin, grid.resolution]),
        obstacle,
        np.zeros_like(obstacle),
        np.zeros((1, 2), np.int64),
        np.zeros(1),
    )
    (cell,) = np.argwhere(obstacle)
    assert np.allclose(grid.cell_to_world(cell), point, atol=0.05)


def blob(x: float, y: float, n: int = 50, spread: float = 0.2) -> np.ndarray:
    t = np.linspace(-1.0, 1.0, n)
    return np.stack([x + spread * t, y + 0.5 * spread * t[::-1]], axis=1)


def test_detections_of_one_object_merge() -> None:
    objects = ObjectMap(merge_radius=0.6)
    first = objects.add(blob(3.0, 0.0), "sofa", 0.7, step=4)
    second = objects.add(blob(3.4, 0.1), "grey couch", 0.9, step=6)
    assert first is not None and second is not None
    assert second.candidate_id == first.candidate_id
    assert len(objects.candidates()) == 1
    assert second.points.shape == (100, 2) and second.frames == 2
    assert (second.first_step, second.last_step) == (4, 6)
    assert second.score == 0.9 and second.phrase == "grey couch"
    assert 3.0 < second.center[0] < 3.4
    same_frame = objects.add(blob(3.1, 0.0), "sofa", 0.5, step=6)
    assert same_frame is not None and same_frame.frames == 2 and same_frame.phrase == "grey couch"


def test_separate_objects_stay_apart() -> None:
    objects = ObjectMap(merge_radius=0.6)
    a = objects.add(blob(3.0, 0.0), "chair", 0.8, step=1)
    b = objects.add(blob(3.0, 1.5), "chair", 0.8, step=1)
    assert a is not None and b is not None and a.candidate_id != b.candidate_id
    assert [c.candidate_id for c in objects.candidates()] == [a.candidate_id, b.candidate_id]
    # A detection nearer to b joins b, not a.
    c = objects.add(blob(3.0, 1.2), "chair", 0.8, step=2)
    assert c is not None and c.candidate_id == b.candidate_id


def test_partial_views_of_a_long_object_merge() -> None:
    # Two halves of a 2 m sofa: their centres are 1 m apart, but each centre is near the other half's points.
    objects = ObjectMap(merge_radius=0.6)
    left = np.stack([np.linspace(0.0, 1.0, 40), np.zeros(40)], axis=1)
    assert objects.add(left, "sofa", 1.0, step=0) is not None
    assert objects.add(left + np.array([1.05, 0.0]), "sofa", 1.0, step=1) is not None
    assert len(objects.candidates()) == 1


def test_rejection_feeds_failed_position_memory() -> None:
    objects = ObjectMap(merge_radius=0.6, failed_radius=1.0)
    kept = objects.add(blob(0.0, 5.0), "bed", 0.8, step=1)
    bad = objects.add(blob(4.0, 0.0), "bed", 0.8, step=1)
    assert kept is not None and bad is not None
    rejected = objects.reject(bad.candidate_id)
    assert rejected.status == "rejected" and objects.rejected() == [rejected]
    assert [c.candidate_id for c in objects.candidates()] == [kept.candidate_id]
    with pytest.raises(KeyError):
        objects.get(bad.candidate_id)
    assert objects.is_failed((4.5, 0.5)) and not objects.is_failed((5.5, 0.0))
    assert objects.add(blob(4.3, 0.2), "bed", 1.0, step=2) is None
    assert len(objects.candidates()) == 1
    fresh = objects.add(blob(7.0, 0.0), "bed", 1.0, step=3)
    assert fresh is not None and fresh.candidate_id not in (kept.candidate_id, bad.candidate_id)


def test_accept_and_reset() -> None:
    objects = ObjectMap()
    a = objects.add(blob(1.0, 1.0), "tv", 0.6, step=0)
    b = objects.add(blob(-3.0, 1.0), "tv", 0.6, step=0)
    assert a is not None and b is not None and objects.accepted() == []
    accepted = objects.accept(b.candidate_id)
    assert accepted.status == "accepted" and objects.accepted() == [accepted]
    merged = objects.add(blob(-3.1, 1.0), "tv", 0.2, step=1)
    assert merged is not None and merged.status == "accepted"
    objects.reject(a.candidate_id)
    objects.reset()
    assert objects.candidates() == [] and objects.rejected() == [] and not objects.is_failed((1.0, 1.0))
    assert objects.add(blob(1.0, 1.0), "tv", 0.6, step=0) is not None


def test_points_are_bounded_and_read_only() -> None:
    objects = ObjectMap(max_points=120)
    candidate = None
    for step in range(5):
        candidate = objects.add(blob(2.0, 2.0, n=100), "plant", 0.5, step=step)
    assert candidate is not None and candidate.points.shape == (120, 2) and candidate.frames == 5
    assert not candidate.points.flags.writeable
    assert objects.add(np.zeros((0, 2)), "plant", 0.5, step=9) is None


def test_nearest_point() -> None:
    objects = ObjectMap()
    candidate = objects.add(np.array([[2.0, 0.0], [2.5, 0.5], [3.0, 1.0]]), "sink", 1.0, step=0)
    assert candidate is not None
    assert nearest_point(candidate, (0.0, 0.0)) == (2.0, 0.0)
    assert nearest_point(candidate, (4.0, 2.0)) == (3.0, 1.0)


def test_rendered_object_projects_onto_its_footprint() -> None:
    # A 6 x 5 m room around the world origin; the episode starts at the origin facing +x, so the episode
    # frame is the world frame. A rotated sofa stands 3 m ahead, 0.8 m to the left.
    res = 0.05
    grid = GridSpec(res, (-1.0, -2.5), (100, 120))
    structure = np.zeros(grid.shape, np.uint8)
    structure[0, :] = structure[-1, :] = structure[:, 0] = structure[:, -1] = Material.WALL
    sofa = ObjectInstance(7, "sofa", (3.0, 0.8), (1.8, 0.8, 0.8), yaw=0.3)
    plant = ObjectInstance(8, "plant", (2.0, -1.0), (0.4, 0.4, 0.9))
    polygon = ((-1.0, -2.5), (5.0, -2.5), (5.0, 2.5), (-1.0, 2.5))
    scene = Scene("box", grid, structure, [sofa, plant], [Room("living room", polygon)])
    sim = SimConfig()
    pose = Pose(0.0, 0.0, 0.1)
    rgb, depth, semantic = render_views(scene, pose, sim)
    obs = Observation(rgb, depth, semantic, pose, sim.intrinsics, step=0, collided=False)
    grounder = GroundTruthGrounder(GroundTruth({o.instance_id: o.category for o in scene.objects}, VOCABULARY))
    (detection,) = grounder.segment(obs, "couch")
    xy = project_mask(
        detection.mask,
        obs.depth,
        obs.intrinsics,
        obs.pose,
        camera_height=sim.camera_height,
        min_depth=sim.min_depth,
        max_depth=sim.max_depth,
    )
    assert xy.shape[0] > 500
    assert np.max(sofa.distance(xy[:, 0], xy[:, 1])) < 0.02
    candidate = ObjectMap().add(xy, detection.phrase, detection.score, obs.step)
    assert candidate is not None
    assert sofa.distance(np.array(candidate.center[0]), np.array(candidate.center[1])) < 0.3
