"""The renderer in buildings: a staircase seen from below and from above has the depth of its real geometry, the
stairwell opens the slab, and a one-storey building renders as its floor plan does."""

from __future__ import annotations

import math

import numpy as np
import pytest
from tests.floor_scenes import FLIGHT, STOREY, two_floors

from drivenav.envs.embedded.building import Building, Storey
from drivenav.envs.embedded.render import Renderer
from drivenav.types import Pose, SimConfig

CFG = SimConfig()
INTR = CFG.intrinsics
TOLERANCE = 1e-3  # metres: float32 depth of a few metres is good to a micrometre
RES_CELL = 0.05  # the grid's cell: step heights read from depth agree with the geometry within one


def hit_points(pose: Pose, depth: np.ndarray) -> np.ndarray:
    """Per pixel the world point its depth says it sees ``(H, W, 3)``, NaN where the depth is clipped."""
    v, u = np.mgrid[0 : depth.shape[0], 0 : depth.shape[1]]
    t = (INTR.cx - u) / INTR.fx
    k = (INTR.cy - v) / INTR.fy
    c, s = math.cos(pose.yaw), math.sin(pose.yaw)
    d = depth.astype(np.float64)
    d[(depth <= CFG.min_depth) | (depth >= CFG.max_depth)] = np.nan
    x = pose.x + d * (c - t * s)
    y = pose.y + d * (s + t * c)
    z = pose.z + CFG.camera_height + k * d
    return np.stack([x, y, z], axis=-1)


def on_the_flight(points: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """For points over the flight's footprint: whether each lies on a tread, a riser or a side of the solid steps,
    and the index of the tread each tread point lies on (-1 elsewhere)."""
    along = points[..., 0] - FLIGHT.foot[0]
    across = points[..., 1] - FLIGHT.foot[1]
    z = points[..., 2] - FLIGHT.base
    step = np.clip(np.floor(np.nan_to_num(along) / FLIGHT.going).astype(int) + 1, 1, FLIGHT.risers - 1)
    top = step * FLIGHT.riser
    tread = np.abs(z - top) < TOLERANCE
    front = np.abs(along - (step - 1) * FLIGHT.going) < TOLERANCE
    back = np.abs(along - step * FLIGHT.going) < TOLERANCE
    riser = (front & (z <= top + TOLERANCE)) | (back & (z <= top + FLIGHT.riser + TOLERANCE))
    side = (np.abs(np.abs(across) - FLIGHT.width / 2) < TOLERANCE) & (z <= top + TOLERANCE)
    on_surface = tread | riser | side
    return on_surface, np.where(tread, step, -1)


def over_flight(points: np.ndarray) -> np.ndarray:
    """Points whose plan position lies over the flight's footprint, its edges included."""
    x0, y0, x1, y1 = FLIGHT.rect()
    x, y = points[..., 0], points[..., 1]
    inside: np.ndarray = (x > x0 - TOLERANCE) & (x < x1 + TOLERANCE) & (y > y0 - TOLERANCE) & (y < y1 + TOLERANCE)
    return inside & np.isfinite(points[..., 2]) & (points[..., 2] < STOREY - 0.2 - TOLERANCE)


@pytest.mark.parametrize(
    ("label", "pose"),
    [
        ("at the foot", Pose(1.0, 2.5, 0.0, 0.0)),  # a metre before the first riser, looking up the flight
        ("on the flight", Pose(3.35, 2.5, 0.0, 0.94)),  # on its ramp a third of the way up, looking up
        ("beside it", Pose(4.0, 4.2, -math.pi / 2.0, 0.0)),  # downstairs beside it, facing its side
    ],
)
def test_a_staircase_seen_from_below_has_the_depth_of_its_steps(label: str, pose: Pose) -> None:
    """Every pixel that sees a point over the flight sees a tread, a riser or a side of the solid steps, and the
    treads' heights read from depth are the steps' within a cell."""
    building = two_floors()
    depth, _ = Renderer(building, CFG).render_geometry(pose)
    points = hit_points(pose, depth)
    inside = over_flight(points)
    on_surface, tread = on_the_flight(points)
    assert inside.sum() > 1500, label
    assert on_surface[inside].all(), f"{label}: {int((~on_surface & inside).sum())} pixels off the steps"
    seen = np.unique(tread[inside & (tread > 0)])
    assert len(seen) >= 3, f"{label}: treads seen {seen}"
    for step in seen:
        heights = points[..., 2][inside & (tread == step)]
        assert np.all(np.abs(heights - step * FLIGHT.riser) < RES_CELL), f"{label}: tread {step}"


def test_from_the_top_the_stairwell_is_an_opening_in_the_floor() -> None:
    """Upstairs at the top of the flight, looking down it (a level camera sees none of a 35 degree flight's
    treads from above): where a row's ray would meet the upper floor inside the stairwell, the floor is missing and
    the ray goes on, to the opening's far edge or farther than the depth range."""
    building = two_floors()
    pose = Pose(6.3, 2.5, math.pi, STOREY)
    depth, _ = Renderer(building, CFG).render_geometry(pose)
    x0, _, x1, _ = FLIGHT.rect()
    checked = 0
    for v in range(int(INTR.cy) + 1, depth.shape[0]):
        floor_depth = CFG.camera_height * INTR.fy / (v - INTR.cy)  # where this row meets the upper floor's plane
        x = pose.x - floor_depth  # on the centre column, facing -x
        if not (x0 + 0.05 < x < x1 - 0.05):
            continue
        checked += 1
        assert depth[v, 320] > floor_depth + TOLERANCE, f"row {v}: a floor at {depth[v, 320]} m over the stairwell"
    assert checked > 30
    hits = hit_points(pose, depth)[..., 2]
    over = np.isfinite(hits) & (np.arange(depth.shape[0])[:, None] > INTR.cy)
    assert np.any(hits[over] < STOREY - TOLERANCE)  # the opening's far edge and what lies below the floor


def test_the_lower_floor_has_a_ceiling_where_the_slab_is_closed() -> None:
    """Downstairs, away from the stairwell, nothing above the upper slab's underside is seen, and that underside
    is (the ceiling)."""
    building = two_floors()
    pose = Pose(1.0, 1.0, -math.pi / 4.0, 0.0)  # facing the south-east corner, the stairwell behind
    depth, _ = Renderer(building, CFG).render_geometry(pose)
    heights = hit_points(pose, depth)[..., 2]
    seen = heights[np.isfinite(heights)]
    assert seen.max() == pytest.approx(building.ceiling(0), abs=TOLERANCE)
    assert np.sum(np.abs(seen - building.ceiling(0)) < TOLERANCE) > 1000


def test_a_one_storey_building_renders_as_its_floor_plan() -> None:
    plan = two_floors().storeys[0].plan
    alone = Renderer(plan, CFG)
    as_building = Renderer(Building("test/one", (Storey(plan, 0.0),)), CFG)
    for pose in (Pose(1.0, 2.5, 0.3), Pose(5.0, 1.2, 2.0), Pose(3.0, 4.0, -1.2)):
        for a, b in zip(alone.render(pose), as_building.render(pose), strict=True):
            assert np.array_equal(a, b)
