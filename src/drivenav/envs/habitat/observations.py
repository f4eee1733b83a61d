"""habitat-lab's observations in drivenav's conventions (:class:`~drivenav.types.Observation`).

* Depth: habitat-lab's depth sensor returns (H, W, 1) float32 ``(clip(d, min, max) - min) / (max - min)``; a
  missing return (raw 0) reads 0 like anything nearer than ``min_depth``. Both come back as ``min_depth``: a clip
  value, which the mapper treats as "nothing measured" (no obstacle, nothing explored). The inverse is computed
  in float64 so that 0 and 1 map back to exactly ``min_depth`` and ``max_depth``.
* Pose: GPS is ``(forward, right)`` from the episode's start position along its start heading, compass the
  heading change counter-clockwise; drivenav's episode frame has +y to the left, so the pose is
  ``(gps[0], -gps[1], compass)``.
"""

from __future__ import annotations

from collections.abc import Mapping

import numpy as np
from numpy.typing import NDArray

from drivenav.grid import wrap_angle
from drivenav.types import Observation, Pose, SimConfig

RGB, DEPTH, SEMANTIC_UUID, GPS, COMPASS = "rgb", "depth", "semantic", "gps", "compass"


def depth_in_metres(depth: NDArray[np.float32], sim: SimConfig, normalized: bool = True) -> NDArray[np.float32]:
    """(H, W) float32 metres in ``[min_depth, max_depth]`` from habitat-lab's (H, W, 1) depth observation."""
    values = np.asarray(depth, dtype=np.float64).reshape(depth.shape[0], depth.shape[1])
    if normalized:
        values = sim.min_depth + values * (sim.max_depth - sim.min_depth)
    return np.clip(values, sim.min_depth, sim.max_depth).astype(np.float32)


def pose_from_gps_compass(gps: NDArray[np.float32], compass: NDArray[np.float32]) -> Pose:
    """The pose in drivenav's episode frame from habitat-lab's episodic GPS and compass."""
    return Pose(float(gps[0]), -float(gps[1]), wrap_angle(float(np.asarray(compass).reshape(-1)[0])))


def to_observation(
    observations: Mapping[str, NDArray[np.generic]], sim: SimConfig, step: int, collided: bool, normalized: bool = True
) -> Observation:
    """One habitat-lab observation (``rgb``, ``depth``, ``gps``, ``compass``, ``semantic`` if present) as
    drivenav's."""
    rgb = np.ascontiguousarray(np.asarray(observations[RGB])[:, :, :3], dtype=np.uint8)
    depth = depth_in_metres(np.asarray(observations[DEPTH], dtype=np.float32), sim, normalized)
    pose = pose_from_gps_compass(np.asarray(observations[GPS]), np.asarray(observations[COMPASS]))
    semantic = None
    if SEMANTIC_UUID in observations:
        ids = np.asarray(observations[SEMANTIC_UUID])
        semantic = np.ascontiguousarray(ids.reshape(ids.shape[0], ids.shape[1]), dtype=np.int32)
    return Observation(rgb, depth, semantic, pose, sim.intrinsics, step, collided)
