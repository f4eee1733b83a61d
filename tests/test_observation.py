"""Observation with a deferred RGB image: rendered on first read, once; replace, copies and pickles carry pixels."""

from __future__ import annotations

import copy
import dataclasses
import pickle

import numpy as np
import pytest

from drivenav.types import CameraIntrinsics, Observation, Pose

INTR = CameraIntrinsics(4, 3, 2.0, 2.0, 2.0, 1.5)


class CountingRender:
    """A picklable RGB source that counts its calls."""

    def __init__(self) -> None:
        self.calls = 0

    def __call__(self) -> np.ndarray:
        self.calls += 1
        return np.full((3, 4, 3), 7, np.uint8)


def deferred(render: CountingRender) -> Observation:
    depth = np.ones((3, 4), np.float32)
    return Observation.deferred(render, depth, None, Pose(1.0, 2.0, 0.5), INTR, 3, False)


def test_fields_are_set_and_rgb_waits_for_its_first_read() -> None:
    render = CountingRender()
    obs = deferred(render)
    assert (obs.step, obs.collided, obs.semantic, obs.occupancy) == (3, False, None, None)
    assert obs.pose == Pose(1.0, 2.0, 0.5) and obs.intrinsics == INTR
    assert render.calls == 0
    first = obs.rgb
    assert render.calls == 1 and obs.rgb is first and int(first[0, 0, 0]) == 7


@pytest.mark.parametrize(
    "duplicate",
    [
        lambda o: dataclasses.replace(o, step=4),
        copy.copy,
        copy.deepcopy,
        lambda o: pickle.loads(pickle.dumps(o)),
    ],
)
def test_copies_carry_the_rendered_pixels(duplicate: object) -> None:
    render = CountingRender()
    obs = deferred(render)
    other = duplicate(obs)  # type: ignore[operator]
    assert render.calls == 1
    np.testing.assert_array_equal(other.rgb, obs.rgb)
    assert "_render_rgb" not in vars(other) and render.calls == 1


def test_unknown_attributes_still_raise() -> None:
    obs = deferred(CountingRender())
    with pytest.raises(AttributeError, match="no attribute 'colour'"):
        obs.colour  # type: ignore[attr-defined]  # noqa: B018
    with pytest.raises(dataclasses.FrozenInstanceError):
        obs.step = 5  # type: ignore[misc]


def test_an_eager_observation_is_unchanged() -> None:
    rgb = np.zeros((3, 4, 3), np.uint8)
    obs = Observation(rgb, np.ones((3, 4), np.float32), None, Pose(0.0, 0.0, 0.0), INTR, 0, False)
    assert obs.rgb is rgb and pickle.loads(pickle.dumps(obs)).rgb.shape == (3, 4, 3)
