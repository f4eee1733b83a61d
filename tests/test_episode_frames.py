"""The 2-D world frame against Habitat's y-up frame, and pose composition."""

from __future__ import annotations

import math

import pytest
from hypothesis import given
from hypothesis import strategies as st

from drivenav.episode import habitat_to_world, quaternion_to_yaw, world_to_habitat, yaw_to_quaternion
from drivenav.grid import wrap_angle
from drivenav.types import Pose

angles = st.floats(-math.pi, math.pi, allow_nan=False)


def test_north_is_minus_z() -> None:
    assert world_to_habitat(1.0, 2.0) == (1.0, 0.0, -2.0)
    # Facing north (yaw 90 deg) is Habitat's identity rotation: the agent faces -z.
    assert yaw_to_quaternion(math.pi / 2) == pytest.approx((0.0, 0.0, 0.0, 1.0))


def test_facing_east_is_minus_ninety_about_y() -> None:
    q = yaw_to_quaternion(0.0)
    # Rotating Habitat's forward (0, 0, -1) by -90 deg about +y gives +x.
    phi = 2.0 * math.atan2(q[1], q[3])
    forward = (-math.sin(phi), -math.cos(phi))  # (x, z)
    assert forward == pytest.approx((1.0, 0.0), abs=1e-12)


@given(angles)
def test_yaw_round_trip(yaw: float) -> None:
    assert wrap_angle(quaternion_to_yaw(yaw_to_quaternion(yaw)) - yaw) == pytest.approx(0.0, abs=1e-9)


@given(st.floats(-100, 100), st.floats(-100, 100))
def test_position_round_trip(x: float, y: float) -> None:
    assert habitat_to_world(world_to_habitat(x, y)) == pytest.approx((x, y))


@given(st.floats(-10, 10), st.floats(-10, 10), angles, st.floats(-10, 10), st.floats(-10, 10), angles)
def test_pose_inverse_composes_to_identity(x: float, y: float, t: float, a: float, b: float, c: float) -> None:
    pose, local = Pose(x, y, t), Pose(a, b, c)
    back = pose.inverse().compose(pose.compose(local))
    assert (back.x, back.y, wrap_angle(back.yaw - local.yaw)) == pytest.approx((a, b, 0.0), abs=1e-9)


def test_episode_frame_example() -> None:
    start = Pose(2.0, 3.0, math.pi / 2)  # facing north
    world = Pose(2.0, 4.0, math.pi / 2)  # one metre north
    local = start.inverse().compose(world)
    assert (local.x, local.y, local.yaw) == pytest.approx((1.0, 0.0, 0.0))
