"""Representative views of tracked directions (DRIVE-Nav Sec. IV-A c).

A direction's representative view is the frame whose camera yaw was closest to its bearing: a view is recorded
once the yaw is within ``view_tolerance`` (15 deg) of the bearing -- inclusively, see
:mod:`drivenav.inspection.sweep` -- and replaced whenever a later frame has a smaller angular error. Views are
keyed by direction label; the tracker never re-uses a label, so a stored view always belongs to the direction that
carries its label, and views of retired labels are dropped. A direction that only got a fresh label -- a
position-based merge of directions, or the followed direction carried over a relabelling -- inherits the view of
the parent whose camera faced the new bearing best (:meth:`RepresentativeViews.inherit`; ours: the paper gives the
merged direction a fresh label and says nothing about its views, and it is not a newly revealed direction).
Stored views hold their frame compressed (:class:`~drivenav.packing.PackedImage`, once per frame however many
directions it becomes the view of), or an RGB image the world has not rendered yet as its rendering call
(:class:`~drivenav.packing.DeferredImage`): reads give the same pixels.
"""

from __future__ import annotations

from collections.abc import Callable, Iterable, Sequence

from drivenav.directions.types import Direction
from drivenav.inspection.sweep import signed_offset, within
from drivenav.packing import DeferredImage, PackedImage
from drivenav.paper import InspectionConfig
from drivenav.semantics.protocols import View
from drivenav.types import Observation


class RepresentativeViews:
    """Per-episode memory of one representative view per direction label (Sec. IV-A c)."""

    def __init__(self, tolerance: float = InspectionConfig().view_tolerance) -> None:
        self.tolerance = tolerance
        self._views: dict[int, View] = {}

    def observe(self, directions: Sequence[Direction], observation: Observation, step: int) -> list[tuple[int, bool]]:
        """Record ``observation`` for every direction whose bearing is within tolerance of the camera yaw.

        A direction without a view gets this frame; one with a view gets it only if the new error is smaller than
        the stored one. Returns ``(label, replaced)`` for every view written, in the order of ``directions``.
        """
        written: list[tuple[int, bool]] = []
        images: _Stored | None = None  # packed once for all the views they become
        for direction in directions:
            label, bearing = direction.label, direction.bearing
            error = abs(signed_offset(bearing, observation.pose.yaw))
            stored = self._views.get(label)
            if not within(error, self.tolerance) or (stored is not None and error >= stored.error):
                continue
            images = images or _stored_images(observation)
            self._views[label] = View(label, *images, observation.pose, bearing, error, step)
            written.append((label, stored is not None))
        return written

    def inherit(self, label: int, parents: Iterable[int], bearing: float) -> bool:
        """Give ``label`` (bearing ``bearing``) the parents' view whose yaw is nearest that bearing, its error
        measured against the new bearing (a later, better aligned frame replaces it); True if one was given."""
        views = [self._views[p] for p in parents if p in self._views]
        if not views or label in self._views:
            return False
        best = min(views, key=lambda v: abs(signed_offset(bearing, v.pose.yaw)))
        error = abs(signed_offset(bearing, best.pose.yaw))
        self._views[label] = best.relabelled(label, bearing, error)
        return True

    def has_view(self, label: int) -> bool:
        return label in self._views

    def get(self, label: int) -> View | None:
        return self._views.get(label)

    def labels(self) -> set[int]:
        return set(self._views)

    def retain(self, labels: Iterable[int]) -> None:
        """Keep only the views of ``labels`` (the directions still tracked)."""
        keep = set(labels)
        self._views = {label: view for label, view in self._views.items() if label in keep}

    def reset(self) -> None:
        """Forget every view (a new episode)."""
        self._views.clear()


_Stored = tuple[PackedImage | DeferredImage, PackedImage | None]


def frame_view(observation: Observation, label: int = -1) -> View:
    """The current frame as a view looking where the agent looks (a floor's album, docs/floors.md), its images kept
    as a representative view keeps them."""
    pose = observation.pose
    return View(label, *_stored_images(observation), pose, pose.yaw, 0.0, observation.step)


def _stored_images(observation: Observation) -> _Stored:
    """The observation's RGB and instance images as a view keeps them: compressed, or an RGB image the world has not
    rendered yet as its rendering call."""
    semantic = None if observation.semantic is None else PackedImage.pack(observation.semantic)
    render = observation.rgb_renderer()
    return (PackedImage.pack(observation.rgb) if render is None else DeferredImage(render)), semantic


def inspectable(directions: Sequence[Direction], heading: float, config: InspectionConfig) -> list[Direction]:
    """The directions an inspection event may cover (Sec. IV-A c): ``|alpha_k| <= forward_range / 2`` (the forward
    240 deg set) when ``config.restrict_forward`` holds, and every direction otherwise (the "w/o 240 deg inspection
    view" ablation)."""
    if not config.restrict_forward:
        return list(directions)
    return forward_of(directions, heading, config.forward_range)


def forward_of(directions: Sequence[Direction], heading: float, forward_range: float) -> list[Direction]:
    """The directions whose bearing lies within ``forward_range / 2`` of ``heading`` (Sec. IV-A c: the forward
    240 deg the paper's inspection and decisions keep to)."""
    half_range = forward_range / 2.0
    return [d for d in directions if within(signed_offset(d.bearing, heading), half_range)]


def needs_inspection(
    directions: Sequence[Direction],
    views: RepresentativeViews,
    heading: float,
    config: InspectionConfig,
    still_due: Callable[[Direction], bool] = lambda _: False,
) -> list[Direction]:
    """The directions that call for an inspection event (Sec. IV-A c): :func:`inspectable` and lacking a view.
    Directions that already have a view trigger no rotation, unless ``still_due`` says otherwise (beyond the paper:
    a view the reasoner has not judged yet)."""
    return [d for d in inspectable(directions, heading, config) if not views.has_view(d.label) or still_due(d)]
