"""The brain-robot wire protocol (version 1): pure encoding and decoding, no sockets (docs/robot.md); what the bodies
and arrays carry (a RESET's episode, depth, JPEG, LiDAR occupancy) is :mod:`drivenav.wire.payloads`'.

A message is a ZMQ multipart message: one JSON header frame (UTF-8), then one frame per array, each the array's
raw little-endian bytes (sent without copies; never pickle). The header names every array with its dtype and
shape, so a receiver checks each frame's size before it builds a view on it.

Requests (brain -> robot) and their replies:

========== ================================================ =================================================
request    body                                             reply
========== ================================================ =================================================
HELLO      the brain's sensor and body settings (RobotInfo) WELCOME with the robot's RobotInfo, or ERROR naming
                                                            the first differing field
RESET      ``episode_id``, ``target``                       OBSERVATION (the pose at reset is the episode origin)
OBSERVE    --                                               OBSERVATION
STEP       ``action`` (0-3, Habitat's numbering)            OBSERVATION after the motion; a STEP whose request id
                                                            was seen is answered again, never executed twice
STOP       --                                               STOPPED (the robot halts at once)
BYE        --                                               GOODBYE with ``measures`` (a simulated robot's Habitat
                                                            metrics of the episode; null on a real robot)
PING       --                                               PONG (a heartbeat: keeps the robot's deadman fed)
========== ================================================ =================================================

Every reply repeats the request id and names its server (``server``: a random id each server draws when it starts,
so that a client tells a restarted server from the one it sent its request to). A malformed, oversized, unknown or
out-of-order request gets an ERROR reply whose ``error`` names what was wrong. An OBSERVATION carries ``rgb`` (uint8
HxWx3, or ``rgb_jpeg`` bytes), ``depth`` (uint16 millimetres, 0 = no return) and, where the robot has them,
``occupancy`` (int8 LiDAR occupancy window, :class:`~drivenav.types.LocalOccupancy`) and ``semantic`` (int32
instance ids, a simulated robot only).
"""

from __future__ import annotations

import json
import math
from collections.abc import Mapping, Sequence
from dataclasses import asdict, dataclass, field, fields
from typing import Any

import numpy as np
from numpy.typing import NDArray

from drivenav.jsonstream import JsonObject
from drivenav.types import CameraIntrinsics, Pose, SimConfig

PROTOCOL = "drivenav-robot"
VERSION = 1
REQUESTS = ("HELLO", "RESET", "OBSERVE", "STEP", "STOP", "BYE", "PING")
REPLIES = ("WELCOME", "OBSERVATION", "STOPPED", "GOODBYE", "PONG", "ERROR")
MAX_HEADER_BYTES = 65_536
MAX_HEADER_DEPTH = 16  # JSON nesting: a header is a flat object whose body holds at most a few levels
MAX_INTEGER_DIGITS = 16  # an integer in a header is a count, an id or a size: never more than 16 digits
MAX_SERVER_ID_CHARS = 64  # a reply's ``server``: the replying server process's random id
MAX_ARRAY_BYTES = 64 * 2**20  # one array frame (the server's per-frame limit, ServerConfig.max_message_bytes)
DEPTH_SCALE = 1000.0  # depth on the wire: uint16 millimetres
_DTYPES = frozenset({"|u1", "|i1", "<u2", "<i2", "<i4", "<u4", "<f4", "<f8"})

JSON = Any  # a value json.loads returns


class ProtocolError(ValueError):
    """A message that breaks the protocol; ``str(error)`` names the field and what was expected."""

    def __init__(self, field_name: str, expected: str, got: object = None) -> None:
        self.field_name = field_name
        text = f"field '{field_name}': expected {expected}"
        if got is not None:
            shown = repr(got)
            text += f", got {shown if len(shown) <= 80 else shown[:77] + '...'}"
        super().__init__(text)


@dataclass(frozen=True)
class RobotInfo:
    """A robot's sensor and body settings (HELLO / WELCOME): what the brain's configuration must match.

    ``provides`` lists the ground truth the robot can give (``semantic`` for a simulated robot, nothing for a real
    one); ``lidar`` says whether observations carry LiDAR occupancy; ``rgb_encoding`` is ``raw`` or ``jpeg``.
    """

    width: int
    height: int
    hfov_deg: float
    min_depth: float
    max_depth: float
    camera_height: float
    forward_step: float
    turn_angle_deg: float
    provides: tuple[str, ...] = ()
    lidar: bool = False
    rgb_encoding: str = "raw"

    @staticmethod
    def from_sim(sim: SimConfig, **extra: Any) -> RobotInfo:
        """The settings a brain configured with ``sim`` expects of its robot."""
        return RobotInfo(
            sim.width,
            sim.height,
            sim.hfov_deg,
            sim.min_depth,
            sim.max_depth,
            sim.camera_height,
            sim.forward_step,
            sim.turn_angle_deg,
            **extra,
        )

    def to_json(self) -> dict[str, JSON]:
        return {**asdict(self), "provides": list(self.provides)}

    @staticmethod
    def from_json(body: Mapping[str, JSON]) -> RobotInfo:
        values: JsonObject = {}
        for item in fields(RobotInfo):
            if item.name not in body:
                if item.name in _INFO_OPTIONAL:
                    continue
                raise ProtocolError(f"body.{item.name}", "a value")
            values[item.name] = body[item.name]
        _check_info_types(values)
        values["provides"] = tuple(values.get("provides", ()))
        return RobotInfo(**values)


_INFO_OPTIONAL = frozenset({"provides", "lidar", "rgb_encoding"})
MATCHED_FIELDS = ("width", "height", "hfov_deg", "min_depth", "max_depth", "forward_step", "turn_angle_deg")


def _check_info_types(values: Mapping[str, Any]) -> None:
    for name in ("width", "height"):
        if not (isinstance(values[name], int) and not isinstance(values[name], bool) and values[name] > 0):
            raise ProtocolError(f"body.{name}", "a positive integer", values[name])
    for name in ("hfov_deg", "min_depth", "max_depth", "camera_height", "forward_step", "turn_angle_deg"):
        value = values[name]
        if isinstance(value, bool) or not isinstance(value, (int, float)) or not math.isfinite(value):
            raise ProtocolError(f"body.{name}", "a finite number", value)
    if values.get("rgb_encoding", "raw") not in ("raw", "jpeg"):
        raise ProtocolError("body.rgb_encoding", "raw or jpeg", values.get("rgb_encoding"))
    provides = values.get("provides", [])
    if not isinstance(provides, list) or not all(isinstance(p, str) for p in provides):
        raise ProtocolError("body.provides", "a list of strings (the ground truth the robot gives)", provides)
    if not isinstance(values.get("lidar", False), bool):
        raise ProtocolError("body.lidar", "true or false", values.get("lidar"))


@dataclass(frozen=True)
class Mismatch:
    """A setting in which the robot differs from the brain's configuration (``sim.<field>``)."""

    field: str
    robot: float
    brain: float

    def __str__(self) -> str:
        return f"{self.field}: the robot has {self.robot}, the brain is configured for {self.brain} (sim.{self.field})"


def mismatch(robot: RobotInfo, brain: RobotInfo) -> Mismatch | None:
    """The first setting in which a robot differs from what the brain is configured for (None when none).

    Sizes, field of view, depth range and step lengths must match (the agent's maps and turn counting rely on them),
    and so must the camera height (the brain's mapper takes it from ``sim.camera_height``: set it to the robot's).
    """
    for name in (*MATCHED_FIELDS, "camera_height"):
        mine, theirs = getattr(brain, name), getattr(robot, name)
        if not math.isclose(float(mine), float(theirs), rel_tol=1e-6, abs_tol=1e-9):
            return Mismatch(name, theirs, mine)
    return None


@dataclass(frozen=True)
class Message:
    """One protocol message: the header's fields and the named arrays.

    ``pose`` is in the episode frame and ``odom`` in the robot's own odometry frame (both ``(x, y, yaw)``, and the
    height ``z`` where the robot's odometry gives one: ``[x, y, yaw, z]`` on the wire, ``z`` written only when not 0);
    ``stamp`` is the sensor time of an observation, ``sent`` the sender's clock when it was encoded; ``server`` is the
    replying server's id (a reply's; empty in a request, and in a reply of a server that names none).
    """

    type: str
    request_id: str
    step: int = 0
    sent: float = 0.0
    stamp: float = 0.0
    pose: Pose | None = None
    odom: Pose | None = None
    intrinsics: CameraIntrinsics | None = None
    gimbal: tuple[float, float] = (0.0, 0.0)
    collided: bool = False
    status: str = "ok"
    body: Mapping[str, JSON] = field(default_factory=dict)
    arrays: Mapping[str, NDArray[Any]] = field(default_factory=dict)
    server: str = ""


def encode(message: Message, protocol: str = PROTOCOL) -> list[bytes | memoryview]:
    """The frames of ``message``: its JSON header, then each array's bytes (C order, little-endian, no copy when
    the array already is). ``protocol`` names the dialect in the header (the robot's, or another protocol that
    reuses this framing: the served grounder's)."""
    specs, buffers = [], []
    for name, array in message.arrays.items():
        wire = _wire_array(array)
        specs.append({"name": name, "dtype": wire.dtype.str, "shape": list(wire.shape)})
        buffers.append(wire.data.cast("B") if wire.size else b"")
    header = {
        "protocol": protocol,
        "version": VERSION,
        "type": message.type,
        "id": message.request_id,
        "step": message.step,
        "sent": message.sent,
        "stamp": message.stamp,
        "pose": _pose_json(message.pose),
        "odom": _pose_json(message.odom),
        "intrinsics": None if message.intrinsics is None else asdict(message.intrinsics),
        "gimbal": list(message.gimbal),
        "collided": message.collided,
        "status": message.status,
        "body": dict(message.body),
        "arrays": specs,
    }
    if message.server:
        header["server"] = message.server
    return [json.dumps(header, allow_nan=False).encode(), *buffers]


def _wire_array(array: NDArray[Any]) -> NDArray[Any]:
    wire = np.ascontiguousarray(array)
    if wire.dtype.byteorder == ">" or (wire.dtype.byteorder == "=" and not _little_endian()):
        wire = wire.astype(wire.dtype.newbyteorder("<"))
    if wire.dtype.str not in _DTYPES:
        raise ProtocolError("arrays.dtype", f"one of {sorted(_DTYPES)}", wire.dtype.str)
    return wire


def _little_endian() -> bool:
    return bool(np.little_endian)


def _pose_json(pose: Pose | None) -> list[float] | None:
    """``[x, y, yaw]``, with the height after them only where it is not 0 (a planar pose keeps its bytes)."""
    if pose is None:
        return None
    return [pose.x, pose.y, pose.yaw, pose.z] if pose.z else [pose.x, pose.y, pose.yaw]


def decode(frames: Sequence[bytes | memoryview], kinds: Sequence[str], protocol: str = PROTOCOL) -> Message:
    """The message in ``frames``, one of the types ``kinds`` (:data:`REQUESTS` or :data:`REPLIES`, or another
    dialect's) of the protocol ``protocol``; a :class:`ProtocolError` names the first thing wrong."""
    if not frames:
        raise ProtocolError("header", "a JSON header frame")
    header = _header(frames[0], protocol)
    kind = header.get("type")
    if kind not in kinds:
        raise ProtocolError("type", f"one of {', '.join(kinds)}", kind)
    arrays = _arrays(header.get("arrays", []), frames[1:])
    return Message(
        type=str(kind),
        request_id=_text(header, "id"),
        step=_integer(header, "step"),
        sent=_number(header, "sent"),
        stamp=_number(header, "stamp"),
        pose=_pose(header, "pose"),
        odom=_pose(header, "odom"),
        intrinsics=_intrinsics(header.get("intrinsics")),
        gimbal=_gimbal(header.get("gimbal", [0.0, 0.0])),
        collided=bool(header.get("collided", False)),
        status=str(header.get("status", "ok")),
        body=_body(header.get("body", {})),
        arrays=arrays,
        server=_server_id(header.get("server", "")),
    )


def _server_id(value: JSON) -> str:
    if not isinstance(value, str) or len(value) > MAX_SERVER_ID_CHARS:
        raise ProtocolError("server", f"a server id of at most {MAX_SERVER_ID_CHARS} characters", value)
    return value


def _header(frame: bytes | memoryview, protocol: str) -> dict[str, JSON]:
    """The header frame as a JSON object, checked before anything is built from it: its size, then (while parsing)
    each integer's digits, then its nesting depth."""
    if len(frame) > MAX_HEADER_BYTES:
        raise ProtocolError("header", f"at most {MAX_HEADER_BYTES} bytes", len(frame))
    try:
        header = json.loads(bytes(frame).decode("utf-8"), parse_int=_bounded_int)
    except ProtocolError:
        raise  # an integer with too many digits
    except RecursionError:
        raise ProtocolError("header", f"JSON nested at most {MAX_HEADER_DEPTH} deep", "deeper") from None
    except (UnicodeDecodeError, ValueError) as error:  # json.JSONDecodeError is a ValueError
        raise ProtocolError("header", "a UTF-8 JSON object", str(error)) from None
    if not isinstance(header, dict):
        raise ProtocolError("header", "a JSON object", type(header).__name__)
    if _depth(header) > MAX_HEADER_DEPTH:
        raise ProtocolError("header", f"JSON nested at most {MAX_HEADER_DEPTH} deep", "deeper")
    if header.get("protocol") != protocol:
        raise ProtocolError("protocol", repr(protocol), header.get("protocol"))
    if header.get("version") != VERSION:
        raise ProtocolError("version", f"protocol version {VERSION}", header.get("version"))
    return header


def _bounded_int(digits: str) -> int:
    """An integer of the header, refused before conversion when it has more than :data:`MAX_INTEGER_DIGITS`."""
    if len(digits.lstrip("-")) > MAX_INTEGER_DIGITS:
        raise ProtocolError("header", f"integers of at most {MAX_INTEGER_DIGITS} digits", f"{len(digits)} digits")
    return int(digits)


def _depth(value: JSON) -> int:
    """The nesting depth of a parsed JSON value (an object or a list counts one level), without recursion."""
    deepest, stack = 0, [(value, 1)]
    while stack:
        item, level = stack.pop()
        children = item.values() if isinstance(item, dict) else item if isinstance(item, list) else None
        if children is None:
            continue
        deepest = max(deepest, level)
        if level <= MAX_HEADER_DEPTH:
            stack.extend((child, level + 1) for child in children)
    return deepest


def _text(header: Mapping[str, JSON], name: str) -> str:
    value = header.get(name)
    if not isinstance(value, str) or not value or len(value) > 128:
        raise ProtocolError(name, "a non-empty string of at most 128 characters", value)
    return value


def _integer(header: Mapping[str, JSON], name: str) -> int:
    value = header.get(name, 0)
    if isinstance(value, bool) or not isinstance(value, int) or value < 0:
        raise ProtocolError(name, "an integer >= 0", value)
    return value


def _number(header: Mapping[str, JSON], name: str) -> float:
    value = header.get(name, 0.0)
    if isinstance(value, bool) or not isinstance(value, (int, float)) or not math.isfinite(value):
        raise ProtocolError(name, "a finite number", value)
    return float(value)


def finite_list(value: JSON, name: str, length: int) -> list[float]:
    ok = isinstance(value, list) and len(value) == length
    ok = ok and all(isinstance(v, (int, float)) and not isinstance(v, bool) and math.isfinite(v) for v in value)
    if not ok:
        raise ProtocolError(name, f"a list of {length} finite numbers", value)
    return [float(v) for v in value]


def _pose(header: Mapping[str, JSON], name: str) -> Pose | None:
    """A pose of 3 numbers ``[x, y, yaw]`` (height 0) or 4 ``[x, y, yaw, z]``."""
    value = header.get(name)
    if value is None:
        return None
    with_height = isinstance(value, list) and len(value) == 4
    return Pose(*finite_list(value, name, 4 if with_height else 3))


def _gimbal(value: JSON) -> tuple[float, float]:
    yaw, pitch = finite_list(value, "gimbal", 2)
    return yaw, pitch


def _intrinsics(value: JSON) -> CameraIntrinsics | None:
    if value is None:
        return None
    names = ("width", "height", "fx", "fy", "cx", "cy")
    if not isinstance(value, dict) or set(value) != set(names):
        raise ProtocolError("intrinsics", f"an object with {', '.join(names)}", value)
    width, height = value["width"], value["height"]
    if not all(isinstance(v, int) and not isinstance(v, bool) and v > 0 for v in (width, height)):
        raise ProtocolError("intrinsics.width/height", "positive integers", (width, height))
    fx, fy, cx, cy = finite_list([value[n] for n in names[2:]], "intrinsics", 4)
    if fx <= 0.0 or fy <= 0.0:
        raise ProtocolError("intrinsics.fx/fy", "positive focal lengths", (fx, fy))
    return CameraIntrinsics(width, height, fx, fy, cx, cy)


def _body(value: JSON) -> dict[str, JSON]:
    if not isinstance(value, dict):
        raise ProtocolError("body", "a JSON object", type(value).__name__)
    return value


def _arrays(specs: JSON, frames: Sequence[bytes | memoryview]) -> dict[str, NDArray[Any]]:
    if not isinstance(specs, list):
        raise ProtocolError("arrays", "a list of {name, dtype, shape}", specs)
    if len(specs) != len(frames):
        raise ProtocolError("arrays", f"one entry per array frame ({len(frames)} frames)", len(specs))
    arrays: dict[str, NDArray[Any]] = {}
    for spec, frame in zip(specs, frames, strict=False):
        name, dtype, shape = _array_spec(spec)
        expected = math.prod(shape) * dtype.itemsize  # Python integers: no overflow
        if expected > MAX_ARRAY_BYTES:
            raise ProtocolError(f"arrays.{name}.shape", f"at most {MAX_ARRAY_BYTES} bytes an array", expected)
        if len(frame) != expected:
            raise ProtocolError(f"arrays.{name}", f"{expected} bytes for {dtype.str} {tuple(shape)}", len(frame))
        arrays[name] = np.frombuffer(frame, dtype=dtype).reshape(shape)
    return arrays


def _array_spec(spec: JSON) -> tuple[str, np.dtype[Any], list[int]]:
    if not isinstance(spec, dict):
        raise ProtocolError("arrays", "objects {name, dtype, shape}", spec)
    name, dtype, shape = spec.get("name"), spec.get("dtype"), spec.get("shape")
    if not isinstance(name, str) or not name:
        raise ProtocolError("arrays.name", "a non-empty string", name)
    if dtype not in _DTYPES:
        raise ProtocolError(f"arrays.{name}.dtype", f"one of {sorted(_DTYPES)}", dtype)
    if not isinstance(shape, list) or len(shape) > 4 or not all(_is_count(n) for n in shape):
        raise ProtocolError(f"arrays.{name}.shape", "a list of at most 4 integers >= 0", shape)
    return name, np.dtype(str(dtype)), shape


def _is_count(value: JSON) -> bool:
    return isinstance(value, int) and not isinstance(value, bool) and value >= 0
