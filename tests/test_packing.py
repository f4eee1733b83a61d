"""Packed images (drivenav.packing): pixel-exact round trips of every dtype and shape, flat frames a few percent."""

from __future__ import annotations

import numpy as np
from hypothesis import given, settings
from hypothesis import strategies as st

from drivenav.packing import PackedImage


def test_instance_image_of_flat_regions_packs_to_a_few_percent() -> None:
    semantic = np.full((480, 640), -1, np.int32)
    semantic[100:300, 50:200] = 7
    semantic[250:480, 400:640] = 12
    packed = PackedImage.pack(semantic)
    assert packed.nbytes < semantic.nbytes / 50
    back = packed.unpack()
    assert back.dtype == np.int32 and np.array_equal(back, semantic) and not back.flags.writeable


def test_noise_reads_back_exactly() -> None:
    noise = np.random.default_rng(3).integers(0, 256, (30, 40, 3), dtype=np.uint8)
    packed = PackedImage.pack(noise)
    assert np.array_equal(packed.unpack(), noise) and not np.shares_memory(packed.unpack(), noise)


@st.composite
def images(draw: st.DrawFn) -> np.ndarray:
    """Images with runs: a few values, each repeated a random number of times, in row-major order."""
    dtype = draw(st.sampled_from([np.uint8, np.int32, np.float32, np.int64, np.bool_]))
    shape = draw(st.lists(st.integers(0, 12), min_size=1, max_size=3).map(tuple))
    seed = draw(st.integers(0, 2**32 - 1))
    rng = np.random.default_rng(seed)
    size = int(np.prod(shape))
    values = rng.integers(-3, 4, size=max(size, 1)).astype(dtype)
    lengths = rng.integers(1, draw(st.integers(1, 40)) + 1, size=max(size, 1))
    return np.repeat(values, lengths)[:size].reshape(shape)


@settings(max_examples=200, deadline=None)
@given(images())
def test_unpack_gives_back_the_image(image: np.ndarray) -> None:
    packed = PackedImage.pack(image)
    back = packed.unpack()
    assert back.dtype == image.dtype and back.shape == image.shape
    assert np.array_equal(back, image) and not back.flags.writeable
