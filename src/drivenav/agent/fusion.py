"""Target-centric semantic fusion (ApexNav, Zhang et al., RA-L 2025; code Robotics-STAR-Lab/ApexNav,
``object_map2d.cpp``): detections fused per object over the episode, so that one confident glimpse of a look-alike
does not end the search. The constants are :class:`~drivenav.agent.config.FusionConfig`'s.

Labels: 0 is the target, ``1..k`` the objects the reasoner named as confusable with it
(:class:`~drivenav.semantics.protocols.CategoryHints`); every frame each label is detected, and an object keeps one
slot per label: its fused confidence ``c``, its detections ``n_obs`` and its running point sum ``S``.

* Points: a detection's projected points (:func:`~drivenav.mapping.objects.project_mask`) within ``max_range`` of
  the camera that fall on obstacle cells of the map (ApexNav keeps the OCCUPIED cells); the map's cells they lie on
  are the detection's cells, and its weight ``n`` is the number of ``count_voxel`` cells its points cover (ApexNav
  counts the voxels of its 3-D cloud; ours are 2-D).
* Association (``searchSingleObjectCluster``): the detection joins the first object (in creation order) having a
  cell within ``association_distance`` of one of its cells, else it starts a new object.
* Update (``fusionConfidenceScore``): ``S <- S + n``, ``c <- ((S - n) c + n s) / S`` with ``s`` the detector's
  score: a point-count weighted mean of the scores, with no angle or distance weight beyond the range cut.
* Negative evidence (``getObservationObjectsCloud``, ``inputObservationObjectsCloud``): an object no detection
  joined this frame whose cells are in view -- ``m`` of its ``evidence_voxel`` cells have a point of the frame's
  depth on obstacle cells within ``evidence_distance`` -- gets the same update for each label it was detected as,
  with ``n = m`` and ``s = 0`` (labels ``1..k``) or ``s = max(0, frame score)`` (label 0: the frame's image-text
  score, where the explorer scores frames; else 0). ApexNav's 3-D distance leaves the floor out; ours keeps the
  depth points on obstacle cells.
* Acceptance (``getTopConfidenceObjectCloud``, ``isConfidenceObject``): the label of largest ``int(S c)`` is the
  target's, ``c_0`` reaches the category's threshold, and ``n_obs_0 >= min_detections``. An object's goal cells
  are those seen as the target at least ``min(goal_views, most seen)`` times.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np
from numpy.typing import NDArray

from drivenav.agent.config import FusionConfig

Keys = NDArray[np.int64]
"""Cells of a world lattice of one cell size, as ``(row + 2**23) * 2**24 + col + 2**23`` (``row, col`` =
floor(y, x / size)): one integer per cell, ordered, for any map within 400 km of the origin at 5 cm."""

_SHIFT = 2**24
_HALF = 2**23


def cell_keys(points: NDArray[np.float64], size: float) -> Keys:
    """The distinct lattice cells (side ``size``) holding ``points`` ``(N, 2)``, sorted."""
    ij = np.floor(points[:, ::-1] / size).astype(np.int64) + _HALF
    keys: Keys = np.unique(ij[:, 0] * _SHIFT + ij[:, 1])
    return keys


def centre_keys(points: NDArray[np.float64], size: float) -> Keys:
    """The lattice cells (side ``size``) of points that are the centres of distinct cells of a map of that size, in
    the points' order (no search for repeats: :func:`cell_keys` for any points)."""
    ij = np.floor(points[:, ::-1] / size).astype(np.int64) + _HALF
    keys: Keys = ij[:, 0] * _SHIFT + ij[:, 1]
    return keys


def key_centres(keys: Keys, size: float) -> NDArray[np.float64]:
    """World ``(x, y)`` of the centres of lattice cells (inverse of :func:`cell_keys`)."""
    rows, cols = keys // _SHIFT - _HALF, keys % _SHIFT - _HALF
    return np.stack([(cols + 0.5) * size, (rows + 0.5) * size], axis=1)


def neighbourhood(keys: Keys, size: float, distance: float) -> Keys:
    """The lattice cells whose centres lie within ``distance`` of the centre of one of ``keys``, sorted."""
    n = math.floor(distance / size + 1e-9)
    di, dj = np.mgrid[-n : n + 1, -n : n + 1]
    near = (di**2 + dj**2) * size**2 <= distance**2 + 1e-12
    offsets = di[near] * _SHIFT + dj[near]
    grown: Keys = np.unique((keys[:, None] + offsets[None, :]).ravel())
    return grown


def fused(confidence: float, points: float, n: float, score: float) -> tuple[float, float]:
    """One update of a label slot (``fusionConfidenceScore``): ``(c, S)`` after ``n`` points scoring ``score``."""
    total = points + n
    return ((total - n) * confidence + n * score) / total, total


@dataclass
class LabelSlot:
    """One label of an object: fused confidence ``c``, detections ``n_obs``, running point sum ``S``."""

    confidence: float = 0.0
    detections: int = 0
    points: float = 0.0

    def add(self, n: float, score: float, detected: bool) -> None:
        self.confidence, self.points = fused(self.confidence, self.points, n, score)
        self.detections += detected


@dataclass
class FusedObject:
    """One object: its map cells (world lattice of the map's resolution), how often each was seen as the target,
    its label slots, when it was first and last detected, its goal cells (those seen as the target at least
    ``min(goal_views, most seen)`` times; empty before its first target detection), and where it lies (its
    ``evidence_voxel`` cells and bounds, for negative evidence)."""

    object_id: int
    cells: Keys
    target_views: dict[int, int]
    slots: list[LabelSlot]
    first_step: int
    last_step: int
    goal: Keys = field(default_factory=lambda: np.empty(0, dtype=np.int64))
    voxels: Keys = field(default_factory=lambda: np.empty(0, dtype=np.int64))  # its evidence_voxel cells
    box: tuple[float, float, float, float] = (0.0, 0.0, 0.0, 0.0)  # x and y bounds of its cells' centres

    @property
    def target(self) -> LabelSlot:
        return self.slots[0]

    def leading_label(self) -> int:
        """The label of largest ``int(S c)`` (``getTopConfidenceObjectCloud``; the lowest of equals)."""
        weights = [int(slot.points * slot.confidence) for slot in self.slots]
        return int(np.argmax(weights))


class ObjectFusion:
    """The objects of one episode (module docstring), for ``labels`` label slots and map cells of ``resolution``."""

    def __init__(self, config: FusionConfig, labels: int, resolution: float) -> None:
        if labels < 1 or not resolution > 0.0:
            raise ValueError(f"ObjectFusion needs labels >= 1 and a positive resolution, got {labels}, {resolution}")
        self.config = config
        self.labels = labels
        self.resolution = resolution
        self.objects: list[FusedObject] = []
        self.joined: set[int] = set()  # objects a detection joined this frame
        self._next_id = 1

    def begin_frame(self) -> None:
        self.joined = set()

    def detect(self, cells: Keys, n: float, label: int, score: float, step: int) -> FusedObject:
        """Fuse one detection of ``label`` covering map ``cells`` (non-empty) with weight ``n`` points."""
        near = neighbourhood(cells, self.resolution, self.config.association_distance)
        found = next((o for o in self.objects if np.isin(o.cells, near, assume_unique=True).any()), None)
        if found is None:
            slots = [LabelSlot() for _ in range(self.labels)]
            found = FusedObject(self._next_id, cells, {}, slots, step, step)
            self._next_id += 1
            self.objects.append(found)
        else:
            found.cells = np.union1d(found.cells, cells)
            found.last_step = max(found.last_step, step)
        centres = key_centres(found.cells, self.resolution)
        found.voxels = cell_keys(centres, self.config.evidence_voxel)
        low, high = centres.min(axis=0), centres.max(axis=0)
        found.box = (float(low[0]), float(low[1]), float(high[0]), float(high[1]))
        found.slots[label].add(n, score, detected=True)
        if label == 0:
            self._count_views(found, cells)
        self.joined.add(found.object_id)
        return found

    def evidence(self, seen: Keys, frame_score: float | None) -> list[FusedObject]:
        """Negative evidence from this frame's depth (``seen``: the ``evidence_voxel`` cells of its points on
        obstacle cells, grown by ``evidence_distance``) for the objects no detection joined; those updated."""
        target_score = max(0.0, frame_score or 0.0)
        updated = []
        for found in self.pending():
            overlap = int(np.isin(found.voxels, seen, assume_unique=True).sum())
            if overlap == 0:
                continue
            for label, slot in enumerate(found.slots):
                if slot.points > 0.0:
                    slot.add(overlap, target_score if label == 0 else 0.0, detected=False)
            updated.append(found)
        return updated

    def pending(self) -> list[FusedObject]:
        """The objects no detection joined this frame."""
        return [o for o in self.objects if o.object_id not in self.joined]

    def seen_cells(self, points: NDArray[np.float64]) -> Keys:
        """The cells of ``points`` (the frame's depth on obstacle cells) that count an object cell as in view: their
        ``evidence_voxel`` cells grown by ``evidence_distance``."""
        voxel = self.config.evidence_voxel
        return neighbourhood(cell_keys(points, voxel), voxel, self.config.evidence_distance)

    def accepted(self, threshold: float) -> list[FusedObject]:
        """The objects accepted as the target (module docstring), highest target confidence first."""
        found = [o for o in self.objects if self.is_target(o, threshold)]
        return sorted(found, key=lambda o: (-o.target.confidence, o.object_id))

    def is_target(self, found: FusedObject, threshold: float) -> bool:
        target = found.target
        return (
            found.leading_label() == 0
            and target.confidence >= threshold
            and target.detections >= self.config.min_detections
        )

    def most_likely(self) -> FusedObject | None:
        """The object of highest target confidence above ``suspicious_confidence`` (ApexNav's "suspicious"
        target when nothing is left to explore), or None."""
        floor = self.config.suspicious_confidence
        found = [o for o in self.objects if o.target.confidence > floor and o.target.detections > 0]
        return min(found, key=lambda o: (-o.target.confidence, o.object_id)) if found else None

    def _count_views(self, found: FusedObject, cells: Keys) -> None:
        views = found.target_views
        for key in cells.tolist():
            views[key] = views.get(key, 0) + 1
        floor = min(self.config.goal_views, max(views.values()))
        found.goal = np.array(sorted(k for k, count in views.items() if count >= floor), dtype=np.int64)
