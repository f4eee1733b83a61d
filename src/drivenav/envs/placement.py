"""Object placement with room-type priors (stub: the signature is the contract; implementation pending)."""

from __future__ import annotations

import numpy as np

from drivenav.envs.scene import ObjectInstance, Scene


def place_objects(scene: Scene, rng: np.random.Generator, density: float = 1.0) -> list[ObjectInstance]:
    """Place objects in ``scene`` (whose ``objects`` are ignored) using its rooms' types as priors.

    Scenes without rooms use a generic indoor prior. Returned objects lie in free space, do not overlap walls
    or each other, and keep the navigable space connected.
    """
    raise NotImplementedError
