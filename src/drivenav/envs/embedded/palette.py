"""Colours of the embedded world's RGB images: object categories, room floors, structure.

Every colour is deterministic and stable across runs and machines: common names come from hand-picked tables,
other names from ``zlib.crc32`` of the lower-cased name (never Python's salted ``hash()``).
"""

from __future__ import annotations

import colorsys
import zlib
from enum import IntEnum

RGB = tuple[int, int, int]


class FloorPattern(IntEnum):
    """Floor textures the renderer knows (drawn from the floor hit's world xy)."""

    TILES = 0
    PLANKS = 1
    PLAIN = 2


# Walls, door frames, unknown space and ceiling (walls pale and warm, ceiling near white, floors mid-tone).
WALL_COLOR: RGB = (206, 196, 172)
BASEBOARD_COLOR: RGB = (112, 96, 80)
DOOR_FRAME_COLOR: RGB = (138, 92, 52)
UNKNOWN_COLOR: RGB = (48, 48, 52)
CEILING_COLOR: RGB = (236, 238, 242)
STAIR_COLOR: RGB = (150, 104, 62)  # treads and risers: wood
RAILING_COLOR: RGB = (70, 56, 44)
SLAB_EDGE_COLOR: RGB = (214, 210, 200)  # the cut edge of a floor slab round a stairwell

_CATEGORY_COLORS: dict[str, RGB] = {
    "chair": (230, 25, 75),
    "bed": (60, 120, 230),
    "sofa": (0, 150, 60),
    "couch": (0, 150, 60),
    "toilet": (250, 250, 255),
    "tv": (20, 20, 30),
    "tv_monitor": (20, 20, 30),
    "television": (20, 20, 30),
    "plant": (120, 220, 40),
    "potted plant": (120, 220, 40),
    "table": (245, 130, 48),
    "dining table": (245, 130, 48),
    "refrigerator": (70, 240, 240),
    "sink": (145, 30, 180),
    "bathtub": (190, 190, 255),
    "cabinet": (128, 64, 0),
    "desk": (255, 200, 40),
    "shelf": (170, 110, 40),
    "bookshelf": (170, 110, 40),
    "lamp": (255, 250, 120),
    "oven": (128, 128, 128),
    "stove": (128, 128, 128),
    "washing machine": (0, 128, 128),
    "picture": (240, 50, 230),
    "mirror": (160, 220, 255),
    "counter": (110, 70, 140),
    "stool": (250, 110, 150),
    "nightstand": (170, 255, 195),
    "dresser": (100, 40, 40),
    "fireplace": (200, 60, 20),
    "towel": (255, 215, 180),
    "clock": (0, 0, 128),
}

_FLOORS: dict[str, tuple[RGB, FloorPattern]] = {
    "": ((128, 124, 118), FloorPattern.PLAIN),
    "kitchen": ((118, 124, 132), FloorPattern.TILES),
    "bathroom": ((118, 150, 168), FloorPattern.TILES),
    "laundry room": ((138, 146, 158), FloorPattern.TILES),
    "bedroom": ((150, 106, 70), FloorPattern.PLANKS),
    "living room": ((124, 84, 52), FloorPattern.PLANKS),
    "dining room": ((112, 72, 44), FloorPattern.PLANKS),
    "office": ((146, 120, 84), FloorPattern.PLANKS),
    "hallway": ((120, 110, 98), FloorPattern.TILES),
    "corridor": ((120, 110, 98), FloorPattern.TILES),
    "entryway": ((104, 98, 92), FloorPattern.TILES),
    "garage": ((108, 108, 108), FloorPattern.PLAIN),
    "closet": ((132, 100, 74), FloorPattern.PLANKS),
    "gym": ((70, 82, 96), FloorPattern.PLAIN),
    "playroom": ((96, 134, 108), FloorPattern.PLAIN),
}


def _crc(name: str) -> int:
    return zlib.crc32(name.strip().lower().encode("utf-8"))


def _hsv(h: float, s: float, v: float) -> RGB:
    r, g, b = colorsys.hsv_to_rgb(h, s, v)
    return round(r * 255), round(g * 255), round(b * 255)


def category_color(category: str) -> RGB:
    """The RGB colour of an object category: saturated, so objects stand out from the pale structure.

    Unlisted categories get a hue from the golden-ratio sequence indexed by the name's CRC-32 and one of three
    saturation/brightness levels, so two unlisted names rarely share a colour.
    """
    key = category.strip().lower()
    if key in _CATEGORY_COLORS:
        return _CATEGORY_COLORS[key]
    h = _crc(key)
    hue = ((h & 0xFFFF) * 0.618033988749895) % 1.0
    level = (h >> 16) % 3
    return _hsv(hue, (0.95, 0.75, 0.85)[level], (0.95, 0.8, 0.6)[level])


def floor_color(room_name: str) -> RGB:
    """The base floor colour of a room type (``""``: outside every room); muted, darker than walls."""
    key = room_name.strip().lower()
    if key in _FLOORS:
        return _FLOORS[key][0]
    h = _crc(key)
    return _hsv(((h & 0xFFFF) / 65536.0), 0.25 + 0.1 * ((h >> 16) % 3), 0.45 + 0.06 * ((h >> 20) % 3))


def floor_pattern(room_name: str) -> FloorPattern:
    """The floor texture of a room type: tiles for wet rooms and passages, planks for living spaces."""
    key = room_name.strip().lower()
    if key in _FLOORS:
        return _FLOORS[key][1]
    return FloorPattern(_crc(key) % 2)
