"""Images held compressed or unrendered: the representative views an episode keeps (Sec. IV-A c) at a few percent
of their memory, read back pixel for pixel.

An agent keeps a view of every live and recently retired direction: about 50 frames, 100 MB as arrays, on a large
floor plan. zlib at level 1 packs a 640 x 480 frame of the embedded world 30-50 times (RGB) and 130-150 times
(instance ids) in about 2 ms each, and unpacks it in 1-1.5 ms; a camera image with noise still shrinks, less. A
simulated world's RGB image that nobody has read yet (:meth:`drivenav.types.Observation.deferred`) is kept as
the call that renders it (:class:`DeferredImage`): no pixels at all, and no rendering unless a reader asks.
"""

from __future__ import annotations

import zlib
from collections.abc import Callable
from dataclasses import dataclass
from typing import Any

import numpy as np
from numpy.typing import NDArray

LEVEL = 1  # zlib's fastest level: frames of flat surfaces gain little from more effort


@dataclass(frozen=True)
class PackedImage:
    """An image's bytes, zlib-compressed, with its shape and dtype."""

    data: bytes
    shape: tuple[int, ...]
    dtype: str

    @classmethod
    def pack(cls, image: NDArray[Any]) -> PackedImage:
        array = np.ascontiguousarray(image)
        return cls(zlib.compress(array.tobytes(), LEVEL), array.shape, array.dtype.str)

    @property
    def nbytes(self) -> int:
        return len(self.data)

    def unpack(self) -> NDArray[Any]:
        """The image (a new, read-only array)."""
        return np.frombuffer(zlib.decompress(self.data), dtype=np.dtype(self.dtype)).reshape(self.shape)


@dataclass(frozen=True)
class DeferredImage:
    """An image kept as the call that renders it (a simulated world's frame: its renderer and pose)."""

    render: Callable[[], NDArray[Any]]

    def unpack(self) -> NDArray[Any]:
        """The image, rendered now (a new, read-only array)."""
        image = np.asarray(self.render())
        image.flags.writeable = False
        return image
