"""The target search with target-centric fusion (``agent.fusion.enabled``; ApexNav, Zhang et al., RA-L 2025): the
body's switch from accepting a detection (at once, or after cross-frame verification) to accepting a fused object.

Every step the grounder is asked for the target's phrase and for each confusable object the reasoner named
(:class:`~drivenav.semantics.protocols.CategoryHints`), and the detections are fused per object
(:class:`~drivenav.agent.fusion.ObjectFusion`); objects no detection joined get negative evidence from the frame's
depth. The objects fusion accepts are the search's candidates, all accepted, under the object's id, with its goal
cells as their points, highest target confidence first: the body's approach drives to the one in front and STOPs.
An object whose evidence falls below the bar leaves the candidates (a ``fusion`` rejection in the trace, with no
failed-position memory: it may come back). With nothing left to explore, :meth:`FusedTargetSearch.settle` takes
the object of highest target confidence even below the threshold (ApexNav's "suspicious" target).
"""

from __future__ import annotations

import math
import time

import numpy as np
from numpy.typing import NDArray

from drivenav.agent.config import FusionConfig
from drivenav.agent.fusion import FusedObject, ObjectFusion, cell_keys, key_centres
from drivenav.agent.target import SearchConfig, TargetSearch
from drivenav.agent.trace import DetectionEvent, TargetAccepted, TargetRejected, Trace
from drivenav.mapping.objects import ObjectCandidate, back_project, pixel_height
from drivenav.mapping.types import MapSnapshot
from drivenav.semantics.protocols import CategoryHints, Detection, Grounder, Reasoner
from drivenav.types import Observation, SimConfig

Points = NDArray[np.float64]

FLOOR_HEIGHT = 0.02
"""Depth points lower than this above the floor are floor (:func:`~drivenav.mapping.objects.project_mask`'s
``min_height``)."""


class FusedTargetSearch(TargetSearch):
    """Detections accepted by target-centric fusion (module docstring), with the category's ``hints``."""

    def __init__(
        self,
        sim: SimConfig,
        config: SearchConfig,
        grounder: Grounder | None,
        reasoner: Reasoner,
        fusion: FusionConfig,
        hints: CategoryHints,
    ) -> None:
        if config.verify:
            raise ValueError("target-centric fusion accepts objects itself: cross-frame verification must be off")
        super().__init__(sim, config, grounder, reasoner)
        self.hints = hints
        self.fusion = ObjectFusion(fusion, 1 + len(hints.similar), sim.grid_resolution)
        self._snapshot: MapSnapshot | None = None
        self._entered: set[int] = set()  # objects that were ever candidates
        self._settled: set[int] = set()  # objects taken below the bar (settle)
        self._order: list[int] = []  # the candidates, first to approach first
        self._grounding = 0.0  # seconds of this step spent grounding and lifting masks (not fusion's compute)

    @property
    def phrases(self) -> tuple[str, ...]:
        """The phrase of each label: the target's, then the confusable objects'."""
        return (self.phrase, *self.hints.similar)

    def observe(
        self,
        observation: Observation,
        trace: Trace,
        snapshot: MapSnapshot | None = None,
        frame_score: float | None = None,
        timings: dict[str, float] | None = None,
    ) -> None:
        """Detect every label, fuse, add negative evidence, and bring the candidates up to date; the fusion's own
        compute (not the grounder's, nor the masks' lifting into the map) goes to ``timings["fusion"]``."""
        self.seen_now = set()
        self.step = observation.step
        self._snapshot = snapshot
        if self.grounder is None or snapshot is None:
            return
        start = time.perf_counter()
        self._grounding = 0.0
        self.fusion.begin_frame()
        for label, phrase in enumerate(self.phrases):
            mark = time.perf_counter()
            detections = self.ground(observation, phrase)
            self._grounding += time.perf_counter() - mark
            for detection in detections:
                self._fuse(observation, detection, label, trace)
        self._evidence(observation, snapshot, frame_score)
        self._update(trace)
        if timings is not None:
            timings["fusion"] = (time.perf_counter() - start - self._grounding) * 1000.0

    def _handle(self, observation: Observation, detection: Detection, trace: Trace) -> bool:
        """A detection of the target's phrase (prompt enrichment's too) is fused under the target's label."""
        return self._fuse(observation, detection, 0, trace)

    def _fuse(self, observation: Observation, detection: Detection, label: int, trace: Trace) -> bool:
        """Fuse one detection of ``label``; False when none of its points lies on an obstacle within range."""
        mark = time.perf_counter()
        projected = self._project(observation, detection)  # lifting a mask is grounding's, as for every method
        self._grounding += time.perf_counter() - mark
        points = self._on_obstacles(self._within_range(projected, observation))
        if len(points) == 0:
            return False
        config = self.fusion.config
        cells = cell_keys(points, self.fusion.resolution)
        n = len(cell_keys(points, config.count_voxel))
        found = self.fusion.detect(cells, n, label, detection.score, observation.step)
        if label == 0:
            self.seen_now.add(found.object_id)
            centre = np.median(points, axis=0)
            trace.add(DetectionEvent(observation.step, detection.phrase, detection.score, _point(centre)))
        return True

    def _within_range(self, points: Points, observation: Observation) -> Points:
        pose = observation.pose
        near = np.hypot(points[:, 0] - pose.x, points[:, 1] - pose.y) <= self.fusion.config.max_range
        return points[near]

    def _on_obstacles(self, points: Points) -> Points:
        """The points on obstacle cells of this step's map (ApexNav keeps the occupied cells)."""
        snapshot = self._snapshot
        if snapshot is None or len(points) == 0:
            return points[:0]
        cells = snapshot.grid.world_to_cell(points)
        rows, cols = snapshot.obstacle.shape
        inside = (cells[:, 0] >= 0) & (cells[:, 0] < rows) & (cells[:, 1] >= 0) & (cells[:, 1] < cols)
        keep = np.zeros(len(points), dtype=np.bool_)
        keep[inside] = snapshot.obstacle[cells[inside, 0], cells[inside, 1]]
        return points[keep]

    def _evidence(self, observation: Observation, snapshot: MapSnapshot, frame_score: float | None) -> None:
        """Negative evidence for the objects no detection joined, from the frame's depth on obstacle cells around
        them (ApexNav crops the depth to each object's bounds)."""
        fusion, config, pose = self.fusion, self.fusion.config, observation.pose
        margin = config.evidence_distance + config.evidence_voxel
        boxes = np.array([o.box for o in fusion.pending()]).reshape(-1, 4) + np.array([-1, -1, 1, 1]) * margin
        gap = np.hypot(
            np.maximum(np.maximum(boxes[:, 0] - pose.x, pose.x - boxes[:, 2]), 0.0),
            np.maximum(np.maximum(boxes[:, 1] - pose.y, pose.y - boxes[:, 3]), 0.0),
        )
        boxes = boxes[gap <= config.max_range]
        if len(boxes) == 0:
            return
        cloud = self._depth_points(observation)
        x, y = cloud[:, :1], cloud[:, 1:]
        around = ((x >= boxes[:, 0]) & (x <= boxes[:, 2]) & (y >= boxes[:, 1]) & (y <= boxes[:, 3])).any(axis=1)
        cloud = self._on_obstacles(self._within_range(cloud[around], observation))
        if len(cloud):
            fusion.evidence(fusion.seen_cells(cloud), frame_score)

    def _depth_points(self, observation: Observation) -> Points:
        """World points of the frame's depth above the floor, sampled so that neighbouring samples at
        ``max_range`` lie at most ``evidence_voxel`` apart."""
        config, sim, intrinsics = self.fusion.config, self.sim, observation.intrinsics
        stride = max(1, math.floor(config.evidence_voxel * intrinsics.fx / config.max_range))
        depth = observation.depth[::stride, ::stride].astype(np.float64)
        v, u = np.nonzero((depth > sim.min_depth) & (depth < sim.max_depth))
        z = depth[v, u]
        v, u = v * stride, u * stride
        above = pixel_height(v, z, intrinsics, sim.camera_height) >= FLOOR_HEIGHT
        return back_project(u[above], z[above], intrinsics, observation.pose)

    def _update(self, trace: Trace) -> None:
        """The candidates: the objects fusion accepts (highest target confidence first), then any settled on;
        an object that left them is rejected in the trace."""
        accepted = self.fusion.accepted(self.hints.threshold)
        ids = {o.object_id for o in accepted}
        settled = [o for o in self.fusion.objects if o.object_id in self._settled and o.object_id not in ids]
        chosen = [*accepted, *settled]
        for found in chosen:
            self._enter(found, trace)
        kept = {o.object_id for o in chosen}
        for candidate in self.objects.candidates():
            if candidate.candidate_id not in kept:
                self.objects.discard(candidate.candidate_id)
                trace.add(TargetRejected(self.step, candidate.candidate_id, candidate.center, "fusion"))
        self._order = [o.object_id for o in chosen]

    def _enter(self, found: FusedObject, trace: Trace) -> None:
        """The object as an accepted candidate at its goal cells (a new one announced in the trace)."""
        target = found.target
        points = key_centres(found.goal, self.fusion.resolution)
        candidate = ObjectCandidate(
            found.object_id,
            self.phrase,
            points,
            target.confidence,
            found.first_step,
            found.last_step,
            max(target.detections, 1),
            "accepted",
        )
        known = found.object_id in {c.candidate_id for c in self.objects.candidates()}
        placed = self.objects.place(candidate)
        if not known:
            self._entered.add(found.object_id)
            trace.add(TargetAccepted(self.step, found.object_id, placed.center))

    def settle(self, trace: Trace) -> bool:
        """The object of highest target confidence above ``suspicious_confidence``, taken for the target."""
        found = self.fusion.most_likely()
        if found is None or found.object_id in self._settled or len(found.goal) == 0:
            return False
        self._settled.add(found.object_id)
        self._update(trace)
        return True

    def outcome(self) -> tuple[int, int, int]:
        """Objects that became candidates, candidates now, and candidates set aside, this episode."""
        return len(self._entered), len(self.objects.candidates()), len(self._aside)

    def current(self) -> ObjectCandidate | None:
        """The first candidate (highest target confidence) not set aside."""
        for candidate_id in self._order:
            if self._aside.get(candidate_id, -1) < self.step:
                return self.objects.get(candidate_id)
        return None


def _point(xy: NDArray[np.float64]) -> tuple[float, float]:
    return float(xy[0]), float(xy[1])
