"""The accepted range of every numeric setting, declared by the dataclass that holds it.

An explorer's section (drivenav's own and a plug-in's) declares its fields' ranges in its class, a table
``RANGES: ClassVar[Mapping[str, Range]] = {"min_goal_distance": LENGTH}``, and the settings loader checks the
chosen section when it is made (:func:`check_declared`): a number without a declared range must at least be finite.
The other sections check their own numbers in ``__post_init__`` (:func:`check_ranges` with a :class:`Range` per
field). Either way, every way a configuration is made -- ``drivenav config show``, a run, ``run.json`` read back,
a caller building a config in Python -- refuses the same values with the same words: one :class:`SettingError` naming
the field and the range, which :mod:`drivenav.settings` turns into a one-line input error on the dotted key.

The bounds follow from what a setting measures, not from tuning: a confidence lies in [0, 1]; an angle within a
circle; a frame's side within :data:`MAX_FRAME_SIDE` pixels; a grid's side within :data:`MAX_GRID_SIDE` cells; a
length within :data:`MAX_LENGTH`; a number of steps within :data:`MAX_STEPS`; and every number is finite. A value
past these bounds would not fail on its own: it would pass and then make every episode an error (an array the
machine cannot hold) or a run that does not end.
"""

from __future__ import annotations

import dataclasses
import math
from collections.abc import Mapping
from dataclasses import dataclass

MAX_FRAME_SIDE = 8192
"""Pixels a side of a camera frame (an 8K frame): one 8192 x 8192 observation -- colour, depth and instance ids,
11 bytes a pixel -- is about 740 MB."""

MAX_GRID_SIDE = 16384
"""Cells a side of the mapper's grids: its maps and the value map's, about 8 bytes a cell, take 2 GiB at
16384 x 16384 (as much as the embedded world allows a scene's grids)."""

MAX_LENGTH = 1000.0
"""Metres: longer than any floor drivenav maps (the mapper's grid stops at ``mapping.max_size``, 200 m by default;
HM3D's largest scenes span under 100 m)."""

MAX_STEPS = 100_000
"""Actions in an episode: a day of a real robot at one action a second (86,400), 200 times Habitat's 500-step
ObjectNav budget. Every count of steps, turns, frames or rounds lies within it."""

MAX_FACTOR = 1000.0
"""A dimensionless gain (the speed field's ``beta``): a thousandfold, far past any preference the paper's 3 expresses,
and well within the precision of the fast-marching times."""


@dataclass(frozen=True)
class Range:
    """The numbers ``low`` .. ``high`` (each end included unless ``*_open``); integers only if ``integer``; ``why``
    says where a bound comes from (shown with it)."""

    low: float = -math.inf
    high: float = math.inf
    low_open: bool = False
    high_open: bool = False
    integer: bool = False
    why: str = ""

    def holds(self, value: object) -> bool:
        """Whether ``value`` is a number of this range (a finite one; an integer if asked for)."""
        if isinstance(value, bool) or not isinstance(value, int | float):
            return False
        if self.integer and not isinstance(value, int):
            return False
        if isinstance(value, float) and not math.isfinite(value):
            return False
        above = value > self.low if self.low_open else value >= self.low
        below = value < self.high if self.high_open else value <= self.high
        return above and below

    @property
    def text(self) -> str:
        """What the range accepts, in words: ``an integer in [1, 8192]``, ``a finite number > 0``, ..."""
        kind = "an integer" if self.integer else "a finite number"
        if math.isinf(self.high):
            bound = f"{kind} {'>' if self.low_open else '>='} {self.low:g}" if math.isfinite(self.low) else kind
        else:
            left, right = "(" if self.low_open else "[", ")" if self.high_open else "]"
            bound = f"{kind} in {left}{self.low:g}, {self.high:g}{right}"
        return f"{bound} ({self.why})" if self.why else bound


UNIT = Range(0.0, 1.0)
"""A confidence or a share."""
LENGTH = Range(0.0, MAX_LENGTH, why="metres")
"""Metres."""
POSITIVE_LENGTH = Range(0.0, MAX_LENGTH, low_open=True, why="metres")
"""Metres, more than none (a size, a step, a resolution)."""
AREA = Range(0.0, MAX_LENGTH * MAX_LENGTH, why="square metres")
"""Square metres."""
CELLS = Range(0.0, float(MAX_GRID_SIDE), why="grid cells")
"""Grid cells (a distance or a margin counted in cells)."""
STEPS = Range(0, MAX_STEPS, integer=True)
"""A number of steps (0: none)."""
COUNT = Range(1, MAX_STEPS, integer=True)
"""A number of steps, turns, frames or images, at least one."""
HALF_TURN = Range(0.0, 180.0)
"""Degrees, at most half a circle."""
FINITE = Range()
"""Any finite number: what a numeric field of an explorer's section without a declared range accepts."""


class SettingError(ValueError):
    """A setting outside its range: the dataclass, the field (dotted below it where a rule spans several), what
    the field accepts and the value given."""

    def __init__(self, owner: type, name: str, expected: str, value: object) -> None:
        self.owner = owner
        self.name = name
        self.expected = expected
        self.value = value
        super().__init__(f"{owner.__name__}.{name}: expected {expected}, got {value!r}")


def check_ranges(config: object, ranges: Mapping[str, Range]) -> None:
    """Raise :class:`SettingError` for the first field of ``config`` named in ``ranges`` whose value is outside its
    range."""
    for name, allowed in ranges.items():
        value = getattr(config, name)
        if not allowed.holds(value):
            raise SettingError(type(config), name, allowed.text, value)


def check_rule(config: object, name: str, holds: bool, expected: str) -> None:
    """Raise :class:`SettingError` on ``name`` (a field of ``config``, or a dotted path below it) unless a rule that
    spans several fields ``holds``."""
    if not holds:
        value: object = config
        for part in name.split("."):
            value = getattr(value, part)
        raise SettingError(type(config), name, expected, value)


def check_declared(config: object) -> None:
    """Raise :class:`SettingError` for the first field of the dataclass ``config`` (and of the dataclasses in it)
    outside the range its class's ``RANGES`` table declares (field name -> :class:`Range`), or, without one, a float
    that is not finite. A table naming no field of the class is an ``AttributeError``."""
    declared: Mapping[str, Range] = getattr(type(config), "RANGES", {})
    check_ranges(config, declared)
    for item in dataclasses.fields(config):  # type: ignore[arg-type]
        value = getattr(config, item.name)
        if dataclasses.is_dataclass(value) and not isinstance(value, type):
            check_declared(value)
        elif item.name not in declared and isinstance(value, float) and not FINITE.holds(value):
            raise SettingError(type(config), item.name, FINITE.text, value)
