"""Carrying a direction's state over its relabelling (paper Sec. IV-A b).

Temporal association gives a merged cluster a fresh label, and a direction that flickers out and back gets one
too. What belongs to the direction goes with it: a merged direction inherits its parents' inspected state and
best representative view; a fresh label at the place of a direction retired earlier is that direction again, not
a newly revealed one; and the followed direction that lost its label is still followed when a fresh label took
over its frontiers.
"""

from __future__ import annotations

from drivenav.agent.context import StepContext
from drivenav.agent.loop import Loop
from drivenav.directions import Direction
from drivenav.directions.tracking import waypoints_coincide


def carry_over(loop: Loop, ctx: StepContext) -> None:
    """Count this step's label changes and carry inspected state, views and the followed direction over them."""
    state, update = loop.state, ctx.result.tracking
    counts = state.counts
    counts.labels_created += len(update.created)
    counts.labels_merged += len(update.merged)
    counts.labels_removed += len(update.removed)
    for child, parents in update.merged.items():
        relabel(loop, child, parents, ctx.directions[child].bearing)
    retired = [label for parents in update.merged.values() for label in parents]
    _remember_retired(loop, (*update.removed, *retired))
    for label in update.created:
        _reidentify(loop, ctx.directions[label])
    if state.selected is not None and state.selected not in ctx.directions:
        _follow_successor(loop, ctx)
    state.followed = ctx.directions.get(state.selected) if state.selected is not None else None
    state.previous = ctx.directions


def relabel(loop: Loop, label: int, parents: tuple[int, ...], bearing: float) -> None:
    """``label`` takes over from ``parents``: inspected if one of them was, and their view facing it best."""
    state = loop.state
    if state.inspected.intersection(parents):
        state.inspected.add(label)
    state.views.inherit(label, parents, bearing)


def _remember_retired(loop: Loop, removed: tuple[int, ...]) -> None:
    """Keep the directions retired within ``reidentify_steps``, with this step's newly retired ones."""
    state = loop.state
    horizon = loop.step - loop.tuning.config.reidentify_steps
    state.gone = {label: gone for label, gone in state.gone.items() if gone[1] >= horizon}
    state.gone.update({label: (state.previous[label], loop.step) for label in removed if label in state.previous})


def _reidentify(loop: Loop, direction: Direction) -> None:
    """A fresh label at the place of a direction whose label was retired earlier (removed, or merged into
    another) is that direction again, no newly revealed one: it keeps its inspected state and view. (Without
    this, a cluster flickering between one and two directions started an inspection event at every split.) A
    branch splitting off a live direction is new: the T of a corridor reveals its exits that way."""
    tolerance = loop.tuning.paper.directions.merge_tolerance
    former = tuple(
        label
        for label, (gone, _) in loop.state.gone.items()
        if waypoints_coincide(direction.waypoints, gone.waypoints, tolerance)
    )
    if former:
        loop.state.counts.labels_reidentified += 1
        relabel(loop, direction.label, former, direction.bearing)


def _follow_successor(loop: Loop, ctx: StepContext) -> None:
    """The followed direction lost its label: follow its successor, or nothing (a decision follows)."""
    state = loop.state
    successor = _successor(loop, ctx)
    if successor is None:
        state.counts.selected_lost += 1
        state.selected = None
        return
    assert state.selected is not None
    state.counts.followed_through_relabel += 1
    relabel(loop, successor.label, (state.selected,), successor.bearing)
    state.selected = successor.label


def _successor(loop: Loop, ctx: StepContext) -> Direction | None:
    """The direction that took over the followed one's frontiers under a fresh label, if any."""
    state, update = loop.state, ctx.result.tracking
    merged = [child for child, parents in update.merged.items() if state.selected in parents]
    if merged:
        return ctx.directions[merged[0]]
    if state.followed is None:
        return None
    tolerance = loop.tuning.paper.directions.merge_tolerance
    fresh = [ctx.directions[label] for label in update.created]
    same = [d for d in fresh if waypoints_coincide(d.waypoints, state.followed.waypoints, tolerance)]
    return same[0] if same else None
