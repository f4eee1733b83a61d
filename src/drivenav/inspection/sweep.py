"""Rotation planning for inspection events (DRIVE-Nav Sec. IV-A c).

At an inspection event the robot measures, for every tracked direction, the signed turn
``alpha_k = wrap(bearing_k - heading)`` in ``(-pi, pi]``. The directions still lacking a representative view are
faced with a sweep: arranged by signed offset, visited from the side (left: ``alpha > 0``, right:
``alpha < 0``) whose nearest direction needs the smaller turn, outward along that side, then across to the other
side, inner direction first. The robot turns in whole steps of ``turn_angle`` (30 deg in Habitat), so only the
yaws ``heading + k * turn_angle`` are reachable; a bearing is *served* by a reachable yaw within half a turn of it.

Boundary choice. With 30 deg turns the best achievable error is at most 15 deg, and it is exactly 15 deg for a
bearing half-way between two reachable yaws. The paper records a view when the error is *less than* 15 deg, which
such a bearing could never satisfy, so an inspection event would never complete. drivenav therefore treats the
tolerance as inclusive (up to :data:`ANGLE_EPS` of float slack) everywhere: the planner serves a half-way bearing
with the yaw nearer the current heading, and :class:`~drivenav.inspection.views.RepresentativeViews` records the
view taken there.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from itertools import pairwise

from drivenav.grid import wrap_angle
from drivenav.types import Action

ANGLE_EPS = 1e-9
"""Radians of float slack on every angular comparison (turn sums never land exactly on a tolerance)."""


def signed_offset(bearing: float, heading: float) -> float:
    """The paper's ``alpha_k``: the signed turn from ``heading`` to ``bearing`` in ``(-pi, pi]`` (Sec. IV-A c)."""
    return wrap_angle(bearing - heading)


def within(angle: float, limit: float) -> bool:
    """Whether ``|angle| <= limit`` up to :data:`ANGLE_EPS` (the inclusive tolerance of Sec. IV-A c)."""
    return abs(angle) <= limit + ANGLE_EPS


def full_scan_turns(turn_angle: float) -> int:
    """Turns of the episode-start 360 deg scan (Sec. IV-A c): twelve for 30 deg turns."""
    return math.ceil(2.0 * math.pi / turn_angle - ANGLE_EPS)


def turn_toward(yaw: float, target: float, turn_angle: float) -> Action | None:
    """The next turn toward ``target`` by the smaller rotation, or None once a turn would not bring it closer.

    Facing ``target`` means being within half a turn of it; a target exactly behind is turned to the left.
    """
    offset = signed_offset(target, yaw)
    if within(offset, turn_angle / 2.0):
        return None
    return Action.TURN_LEFT if offset > 0.0 else Action.TURN_RIGHT


def sweep_turns(heading: float, yaws: Sequence[float], turn_angle: float) -> int:
    """How many turns visiting ``yaws`` in order from ``heading`` costs, each leg by the smaller rotation."""
    return sum(round(abs(signed_offset(b, a)) / turn_angle) for a, b in pairwise([heading, *yaws]))


def _stop_counts(magnitudes: Sequence[float], turn_angle: float) -> list[int]:
    """Fewest turn counts ``k`` on one side serving every ``|alpha|`` in ``magnitudes``, ascending.

    Greedy from the outermost offset inward: each unserved offset gets the innermost ``k`` serving it (the smaller
    turn at a half-way boundary), which also serves every inner offset within half a turn of ``k``.
    """
    half = turn_angle / 2.0
    counts: list[int] = []
    for magnitude in sorted(magnitudes, reverse=True):
        if counts and within(magnitude - counts[-1] * turn_angle, half):
            continue
        counts.append(math.ceil((magnitude - half - ANGLE_EPS) / turn_angle))
    return sorted(counts)


def _side_yaws(heading: float, offsets: Sequence[float], sign: float, turn_angle: float) -> list[float]:
    """Yaws serving ``offsets`` (all on the side of ``sign``), from the heading outward."""
    counts = _stop_counts([abs(a) for a in offsets], turn_angle)
    return [wrap_angle(heading + sign * k * turn_angle) for k in counts]


def _unserved(offsets: Sequence[float], heading: float, yaws: Sequence[float], turn_angle: float) -> list[float]:
    """The offsets (relative to ``heading``) that no yaw in ``yaws`` serves."""
    return [a for a in offsets if not any(within(signed_offset(heading + a, y), turn_angle / 2.0) for y in yaws)]


def plan_sweep(heading: float, bearings: Sequence[float], turn_angle: float) -> list[float]:
    """The yaws, in visiting order, that bring every bearing within half a turn of a visited yaw (Sec. IV-A c).

    Every yaw is ``heading + k * turn_angle`` wrapped to ``(-pi, pi]``. Bearings already served by ``heading``
    need no turn, and one yaw serving several bearings is one stop. The side whose nearest unserved bearing has the
    smaller ``|alpha|`` goes first (left on a tie), outward; then the other side's bearings not already served,
    inner first. Returns ``[]`` when nothing needs a turn. Within the forward 240 deg range this never costs more
    turns than a full scan; over all 360 deg (the "w/o 240" ablation) it may.
    """
    offsets = _unserved([signed_offset(b, heading) for b in bearings], heading, [heading], turn_angle)
    left = [a for a in offsets if a > 0.0]
    right = [a for a in offsets if a < 0.0]
    sides = [(left, 1.0), (right, -1.0)]
    if left and right and min(-a for a in right) < min(left):
        sides.reverse()
    (first, first_sign), (second, second_sign) = sides
    yaws = _side_yaws(heading, first, first_sign, turn_angle)
    rest = _unserved(second, heading, yaws, turn_angle)
    return yaws + _side_yaws(heading, rest, second_sign, turn_angle)
