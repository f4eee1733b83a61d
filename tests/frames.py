"""A frame as a model sees it: an :class:`~drivenav.types.Observation` built around test images."""

from __future__ import annotations

import numpy as np
from numpy.typing import NDArray

from drivenav.types import CameraIntrinsics, Observation, Pose


def observation_of(rgb: NDArray[np.uint8], semantic: NDArray[np.int32] | None = None) -> Observation:
    """``rgb`` (and ``semantic``) with a flat 2 m depth image, at the origin, step 0."""
    height, width = rgb.shape[:2]
    return Observation(
        rgb=rgb,
        depth=np.full((height, width), 2.0, np.float32),
        semantic=semantic,
        pose=Pose(0.0, 0.0, 0.0),
        intrinsics=CameraIntrinsics.from_hfov(width, height, 79.0),
        step=0,
        collided=False,
    )
