"""Carrying a direction's state over its relabelling (paper Sec. IV-A b).

Temporal association gives a merged cluster a fresh label, and a direction that flickers out and back gets one
too. What belongs to the direction goes with it: a merged direction inherits its parents' inspected state and
best representative view; a fresh label at the place of a direction retired earlier is that direction again, not
a newly revealed one; and the followed direction that lost its label is still followed when a fresh label took
over its frontiers.
"""

from __future__ import annotations

from drivenav.agent.context import StepContext
from drivenav.agent.explorers.drive_nav.memory import Directions
from drivenav.agent.handles import StepHandles
from drivenav.directions import Direction
from drivenav.directions.tracking import waypoints_coincide


def carry_over(d: Directions, handles: StepHandles, ctx: StepContext) -> None:
    """Count this step's label changes and carry inspected state, views and the followed direction over them."""
    update, counts = ctx.result.tracking, d.counts
    counts.labels_created += len(update.created)
    counts.labels_merged += len(update.merged)
    counts.labels_removed += len(update.removed)
    for child, parents in update.merged.items():
        relabel(d, child, parents, ctx.directions[child].bearing)
    retired = [label for parents in update.merged.values() for label in parents]
    _remember_retired(d, handles, (*update.removed, *retired))
    for label in update.created:
        _reidentify(d, handles, ctx.directions[label])
    if d.selected is not None and d.selected not in ctx.directions:
        _follow_successor(d, handles, ctx)
    d.followed = ctx.directions.get(d.selected) if d.selected is not None else None
    d.previous = ctx.directions
    _note_births(d, handles, ctx)


def relabel(d: Directions, label: int, parents: tuple[int, ...], bearing: float) -> None:
    """``label`` takes over from ``parents``: inspected if one of them was, their view facing it best, and tracked
    since the earliest of them was."""
    if d.inspected.intersection(parents):
        d.inspected.add(label)
    since = [d.born[parent] for parent in parents if parent in d.born]
    if since:
        d.born[label] = min(since)
    d.views.inherit(label, parents, bearing)


def _note_births(d: Directions, handles: StepHandles, ctx: StepContext) -> None:
    """A direction seen for the first time is tracked from this step; labels neither live nor remembered as retired
    are forgotten."""
    for label in ctx.directions:
        d.born.setdefault(label, handles.step)
    d.born = {label: step for label, step in d.born.items() if label in ctx.directions or label in d.gone}


def _remember_retired(d: Directions, handles: StepHandles, removed: tuple[int, ...]) -> None:
    """Keep the directions retired within ``reidentify_steps``, with this step's newly retired ones."""
    horizon = handles.step - d.config.reidentify_steps
    d.gone = {label: gone for label, gone in d.gone.items() if gone[1] >= horizon}
    d.gone.update({label: (d.previous[label], handles.step) for label in removed if label in d.previous})


def _reidentify(d: Directions, handles: StepHandles, direction: Direction) -> None:
    """A fresh label at the place of a direction whose label was retired earlier (removed, or merged into
    another) is that direction again, no newly revealed one: it keeps its inspected state and view. (Without
    this, a cluster flickering between one and two directions started an inspection event at every split.) A
    branch splitting off a live direction is new: the T of a corridor reveals its exits that way."""
    tolerance = handles.tuning.paper.directions.merge_tolerance
    former = tuple(
        label
        for label, (gone, _) in d.gone.items()
        if waypoints_coincide(direction.waypoints, gone.waypoints, tolerance)
    )
    if former:
        d.counts.labels_reidentified += 1
        relabel(d, direction.label, former, direction.bearing)


def _follow_successor(d: Directions, handles: StepHandles, ctx: StepContext) -> None:
    """The followed direction lost its label: follow its successor, or nothing (a decision follows)."""
    successor = _successor(d, handles, ctx)
    if successor is None:
        d.counts.selected_lost += 1
        d.selected = None
        return
    assert d.selected is not None
    d.counts.followed_through_relabel += 1
    relabel(d, successor.label, (d.selected,), successor.bearing)
    d.selected = successor.label


def _successor(d: Directions, handles: StepHandles, ctx: StepContext) -> Direction | None:
    """The direction that took over the followed one's frontiers under a fresh label, if any."""
    update = ctx.result.tracking
    merged = [child for child, parents in update.merged.items() if d.selected in parents]
    if merged:
        return ctx.directions[merged[0]]
    if d.followed is None:
        return None
    tolerance = handles.tuning.paper.directions.merge_tolerance
    fresh = [ctx.directions[label] for label in update.created]
    same = [x for x in fresh if waypoints_coincide(x.waypoints, d.followed.waypoints, tolerance)]
    return same[0] if same else None
