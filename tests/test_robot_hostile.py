"""The robot server under hostile messages: every malformed header or frame gets an ERROR reply naming what was
wrong, checked before anything is allocated (sizes, integer digits, nesting, array shapes against the frame's
bytes), a fault in the robot's own parts is an ERROR too, and the server keeps serving: a correct HELLO is
answered after each case. Endpoints are checked before any socket binds."""

from __future__ import annotations

import contextlib
import json
from typing import Any

import pytest
import zmq
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from drivenav.brain.bench import StillCamera
from drivenav.errors import InputError
from drivenav.robot.parts import HeldStill, SensorFrame
from drivenav.robot.server import RobotServer, RobotSession, served
from drivenav.types import SimConfig
from drivenav.wire.protocol import REQUESTS, Message, ProtocolError, RobotInfo, decode
from drivenav.wire.security import check_bind, check_endpoint
from test_robot_bridge import RawClient, hello

SIM = SimConfig(width=64, height=48)


def _session() -> RobotSession:
    return RobotSession(RobotInfo.from_sim(SIM), StillCamera(SIM), HeldStill())


def _header(kind: str = "PING", **fields: Any) -> dict[str, Any]:
    return {"protocol": "drivenav-robot", "version": 1, "type": kind, "id": "x1", **fields}


def _frames(header: dict[str, Any] | str, *arrays: bytes) -> list[bytes]:
    text = header if isinstance(header, str) else json.dumps(header)
    return [text.encode(), *arrays]


def _hello_body(**changes: Any) -> dict[str, Any]:
    return {**RobotInfo.from_sim(SIM).to_json(), **changes}


HOSTILE = {
    "provides is a number": (_frames(_header("HELLO", body=_hello_body(provides=5))), "body.provides"),
    "lidar is a string": (_frames(_header("HELLO", body=_hello_body(lidar="yes"))), "body.lidar"),
    "shape 2^32 x 2^32, empty frame": (
        _frames(_header(arrays=[{"name": "a", "dtype": "|u1", "shape": [2**32, 2**32]}]), b""),
        "arrays.a.shape",
    ),
    "shape 2^70": (_frames(_header(arrays=[{"name": "a", "dtype": "<f8", "shape": [2**70]}]), b""), "16 digits"),
    "shape 2^40 x 2^40": (
        _frames(_header(arrays=[{"name": "a", "dtype": "<f8", "shape": [2**40, 2**40]}]), b""),
        "arrays.a.shape",
    ),
    "boolean dimension": (_frames(_header(arrays=[{"name": "a", "dtype": "|u1", "shape": [True]}]), b"x"), "shape"),
    "a 5000-digit integer": (_frames('{"protocol": "drivenav-robot", "step": ' + "9" * 5000 + "}"), "16 digits"),
    "JSON nested 30,000 deep": (_frames('{"body": ' + "[" * 30_000 + "]" * 30_000 + "}"), "nested"),
    "JSON nested 100 deep": (_frames(_header(body={"a": json.loads("[" * 100 + "]" * 100)})), "nested"),
    "not UTF-8": ([b"\xff\xfe{}"], "UTF-8"),
}


@pytest.mark.parametrize("case", list(HOSTILE), ids=list(HOSTILE))
def test_a_hostile_message_is_refused_before_anything_is_built(case: str) -> None:
    frames, expected = HOSTILE[case]
    with pytest.raises(ProtocolError, match=expected.replace(".", r"\.")):
        message = decode(frames, REQUESTS)
        RobotInfo.from_json(message.body)  # a HELLO's body, as the session reads it


@pytest.fixture(scope="module")
def server() -> Any:
    with served(_session()) as endpoint:
        client = RawClient(endpoint)
        yield client
        client.close()


@pytest.mark.parametrize("case", list(HOSTILE), ids=list(HOSTILE))
def test_the_server_answers_each_hostile_message_and_keeps_serving(server: RawClient, case: str) -> None:
    frames, _ = HOSTILE[case]
    server.send(frames)
    reply = server.reply()
    assert reply is not None and reply.type == "ERROR" and reply.body["error"], case
    assert hello(server).type == "WELCOME"  # type: ignore[union-attr]


class _BrokenCamera(StillCamera):
    def read(self) -> SensorFrame:
        raise RuntimeError("the camera driver crashed")


def test_a_fault_of_the_robot_is_an_error_reply_and_the_server_keeps_serving() -> None:
    session = RobotSession(RobotInfo.from_sim(SIM), _BrokenCamera(SIM), HeldStill())
    with served(session) as endpoint:
        client = RawClient(endpoint)
        try:
            assert hello(client).type == "WELCOME"  # type: ignore[union-attr]
            client.request(Message("RESET", "r1", body={"episode_id": "e", "target": "chair"}))
            reply = client.reply()
            assert reply is not None and reply.type == "ERROR"
            assert reply.body["error"] == "RESET failed on the robot: RuntimeError: the camera driver crashed"
            client.request(Message("PING", "p1"))
            assert client.reply().type == "PONG"  # type: ignore[union-attr]
        finally:
            client.close()


_KEYS = ["protocol", "version", "type", "id", "step", "sent", "stamp", "pose", "odom", "intrinsics", "gimbal"]
_KEYS += ["collided", "status", "body", "arrays"]
_JSON = st.recursive(
    st.none() | st.booleans() | st.integers() | st.floats(allow_nan=False) | st.text(max_size=8),
    lambda inner: st.lists(inner, max_size=4) | st.dictionaries(st.text(max_size=6), inner, max_size=4),
    max_leaves=12,
)
_ARRAY = st.fixed_dictionaries(
    {"name": st.text(max_size=4), "dtype": st.sampled_from(["|u1", "<f4", "<u2", "<i4", "object", 3]), "shape": _JSON}
)
_HEADERS = st.fixed_dictionaries(
    {"protocol": st.just("drivenav-robot"), "version": st.just(1), "type": st.sampled_from([*REQUESTS, "X"])},
    optional={key: _JSON for key in _KEYS[3:]} | {"arrays": st.lists(_ARRAY, max_size=3)},
)


@settings(max_examples=300, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(header=_HEADERS, frames=st.lists(st.binary(max_size=64), max_size=3))
def test_decoding_any_header_and_frames_gives_a_message_or_a_protocol_error(
    header: dict[str, Any], frames: list[bytes]
) -> None:
    try:
        message = decode([json.dumps(header).encode(), *frames], REQUESTS)
    except ProtocolError:
        return
    assert message.type in REQUESTS
    if message.type == "HELLO":
        with contextlib.suppress(ProtocolError):
            RobotInfo.from_json(message.body)


@settings(max_examples=40, deadline=None, suppress_health_check=[HealthCheck.function_scoped_fixture])
@given(header=_HEADERS, frames=st.lists(st.binary(max_size=64), max_size=3))
def test_the_server_answers_any_message_and_keeps_serving(
    server: RawClient, header: dict[str, Any], frames: list[bytes]
) -> None:
    server.send([json.dumps(header).encode(), *frames])
    reply = server.reply()
    assert reply is not None
    server.request(Message("PING", "alive"))
    assert server.reply().type == "PONG"  # type: ignore[union-attr]


@pytest.mark.parametrize(
    "address", ["tcp://127.0.0.1:99999", "tcp://127.0.0.1:0", "tcp://127.0.0.1", "not-an-address", "http://x:80"]
)
def test_a_bad_endpoint_is_refused_before_any_socket(address: str) -> None:
    with pytest.raises(InputError, match="--bind"):
        check_bind(address, None)
    with pytest.raises(InputError, match="--robot"):
        check_endpoint(address, "--robot")


def test_a_port_in_use_is_one_line_naming_bind() -> None:
    with served(_session()) as endpoint, pytest.raises(InputError, match=r"--bind.*free to serve on"):
        RobotServer(_session(), endpoint)
    assert zmq  # the second server released its socket and context (no hang at exit)
