"""What the brain-robot protocol's bodies and arrays carry (:mod:`drivenav.wire.protocol`, docs/robot.md): a RESET's
episode and what it claims of it, depth as uint16 millimetres, RGB as JPEG bytes, and a LiDAR occupancy window."""

from __future__ import annotations

import io
from collections.abc import Mapping

import numpy as np
from numpy.typing import NDArray

from drivenav.episode import Episode
from drivenav.types import LocalOccupancy
from drivenav.wire.protocol import DEPTH_SCALE, JSON, Message, ProtocolError, finite_list

# -- episodes -------------------------------------------------------------------------------------------------------


def reset_body(episode: Episode) -> dict[str, JSON]:
    """A RESET's body: the episode's id and target text and, for an episode of an episodes file (one with goals),
    what it claims of the episode (``episode``: scene, target, start), so that a robot that knows the episodes
    (``serve-sim``) can refuse one that is not the episode it serves under that id. A live episode (no goals: a
    target of the operator's, wherever the robot stands) claims nothing."""
    body: dict[str, JSON] = {"episode_id": episode.episode_id, "target": episode.object_category}
    if episode.goals:
        body["episode"] = _claims(episode)
    return body


def _claims(episode: Episode) -> dict[str, JSON]:
    return {
        "scene_id": episode.scene_id,
        "target": episode.object_category,
        "start_position": list(episode.start_position),
    }


def check_claimed_episode(episode: Episode, body: Mapping[str, JSON]) -> None:
    """Refuse a RESET whose claimed scene, target or start differ from ``episode`` (the one served under its id):
    the brain would record this episode's metrics under another episode's scene and target."""
    claimed = body.get("episode")
    if claimed is None:
        return
    if not isinstance(claimed, dict):
        raise ProtocolError("body.episode", "an object with scene_id, target, start_position", claimed)
    for name, value in _claims(episode).items():
        if claimed.get(name) != value:
            expected = f"{value!r}, episode {episode.episode_id}'s on this robot (run the brain on its episodes file)"
            raise ProtocolError(f"body.episode.{name}", expected, claimed.get(name))


# -- payload conversions ------------------------------------------------------------------------------------------


def depth_to_wire(depth: NDArray[np.float32]) -> NDArray[np.uint16]:
    """Metres to uint16 millimetres (rounded); no return (NaN, inf, <= 0) and anything past 65.535 m become 0."""
    mm = np.nan_to_num(np.asarray(depth, dtype=np.float64) * DEPTH_SCALE, nan=0.0, posinf=0.0, neginf=0.0)
    mm = np.rint(mm)
    mm[(mm <= 0.0) | (mm > np.iinfo(np.uint16).max)] = 0.0
    return mm.astype(np.uint16)


def depth_from_wire(mm: NDArray[np.uint16]) -> NDArray[np.float32]:
    """uint16 millimetres to float32 metres; 0 (no return) becomes NaN, a hole the mapper skips (never
    ``min_depth``)."""
    depth: NDArray[np.float32] = mm.astype(np.float32) / np.float32(DEPTH_SCALE)
    depth[mm == 0] = np.nan
    return depth


def rgb_to_jpeg(rgb: NDArray[np.uint8], quality: int = 90) -> NDArray[np.uint8]:
    """An RGB image as JPEG bytes (a uint8 array, to travel as an array frame)."""
    from PIL import Image

    buffer = io.BytesIO()
    Image.fromarray(rgb).save(buffer, format="JPEG", quality=quality)
    return np.frombuffer(buffer.getvalue(), dtype=np.uint8)


def rgb_from_jpeg(data: NDArray[np.uint8], shape: tuple[int, int]) -> NDArray[np.uint8]:
    """The RGB image of JPEG bytes; it must have ``shape`` (height, width)."""
    from PIL import Image, UnidentifiedImageError

    try:
        image = np.asarray(Image.open(io.BytesIO(data.tobytes())).convert("RGB"), dtype=np.uint8)
    except (UnidentifiedImageError, OSError) as error:
        raise ProtocolError("arrays.rgb_jpeg", "a JPEG image", str(error)) from None
    if image.shape[:2] != shape:
        raise ProtocolError("arrays.rgb_jpeg", f"an image of {shape[0]}x{shape[1]} (height x width)", image.shape[:2])
    return image


def occupancy_body(local: LocalOccupancy) -> dict[str, JSON]:
    """The header fields of a LiDAR occupancy window (its cells travel as the ``occupancy`` array)."""
    return {"occupancy_origin": list(local.origin), "occupancy_resolution": local.resolution}


def occupancy_from(message: Message) -> LocalOccupancy | None:
    """The LiDAR occupancy window an OBSERVATION carries, or None."""
    cells = message.arrays.get("occupancy")
    if cells is None:
        return None
    if cells.dtype != np.int8 or cells.ndim != 2:
        raise ProtocolError("arrays.occupancy", "a 2-D int8 array", f"{cells.dtype} {cells.shape}")
    origin = finite_list(message.body.get("occupancy_origin"), "body.occupancy_origin", 2)
    resolution = finite_list([message.body.get("occupancy_resolution")], "body.occupancy_resolution", 1)[0]
    if resolution <= 0.0:
        raise ProtocolError("body.occupancy_resolution", "a positive cell size", resolution)
    return LocalOccupancy(cells, (origin[0], origin[1]), resolution)
