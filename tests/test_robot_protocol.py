"""The robot protocol's pure encoding: headers, arrays without copies, depth in millimetres, refusals that name
the field."""

from __future__ import annotations

import json
import math

import numpy as np
import pytest
from hypothesis import given
from hypothesis import strategies as st

from drivenav.types import CameraIntrinsics, LocalOccupancy, Pose, SimConfig
from drivenav.wire.payloads import (
    depth_from_wire,
    depth_to_wire,
    occupancy_body,
    occupancy_from,
    rgb_from_jpeg,
    rgb_to_jpeg,
)
from drivenav.wire.protocol import REPLIES, REQUESTS, Message, ProtocolError, RobotInfo, decode, encode, mismatch


def observation_message() -> Message:
    rgb = np.arange(4 * 6 * 3, dtype=np.uint8).reshape(4, 6, 3)
    depth = depth_to_wire(np.array([[0.5, 1.2345, np.nan, 5.0]] * 3, dtype=np.float32))
    return Message(
        "OBSERVATION",
        "abc-1",
        step=7,
        pose=Pose(1.0, -2.0, 0.5),
        odom=Pose(10.0, 3.0, -1.0),
        intrinsics=CameraIntrinsics(6, 4, 3.0, 3.0, 2.5, 1.5),
        gimbal=(0.1, 0.0),
        collided=True,
        arrays={"rgb": rgb, "depth": depth},
    )


def test_a_message_survives_the_wire_bit_for_bit() -> None:
    sent = observation_message()
    frames = encode(sent)
    header = json.loads(bytes(frames[0]))
    assert header["arrays"] == [
        {"name": "rgb", "dtype": "|u1", "shape": [4, 6, 3]},
        {"name": "depth", "dtype": "<u2", "shape": [3, 4]},
    ]
    got = decode([bytes(f) for f in frames], REPLIES)
    assert (got.type, got.request_id, got.step, got.collided) == ("OBSERVATION", "abc-1", 7, True)
    assert got.pose == sent.pose and got.odom == sent.odom and got.intrinsics == sent.intrinsics
    assert got.gimbal == (0.1, 0.0)
    for name in ("rgb", "depth"):
        np.testing.assert_array_equal(got.arrays[name], sent.arrays[name])


def test_arrays_are_sent_without_copies() -> None:
    rgb = np.zeros((480, 640, 3), dtype=np.uint8)
    frames = encode(Message("OBSERVATION", "x", arrays={"rgb": rgb}))
    view = frames[1]
    assert isinstance(view, memoryview)
    rgb[0, 0, 0] = 7  # the frame is a view on the array's own memory
    assert view[0] == 7


def test_depth_travels_in_millimetres_and_no_return_becomes_a_hole() -> None:
    depth = np.array([[0.5, 1.2344, 1.2346, 5.0, np.nan, 0.0, -1.0, np.inf]], dtype=np.float32)
    mm = depth_to_wire(depth)
    assert mm.dtype == np.uint16
    assert mm.tolist() == [[500, 1234, 1235, 5000, 0, 0, 0, 0]]
    back = depth_from_wire(mm)
    assert back[0, :4].tolist() == pytest.approx([0.5, 1.234, 1.235, 5.0])
    assert np.isnan(back[0, 4:]).all()  # invalid, never min_depth


@given(st.lists(st.floats(0.0625, 65.0, width=32), min_size=1, max_size=50))
def test_depth_round_trip_is_within_half_a_millimetre(values: list[float]) -> None:
    depth = np.array(values, dtype=np.float32)
    back = depth_from_wire(depth_to_wire(depth))
    assert np.all(np.abs(back - depth) <= 0.0005 + 1e-6)


def test_jpeg_rgb_round_trip_is_close() -> None:
    rgb = np.zeros((48, 64, 3), dtype=np.uint8)
    rgb[:, 32:] = (200, 50, 20)
    back = rgb_from_jpeg(rgb_to_jpeg(rgb), (48, 64))
    assert np.abs(back.astype(int) - rgb.astype(int)).mean() < 4
    with pytest.raises(ProtocolError, match="rgb_jpeg"):
        rgb_from_jpeg(rgb_to_jpeg(rgb), (64, 48))


def test_occupancy_window_travels_with_its_origin() -> None:
    cells = np.array([[-1, 0], [1, 0]], dtype=np.int8)
    local = LocalOccupancy(cells, (1.25, -3.0), 0.05)
    message = Message("OBSERVATION", "o", body=occupancy_body(local), arrays={"occupancy": cells})
    got = occupancy_from(decode([bytes(f) for f in encode(message)], REPLIES))
    assert got is not None
    assert got.origin == (1.25, -3.0) and got.resolution == 0.05
    np.testing.assert_array_equal(got.cells, cells)


def _header(**changes: object) -> bytes:
    header = json.loads(bytes(encode(Message("STEP", "r1", body={"action": 1}))[0]))
    header.update(changes)
    return json.dumps(header).encode()


@pytest.mark.parametrize(
    ("frames", "field"),
    [
        ([b"{not json"], "header"),
        ([b"[1, 2]"], "header"),
        ([_header(version=2)], "version"),
        ([_header(protocol="other")], "protocol"),
        ([_header(type="DANCE")], "type"),
        ([_header(id="")], "id"),
        ([_header(pose=[0, "a", 0])], "pose"),
        ([_header(step=-1)], "step"),
        ([_header(arrays=[{"name": "depth", "dtype": "<u2", "shape": [2, 2]}]), b"\x00" * 7], "arrays.depth"),
        ([_header(arrays=[{"name": "x", "dtype": "object", "shape": [1]}]), b"\x00"], "arrays.x.dtype"),
        ([_header(arrays=[]), b"\x00"], "arrays"),
        ([b"x" * 70_000], "header"),
    ],
)
def test_a_malformed_message_is_refused_naming_the_field(frames: list[bytes], field: str) -> None:
    with pytest.raises(ProtocolError) as error:
        decode(frames, REQUESTS)
    assert error.value.field_name == field
    assert f"field '{field}'" in str(error.value)


def test_hello_mismatch_names_the_differing_field() -> None:
    brain = RobotInfo.from_sim(SimConfig())
    assert mismatch(brain, brain) is None
    differs = mismatch(RobotInfo.from_sim(SimConfig(hfov_deg=90.0)), brain)
    assert differs is not None and (differs.field, differs.robot, differs.brain) == ("hfov_deg", 90.0, 79.0)
    assert str(differs) == "hfov_deg: the robot has 90.0, the brain is configured for 79.0 (sim.hfov_deg)"
    differs = mismatch(RobotInfo.from_sim(SimConfig(forward_step=0.2)), brain)
    assert differs is not None and differs.field == "forward_step"


def test_robot_info_round_trips_and_checks_types() -> None:
    info = RobotInfo.from_sim(SimConfig(), provides=("semantic",), lidar=True)
    assert RobotInfo.from_json(json.loads(json.dumps(info.to_json()))) == info
    body = info.to_json()
    body["width"] = "640"
    with pytest.raises(ProtocolError, match=r"body\.width"):
        RobotInfo.from_json(body)
    body = info.to_json()
    del body["hfov_deg"]
    with pytest.raises(ProtocolError, match=r"body\.hfov_deg"):
        RobotInfo.from_json(body)
    assert math.isclose(RobotInfo.from_json(info.to_json()).hfov_deg, 79.0)
