"""The object map: grounded target candidates in the episode frame and failed-position memory (Sec. IV-C).

"Accepted masks are projected from RGB-D observations into the object map and can replace the frontier goal,
whereas rejected detections are removed and stored as failed-position memory." A grounded mask is lifted to
world ``(x, y)`` points with :func:`project_mask`; :class:`ObjectMap` merges the points of repeated
detections of one object into an :class:`ObjectCandidate`, which verification then accepts or rejects. A
rejected candidate leaves the map, and later detections at its place are ignored.

Back-projection follows the occupancy mapper (:func:`drivenav.mapping.kernels.project_depth`) exactly: pixel
``(v, u)`` with z-depth ``z`` lies ``z`` metres ahead of the camera and ``z * (cx - u) / fx`` to its left
(a pixel left of ``cx`` looks left), at height ``camera_height + z * (cy - v) / fy`` above the floor.
"""

from __future__ import annotations

import dataclasses
import math
from dataclasses import dataclass
from typing import Literal

import numpy as np
from numpy.typing import NDArray

from drivenav.types import CameraIntrinsics, Pose

Points = NDArray[np.float64]
Status = Literal["candidate", "accepted", "rejected"]


def back_project(u: NDArray[np.int64], z: NDArray[np.float64], intrinsics: CameraIntrinsics, pose: Pose) -> Points:
    """World ``(x, y)`` ``(N, 2)``, in the frame of ``pose``, of pixels in columns ``u`` at z-depth ``z``."""
    left = z * (intrinsics.cx - u) / intrinsics.fx
    c, s = math.cos(pose.yaw), math.sin(pose.yaw)
    return np.stack([pose.x + c * z - s * left, pose.y + s * z + c * left], axis=1)


def pixel_height(
    v: NDArray[np.int64], z: NDArray[np.float64], intrinsics: CameraIntrinsics, camera_height: float
) -> NDArray[np.float64]:
    """Height above the floor of pixels in rows ``v`` at z-depth ``z`` (level camera at ``camera_height``)."""
    return camera_height + z * (intrinsics.cy - v) / intrinsics.fy


def project_mask(
    mask: NDArray[np.bool_],
    depth: NDArray[np.float32],
    intrinsics: CameraIntrinsics,
    pose: Pose,
    *,
    camera_height: float,
    min_depth: float,
    max_depth: float,
    clip_epsilon: float = 0.01,
    min_height: float = 0.02,
    max_points: int = 4000,
) -> Points:
    """World ``(x, y)`` ``(N, 2)`` (the frame of ``pose``) of the ``mask`` pixels with a valid depth reading.

    Readings that are NaN, infinite, <= 0 or within ``clip_epsilon`` of ``min_depth`` / ``max_depth`` (clip
    values, not surfaces) are skipped, and so are points lower than ``min_height`` above the floor: floor seen
    through a loose mask edge, which would drag the object towards the camera. When more than ``max_points``
    pixels remain, only an evenly strided subset of at most ``max_points`` is projected.
    """
    if mask.shape != depth.shape:
        raise ValueError(f"mask shape {mask.shape} differs from depth shape {depth.shape}")
    v, u = np.nonzero(mask)
    z = depth[v, u].astype(np.float64)
    valid = (z > max(min_depth + clip_epsilon, 0.0)) & (z < max_depth - clip_epsilon)  # False for NaN and inf
    v, u, z = v[valid], u[valid], z[valid]
    keep = np.flatnonzero(pixel_height(v, z, intrinsics, camera_height) >= min_height)
    keep = keep[:: max(1, math.ceil(keep.size / max_points))]
    return back_project(u[keep], z[keep], intrinsics, pose)


@dataclass(frozen=True, eq=False)
class ObjectCandidate:
    """One object in the map: the accumulated points of its detections and its verification status.

    ``score`` is the best detection score and ``phrase`` the phrase of that detection; ``frames`` counts the
    distinct steps it was detected in, between ``first_step`` and ``last_step``. Each update yields a new
    snapshot (equality is identity: ``points`` is an array); ``points`` is read-only.
    """

    candidate_id: int
    phrase: str
    points: Points
    score: float
    first_step: int
    last_step: int
    frames: int = 1
    status: Status = "candidate"

    @property
    def center(self) -> tuple[float, float]:
        """The per-axis median of the points (robust to stray pixels)."""
        return _median(self.points)


def nearest_point(candidate: ObjectCandidate, xy: tuple[float, float]) -> tuple[float, float]:
    """The point of ``candidate`` closest to ``xy``: where the agent approaches it."""
    k = int(np.argmin(_distances(candidate.points, xy)))
    return float(candidate.points[k, 0]), float(candidate.points[k, 1])


class ObjectMap:
    """Target candidates of one episode plus the failed-position memory of rejected ones (Sec. IV-C).

    A detection joins the candidate nearest to it when that lies within ``merge_radius``: the distance between
    a detection and a candidate is the smaller of (centre of one, nearest point of the other), which tolerates
    stray points and still joins partial views of a large object. The phrase plays no part, so the phrases that
    prompt enrichment proposes for one object join it. A candidate keeps at most ``max_points`` points (an
    evenly strided subset). A detection whose centre lies within ``failed_radius`` of a rejected candidate's
    centre or points is ignored.
    """

    def __init__(self, merge_radius: float = 0.6, failed_radius: float = 1.0, max_points: int = 2000) -> None:
        if merge_radius < 0.0 or failed_radius < 0.0 or max_points < 1:
            raise ValueError("ObjectMap needs merge_radius >= 0, failed_radius >= 0 and max_points >= 1")
        self.merge_radius = merge_radius
        self.failed_radius = failed_radius
        self.max_points = max_points
        self.reset()

    def reset(self) -> None:
        """Forget all candidates and the failed-position memory (a new episode)."""
        self._live: dict[int, ObjectCandidate] = {}
        self._failed: list[ObjectCandidate] = []
        self._next_id = 1

    def add(self, points: Points, phrase: str, score: float, step: int) -> ObjectCandidate | None:
        """Record one projected detection; the candidate it created or joined, None if empty or failed before."""
        points = np.asarray(points, dtype=np.float64).reshape(-1, 2)
        if points.shape[0] == 0 or self.is_failed(_median(points)):
            return None
        match = self.match(points)
        if match is None:
            created = ObjectCandidate(self._next_id, phrase, self._bounded(points), score, step, step)
            self._next_id += 1
            return self._store(created)
        return self._store(self._merged(match, points, phrase, score, step))

    def accept(self, candidate_id: int) -> ObjectCandidate:
        """Mark a candidate verified; it can now replace the frontier goal."""
        return self._store(dataclasses.replace(self.get(candidate_id), status="accepted"))

    def reject(self, candidate_id: int) -> ObjectCandidate:
        """Remove a candidate and remember its place as failed; returns it with status ``"rejected"``."""
        rejected = dataclasses.replace(self._live.pop(candidate_id), status="rejected")
        self._failed.append(rejected)
        return rejected

    def place(self, candidate: ObjectCandidate) -> ObjectCandidate:
        """Enter or replace a candidate made elsewhere (target-centric fusion's objects, by their own ids), its
        points made read-only; the ids :meth:`add` gives are not used then."""
        points = np.array(candidate.points, dtype=np.float64)
        points.flags.writeable = False
        return self._store(dataclasses.replace(candidate, points=points))

    def discard(self, candidate_id: int) -> ObjectCandidate:
        """Remove a candidate without remembering its place as failed (its evidence no longer holds)."""
        return self._live.pop(candidate_id)

    def is_failed(self, xy: tuple[float, float]) -> bool:
        """Whether ``xy`` lies within ``failed_radius`` of a rejected candidate's centre or points."""
        return any(_cloud_distance(c.points, c.center, xy) <= self.failed_radius for c in self._failed)

    def get(self, candidate_id: int) -> ObjectCandidate:
        """A live candidate by id (``KeyError`` if unknown or rejected)."""
        return self._live[candidate_id]

    def candidates(self) -> list[ObjectCandidate]:
        """Live candidates, accepted or not, by id."""
        return sorted(self._live.values(), key=lambda c: c.candidate_id)

    def accepted(self) -> list[ObjectCandidate]:
        """Accepted candidates, by id."""
        return [c for c in self.candidates() if c.status == "accepted"]

    def rejected(self) -> list[ObjectCandidate]:
        """The failed-position memory: rejected candidates in rejection order."""
        return list(self._failed)

    def _store(self, candidate: ObjectCandidate) -> ObjectCandidate:
        self._live[candidate.candidate_id] = candidate
        return candidate

    def match(self, points: Points) -> ObjectCandidate | None:
        """The live candidate a detection with these ``points`` would join: the nearest within ``merge_radius``."""
        center = _median(points)
        best: ObjectCandidate | None = None
        best_distance = self.merge_radius
        for candidate in self.candidates():
            distance = min(
                _cloud_distance(candidate.points, candidate.center, center),
                _cloud_distance(points, center, candidate.center),
            )
            if distance <= best_distance:
                best, best_distance = candidate, distance
        return best

    def _merged(self, old: ObjectCandidate, points: Points, phrase: str, score: float, step: int) -> ObjectCandidate:
        return dataclasses.replace(
            old,
            points=self._bounded(np.concatenate([old.points, points])),
            phrase=phrase if score > old.score else old.phrase,
            score=max(score, old.score),
            first_step=min(step, old.first_step),
            last_step=max(step, old.last_step),
            frames=old.frames + (step != old.last_step),
        )

    def _bounded(self, points: Points) -> Points:
        """At most ``max_points`` of ``points`` (an evenly strided subset), as a read-only array."""
        if points.shape[0] > self.max_points:
            points = points[np.linspace(0, points.shape[0] - 1, self.max_points).round().astype(np.int64)]
        points = np.array(points, dtype=np.float64)
        points.flags.writeable = False
        return points


def _median(points: Points) -> tuple[float, float]:
    x, y = np.median(points, axis=0)
    return float(x), float(y)


def _distances(points: Points, xy: tuple[float, float]) -> NDArray[np.float64]:
    return np.hypot(points[:, 0] - xy[0], points[:, 1] - xy[1])


def _cloud_distance(points: Points, center: tuple[float, float], xy: tuple[float, float]) -> float:
    """Distance from ``xy`` to the nearer of a cloud's centre and its closest point."""
    return min(math.dist(center, xy), float(np.min(_distances(points, xy))))
