"""Finding the target: grounding every step, prompt enrichment and cross-frame verification (Sec. IV-B, IV-C).

:class:`TargetSearch` owns the grounder, the object map and the phrase the grounder is asked for. Every step it
segments the current frame; a new detection becomes a *candidate*. With verification on, a candidate collects at
most ``verify_frames`` approach frames, each judged by the reasoner: ``sure`` accepts at once, ``not`` rejects at
once (its position goes to failed-position memory), ``uncertain`` waits for the next frame, and a candidate not
rejected within the frames is accepted. A candidate the agent cannot get to is *set aside* for some steps
(:meth:`TargetSearch.set_aside`), not rejected: failed-position memory is for verification's "not". Without
verification, detections are accepted at once. Prompt enrichment (only when the reasoner sees the target but no
candidate exists) alternates proposing a detector phrase and testing it on the current frame for at most
``enrich_rounds`` rounds; a phrase that grounds is kept for the rest of the episode.
"""

from __future__ import annotations

from collections import Counter
from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

from drivenav.agent.trace import (
    DetectionEvent,
    TargetAccepted,
    TargetRejected,
    TargetSetAside,
    Trace,
    VerificationEvent,
)
from drivenav.mapping.objects import ObjectCandidate, ObjectMap, project_mask
from drivenav.mapping.types import MapSnapshot
from drivenav.semantics.protocols import Detection, Grounder, Reasoner, VerificationFrame, View, prefetch
from drivenav.types import Observation, SimConfig

OVERLAY_COLOR = np.array([255, 0, 0], dtype=np.float32)


@dataclass(frozen=True)
class SearchConfig:
    enrich: bool = True
    verify: bool = True
    enrich_rounds: int = 5
    verify_frames: int = 3
    spacing_steps: int = 3  # steps between two verification frames of a candidate (distinct approach views)


def mask_overlay(rgb: NDArray[np.uint8], mask: NDArray[np.bool_]) -> NDArray[np.uint8]:
    """The frame with the candidate's mask tinted red, as shown to the verifier (Sec. IV-C)."""
    out = rgb.astype(np.float32)
    out[mask] = 0.45 * out[mask] + 0.55 * OVERLAY_COLOR
    return out.astype(np.uint8)


class TargetSearch:
    """Per-episode grounding state; the agent asks it for the current target candidate."""

    def __init__(self, sim: SimConfig, config: SearchConfig, grounder: Grounder | None, reasoner: Reasoner) -> None:
        self.sim = sim
        self.config = config
        self.grounder = grounder
        self.reasoner = reasoner
        self.objects = ObjectMap()
        self.goal = ""
        self.phrase = ""
        self.failed_phrases: list[str] = []
        self.enrich_rounds = 0
        self.verifications: Counter[str] = Counter()
        self.seen_now: set[int] = set()
        self.step = 0
        self._frames: dict[int, list[VerificationFrame]] = {}
        self._aside: dict[int, int] = {}  # candidate id -> step until which it is set aside
        self._grounded: tuple[Observation | None, dict[str, list[Detection]]] = (None, {})  # this frame's, by phrase

    def begin(self, goal: str) -> None:
        self.goal = goal
        self.phrase = goal

    # ----------------------------------------------------------------- every step

    @property
    def phrases(self) -> tuple[str, ...]:
        """The phrases :meth:`observe` grounds in every frame: the target's."""
        return (self.phrase,)

    def prefetch(self, observation: Observation) -> None:
        """Tell the grounder, before the frame is mapped, which phrases :meth:`observe` will ground in it (a served
        grounder grounds them meanwhile)."""
        if self.grounder is not None:
            prefetch(self.grounder, observation, self.phrases)

    def ground(self, observation: Observation, phrase: str) -> list[Detection]:
        """The grounder's detections of ``phrase`` in ``observation``: each frame is grounded once per phrase (a
        pending candidate's last frame, a proposed phrase that is the current one, ask again what was found)."""
        assert self.grounder is not None
        frame, found = self._grounded
        if frame is not observation:
            found = {}
            self._grounded = (observation, found)
        if phrase not in found:
            found[phrase] = self.grounder.segment(observation, phrase)
        return found[phrase]

    def observe(
        self,
        observation: Observation,
        trace: Trace,
        snapshot: MapSnapshot | None = None,
        frame_score: float | None = None,
        timings: dict[str, float] | None = None,
    ) -> None:
        """Ground the current phrase in this frame; detections become candidates and are verified. ``snapshot``
        (this step's maps), ``frame_score`` (the explorer's image-text score of the frame, where it scores frames)
        and ``timings`` (ms by part) serve searches that fuse detections over frames
        (:class:`~drivenav.agent.fused_search.FusedTargetSearch`); this one reads the frame alone."""
        self.seen_now = set()
        self.step = observation.step
        if self.grounder is None:
            return
        for detection in self.ground(observation, self.phrase):
            self._handle(observation, detection, trace)

    def _project(self, observation: Observation, detection: Detection) -> NDArray[np.float64]:
        """World points (episode frame) of the detection's mask (Sec. IV-C: masks projected with depth + pose)."""
        return project_mask(
            detection.mask,
            observation.depth,
            observation.intrinsics,
            observation.pose,
            camera_height=self.sim.camera_height,
            min_depth=self.sim.min_depth,
            max_depth=self.sim.max_depth,
        )

    def _handle(self, observation: Observation, detection: Detection, trace: Trace) -> bool:
        """Enter a detection into the object map (unless it falls in failed memory); True if it did."""
        points = self._project(observation, detection)
        if len(points) == 0:
            return False
        candidate = self.objects.add(points, detection.phrase, detection.score, observation.step)
        if candidate is None:
            return False
        self.seen_now.add(candidate.candidate_id)
        trace.add(DetectionEvent(observation.step, detection.phrase, detection.score, candidate.center))
        if candidate.status == "candidate":
            self._verify(observation, detection, candidate, trace, force=False)
        return True

    # ----------------------------------------------------------------- verification (Sec. IV-C)

    def _verify(
        self, observation: Observation, detection: Detection, candidate: ObjectCandidate, trace: Trace, force: bool
    ) -> None:
        cid = candidate.candidate_id
        if not self.config.verify:
            self._accept(cid, observation.step, trace)
            return
        frames = self._frames.setdefault(cid, [])
        if frames and not force and observation.step - frames[-1].step < self.config.spacing_steps:
            return
        frame = VerificationFrame(
            observation.rgb,
            detection.mask,
            mask_overlay(observation.rgb, detection.mask),
            observation.semantic,
            observation.pose,
            observation.step,
        )
        verdict = self.reasoner.verify(self.goal, frame, list(frames))
        frames.append(frame)
        trace.add(VerificationEvent(observation.step, cid, verdict.judgement))
        if verdict.judgement == "sure":
            self._accept(cid, observation.step, trace)
        elif verdict.judgement == "not":
            self.reject(cid, observation.step, trace, "verification")
        else:
            self.verifications["uncertain"] += 1
            if len(frames) >= self.config.verify_frames:
                self._accept(cid, observation.step, trace)

    def verify_now(self, observation: Observation, candidate_id: int, trace: Trace) -> None:
        """The agent has reached a pending candidate: judge this last approach frame, and accept the candidate
        unless it is rejected now (no rejection within the frames it got)."""
        candidate = self.objects.get(candidate_id)
        detections = self.ground(observation, self.phrase) if self.grounder is not None else []
        for detection in detections:
            points = self._project(observation, detection)
            match = self.objects.match(points) if len(points) else None
            if match is not None and match.candidate_id == candidate_id:
                self._verify(observation, detection, candidate, trace, force=True)
                break
        if any(c.candidate_id == candidate_id and c.status == "candidate" for c in self.objects.candidates()):
            self._accept(candidate_id, observation.step, trace)

    def _accept(self, candidate_id: int, step: int, trace: Trace) -> None:
        candidate = self.objects.accept(candidate_id)
        if self.config.verify:
            self.verifications["accepted"] += 1
        trace.add(TargetAccepted(step, candidate_id, candidate.center))

    def reject(self, candidate_id: int, step: int, trace: Trace, reason: str) -> None:
        """Reject a candidate: its position goes to failed-position memory and is never approached again."""
        candidate = self.objects.reject(candidate_id)
        if reason == "verification":
            self.verifications["rejected"] += 1
        trace.add(TargetRejected(step, candidate_id, candidate.center, reason))

    def set_aside(self, candidate_id: int, until: int, trace: Trace) -> None:
        """Leave a candidate alone until step ``until`` (the agent could not get to it); it stays in the map."""
        self._aside[candidate_id] = until
        trace.add(TargetSetAside(self.step, candidate_id, self.objects.get(candidate_id).center, until))

    # ----------------------------------------------------------------- enrichment (Sec. IV-B)

    def enrich(self, observation: Observation, view: View, description: str, trace: Trace) -> bool:
        """Propose-and-ground rounds on the current frame; True when a phrase grounded the target."""
        if not self.config.enrich or self.grounder is None:
            return False
        for _ in range(self.config.enrich_rounds):
            proposal = self.reasoner.propose_prompt(self.goal, view, description, list(self.failed_phrases))
            self.enrich_rounds += 1
            phrase = proposal.phrase.strip()
            if not phrase or phrase.lower() in (f.lower() for f in self.failed_phrases):
                break  # the proposer has run out of new phrases
            detections = self.ground(observation, phrase)
            grounded = [self._handle(observation, d, trace) for d in detections]
            if any(grounded):
                self.phrase = phrase
                return True
            self.failed_phrases.append(phrase)
        return False

    def settle(self, trace: Trace) -> bool:
        """Nothing is left to explore: take the most likely object for the target even below the acceptance bar,
        where the search keeps such evidence; True when it did. This one keeps none."""
        return False

    # ----------------------------------------------------------------- queries

    def outcome(self) -> tuple[int, int, int]:
        """Candidates entered into the object map, accepted, and set aside, this episode."""
        live = self.objects.candidates()
        created = len(live) + len(self.objects.rejected())
        return created, sum(c.status == "accepted" for c in live), len(self._aside)

    def current(self) -> ObjectCandidate | None:
        """The candidate to approach: accepted ones first, then the earliest pending one; none set aside."""
        accepted = [c for c in self.objects.accepted() if self._aside.get(c.candidate_id, -1) < self.step]
        if accepted:
            return accepted[0]
        pending = [
            c
            for c in self.objects.candidates()
            if c.status == "candidate" and self._aside.get(c.candidate_id, -1) < self.step
        ]
        return min(pending, key=lambda c: c.first_step) if pending else None
