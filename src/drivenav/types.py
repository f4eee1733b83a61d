"""The types every layer shares: actions, poses, camera intrinsics, the sensor/agent body and observations.

Neutral ground between the algorithmic core (``mapping``, ``directions``, ``inspection``, ``semantics``, ``agent``)
and the worlds (``envs``): both import these, neither imports the other.

Frames. The *world* frame of a scene is the 2-D map frame (x east, y north, metres; yaw counter-clockwise from
+x). The *episode* frame, in which observations report the pose, has its origin at the episode's start position,
its +x axis along the start heading and +y to the left, yaw counter-clockwise from the start heading: Habitat's
GPS+compass, made right-handed (Habitat's GPS reports ``(forward, right)``; an adapter negates the second
component).
"""

from __future__ import annotations

import math
from collections.abc import Callable, Mapping
from dataclasses import dataclass
from enum import IntEnum
from typing import TYPE_CHECKING, Any, Protocol

import numpy as np
from numpy.typing import NDArray

from drivenav.ranges import COUNT, LENGTH, MAX_FRAME_SIDE, POSITIVE_LENGTH, Range, check_ranges, check_rule


class Action(IntEnum):
    """Discrete actions, numbered as in Habitat's ObjectNav task."""

    STOP = 0
    MOVE_FORWARD = 1
    TURN_LEFT = 2
    TURN_RIGHT = 3


@dataclass(frozen=True)
class Pose:
    """A pose on the floor: planar position in metres, yaw in radians (counter-clockwise), and the height ``z`` of
    the agent's feet (metres, up; what odometry or habitat's agent state reports, 0 in a world without floors).
    Headings stay planar: the body is upright, so a frame change turns about the vertical and shifts ``z``."""

    x: float
    y: float
    yaw: float
    z: float = 0.0

    def compose(self, local: Pose) -> Pose:
        """``self * local``: the pose ``local`` (given in this pose's frame) in the parent frame."""
        c, s = math.cos(self.yaw), math.sin(self.yaw)
        return Pose(
            self.x + c * local.x - s * local.y,
            self.y + s * local.x + c * local.y,
            self.yaw + local.yaw,
            self.z + local.z,
        )

    def inverse(self) -> Pose:
        """The pose of the parent frame's origin in this pose's frame."""
        c, s = math.cos(self.yaw), math.sin(self.yaw)
        return Pose(-c * self.x - s * self.y, s * self.x - c * self.y, -self.yaw, -self.z)


@dataclass(frozen=True)
class CameraIntrinsics:
    """Pinhole intrinsics in pixels. The camera looks along the agent's heading, level with the floor."""

    width: int
    height: int
    fx: float
    fy: float
    cx: float
    cy: float

    @staticmethod
    def from_hfov(width: int, height: int, hfov_deg: float) -> CameraIntrinsics:
        """Square pixels with the given horizontal field of view (Habitat's convention)."""
        f = (width / 2.0) / math.tan(math.radians(hfov_deg) / 2.0)
        return CameraIntrinsics(width, height, f, f, (width - 1) / 2.0, (height - 1) / 2.0)


@dataclass(frozen=True)
class SimConfig:
    """Simulator settings; defaults follow the Habitat ObjectNav set-up the paper uses."""

    width: int = 640
    height: int = 480
    hfov_deg: float = 79.0
    camera_height: float = 0.88
    min_depth: float = 0.5
    max_depth: float = 5.0
    agent_radius: float = 0.18
    agent_height: float = 0.88
    forward_step: float = 0.25
    turn_angle_deg: float = 30.0
    max_steps: int = 500
    success_distance: float = 0.25
    grid_resolution: float = 0.05

    def __post_init__(self) -> None:
        frame_side = Range(1, MAX_FRAME_SIDE, integer=True)
        ranges = {
            "width": frame_side,
            "height": frame_side,
            "hfov_deg": Range(0.0, 180.0, low_open=True, high_open=True, why="a pinhole camera's field of view"),
            "camera_height": LENGTH,
            "min_depth": LENGTH,
            "max_depth": POSITIVE_LENGTH,
            "agent_radius": LENGTH,
            "agent_height": POSITIVE_LENGTH,
            "forward_step": POSITIVE_LENGTH,
            "turn_angle_deg": Range(0.0, 180.0, low_open=True, why="a larger turn is the other way round"),
            "max_steps": COUNT,
            "success_distance": LENGTH,
            "grid_resolution": POSITIVE_LENGTH,
        }
        check_ranges(self, ranges)
        check_rule(self, "min_depth", self.min_depth < self.max_depth, f"less than max_depth ({self.max_depth:g} m)")

    @property
    def intrinsics(self) -> CameraIntrinsics:
        return CameraIntrinsics.from_hfov(self.width, self.height, self.hfov_deg)


UNKNOWN_CELL, FREE_CELL, OCCUPIED_CELL = -1, 0, 1  # the states of a LocalOccupancy cell


@dataclass(frozen=True)
class LocalOccupancy:
    """A window of a robot's 2-D LiDAR occupancy grid in the episode frame (paper Sec. V-E: LiDAR returns kept
    only inside the camera's forward field of view).

    ``cells`` is (rows, cols) int8, :data:`UNKNOWN_CELL`, :data:`FREE_CELL` or :data:`OCCUPIED_CELL`, indexed as
    every drivenav grid (:mod:`drivenav.grid`: row with ``y``, column with ``x``); ``origin`` is the episode-frame
    position of the lower-left corner of cell (0, 0) and ``resolution`` the cell size, in metres.
    """

    cells: NDArray[np.int8]
    origin: tuple[float, float]
    resolution: float


@dataclass(frozen=True)
class Observation:
    """One egocentric observation.

    ``rgb`` is (H, W, 3) uint8; ``depth`` is (H, W) float32 z-depth in metres clipped to
    ``[min_depth, max_depth]``; ``semantic`` is (H, W) int32 instance ids (0 = none) or None where the world
    has no ground truth; ``pose`` is in the episode frame. ``occupancy`` is a robot's LiDAR occupancy around the
    agent (None in simulation and where the robot sends none).

    A world whose RGB image costs more than its other images may hand it over unrendered (:meth:`deferred`): it is
    rendered on the first read of ``rgb`` and kept, so a consumer that never looks at it (the embedded models read
    depth and instance ids) never pays for it. ``dataclasses.replace``, copies and pickles read it first.
    """

    rgb: NDArray[np.uint8]
    depth: NDArray[np.float32]
    semantic: NDArray[np.int32] | None
    pose: Pose
    intrinsics: CameraIntrinsics
    step: int
    collided: bool
    occupancy: LocalOccupancy | None = None

    @classmethod
    def deferred(
        cls,
        render_rgb: Callable[[], NDArray[np.uint8]],
        depth: NDArray[np.float32],
        semantic: NDArray[np.int32] | None,
        pose: Pose,
        intrinsics: CameraIntrinsics,
        step: int,
        collided: bool,
        occupancy: LocalOccupancy | None = None,
    ) -> Observation:
        """An observation whose ``rgb`` is ``render_rgb()``, called on its first read (at most once)."""
        observation = object.__new__(cls)
        observation.__dict__.update(
            depth=depth,
            semantic=semantic,
            pose=pose,
            intrinsics=intrinsics,
            step=step,
            collided=collided,
            occupancy=occupancy,
            _render_rgb=render_rgb,
        )
        return observation

    def rgb_renderer(self) -> Callable[[], NDArray[np.uint8]] | None:
        """The call that renders a deferred RGB image not read yet; None once it is read, and for an eager one."""
        render: Callable[[], NDArray[np.uint8]] | None = self.__dict__.get("_render_rgb")
        return render

    if not TYPE_CHECKING:  # hidden from type checkers, which would otherwise accept any attribute name

        def __getattr__(self, name: str) -> Any:
            """Only reached for attributes not set: a deferred ``rgb`` is rendered here, once."""
            render = self.rgb_renderer() if name == "rgb" else None
            if render is None:
                raise AttributeError(f"{type(self).__name__!r} object has no attribute {name!r}")
            rgb = render()
            object.__setattr__(self, "rgb", rgb)
            object.__delattr__(self, "_render_rgb")
            return rgb

    def __getstate__(self) -> dict[str, object]:
        """Pickles and copies carry the pixels, not the renderer of a deferred image."""
        self.rgb  # noqa: B018 -- renders a deferred image
        return dict(self.__dict__)


SEMANTIC = "semantic"  # instance ids of the visible pixels and what each instance is
GEODESIC = "geodesic"  # the geodesic distance to the goals and the world's motion model
PRIVILEGED_KINDS = (SEMANTIC, GEODESIC)


class GeodesicOracle(Protocol):
    """Ground-truth geometry of one episode (``geodesic``): what the oracle agent plans with."""

    @property
    def start_pose(self) -> Pose:
        """The episode's start pose in the world frame."""
        ...

    def distance(self, pose: Pose) -> float:
        """Geodesic distance from a world-frame pose's point (its height included) to the nearest goal (the success
        metric's own)."""
        ...

    def forward(self, pose: Pose) -> tuple[Pose, bool]:
        """Where a forward step from a world-frame pose along its yaw ends, and whether it collides."""
        ...

    @property
    def goal_heights(self) -> tuple[float, ...]:
        """The heights of the goals' view points in the world frame (the floors the goals are seen from)."""
        ...


class CategoryVocabulary(Protocol):
    """The world's category names (``semantic``): what a phrase names, and a category's synonyms."""

    def canonical(self, name: str) -> str | None:
        """The category a name or synonym stands for, or None where the vocabulary does not know it."""
        ...

    def synonyms(self, category: str) -> tuple[str, ...]:
        """Other names of a category returned by :meth:`canonical`."""
        ...

    def categories(self) -> list[str]:
        """Every category name (canonical), in the vocabulary's order."""
        ...

    @property
    def room_types(self) -> tuple[str, ...]:
        """The kinds of room the world's scenes have (empty where it does not say)."""
        ...

    def room_shares(self, category: str) -> dict[str, float]:
        """Where a category is found: room type -> share of its objects (summing to 1; empty where the vocabulary
        does not say): the common knowledge a language model has of homes, which stand-in reasoners draw on."""
        ...


@dataclass(frozen=True)
class GroundTruth:
    """Privileged information for the agents (and stand-in models) that ask for it.

    ``labels`` and ``vocabulary`` (``semantic``): instance id -> category name, for the ids in
    :attr:`Observation.semantic`, and the world's category names; ``geodesic`` (``geodesic``): the episode's
    geometry for the oracle.
    """

    labels: Mapping[int, str] | None = None
    vocabulary: CategoryVocabulary | None = None
    geodesic: GeodesicOracle | None = None
