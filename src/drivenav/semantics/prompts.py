"""The texts of the VLM's three questions and the JSON answers they ask for (Sec. IV-A c, IV-B, IV-C), and of
ApexNav's category question (text only, asked once per category).

DRIVE-Nav asks Qwen3-VL (i) which persistent direction to explore next, from one representative view per
direction, and whether the target is visible in any of them (Sec. IV-A c, IV-B); (ii) for a detector-oriented
noun phrase naming the target in the target-facing view, given the direction's description and the prompts
that already failed (Sec. IV-B); (iii) whether a segmented candidate is the target, from the current frame, its
mask overlay and earlier approach frames: completely sure, uncertain or definitely not (Sec. IV-C). ApexNav
(Zhang et al., RA-L 2025) asks a language model once per category for the objects a detector confuses with it, a
detection threshold and the room it is most likely in (:func:`hints_text`, our own wording of those three asks).

Each question text states the target as ``Target object: "<goal>".`` (the goal JSON-quoted) and ends with the
answer's schema, verbatim; :mod:`drivenav.semantics.fake_vlm_server` relies on both to answer like a model.
"""

from __future__ import annotations

import json
import math
from collections.abc import Sequence

from drivenav.semantics.protocols import EVERYWHERE, HINT_THRESHOLDS, Candidate

SYSTEM_PROMPT = (
    "You are the semantic reasoning module of an indoor robot searching for an object named in open "
    "vocabulary. You look at the robot's camera images and answer with one JSON object only, without any "
    "other text."
)

SELECT_SCHEMA = (
    '{"direction": <label of the direction to explore next, integer>, "target_visible": <true or false>, '
    '"target_direction": <label of the view showing the target, integer, or null>, '
    '"descriptions": {"<label>": "<what that view shows, at most 12 words>"}}'
)
PROPOSE_SCHEMA = '{"phrase": "<noun phrase of at most 6 words>"}'
VERIFY_SCHEMA = '{"judgement": "sure" | "uncertain" | "not"}'
HINTS_SCHEMA = '{"similar_objects": ["<object name>", ...], "threshold": <number>, "room": "<room or everywhere>"}'
HINTS_SYSTEM_PROMPT = (
    "You are the semantic reasoning module of an indoor robot searching for an object named in open "
    "vocabulary. You answer with one JSON object only, without any other text."
)
MAX_ROOM_WORDS = 4

GOAL_PREFIX = "Target object: "
MAX_PHRASE_WORDS = 6


def goal_line(goal: str) -> str:
    """The line naming the target, with the goal JSON-quoted so any text survives."""
    return f"{GOAL_PREFIX}{json.dumps(goal)}."


def view_caption(label: int) -> str:
    """The caption put before a direction's representative view."""
    return f"view of direction {label}"


def _answer_with(schema: str) -> str:
    return f"Answer with one JSON object exactly in this form:\n{schema}"


def _candidate_line(candidate: Candidate) -> str:
    degrees = math.degrees(candidate.turn)
    side = "left" if degrees > 0 else "right" if degrees < 0 else "ahead"
    distance = f"{candidate.travel_time:.1f} m away" if math.isfinite(candidate.travel_time) else "unreachable"
    seen = "" if candidate.view is not None else " (no view)"
    return (
        f"- direction {candidate.label}: turn {abs(degrees):.0f} deg {side}, {distance}, "
        f"{candidate.frontier_cells} unexplored frontier cells{seen}"
    )


def select_text(goal: str, candidates: Sequence[Candidate], omitted: int) -> str:
    """Question (i), Sec. IV-A c / IV-B: the next direction, target visibility and per-view descriptions.

    ``candidates`` are the directions offered (their views follow the text, captioned by
    :func:`view_caption`); ``omitted`` counts farther directions left out to respect the image limit.
    """
    lines = [
        goal_line(goal),
        "The robot stands at a decision point. Each direction below leads towards unexplored space; a "
        'representative camera view of each direction follows, captioned "view of direction <label>".',
        *(_candidate_line(candidate) for candidate in candidates),
    ]
    if omitted:
        lines.append(f"({omitted} farther directions are not offered: only the nearest fit in one request.)")
    lines += [
        "Choose the direction most likely to lead to the target, judging from the kind of room, the objects "
        "and the openings each view shows, and preferring nearer directions when the evidence is similar. "
        "Say whether the target itself is visible in any view and in which direction, and describe each "
        "view briefly.",
        _answer_with(SELECT_SCHEMA),
    ]
    return "\n".join(lines)


def propose_text(goal: str, description: str, failed: Sequence[str]) -> str:
    """Question (ii), Sec. IV-B: a detector-oriented noun phrase for the target in the attached view."""
    tried = ", ".join(json.dumps(phrase) for phrase in failed) if failed else "none yet"
    return "\n".join(
        [
            goal_line(goal),
            "The image is the robot's view towards the direction where the target was reported visible.",
            f"Earlier description of that direction: {json.dumps(description)}.",
            f"Prompts the object detector already failed to ground: {tried}.",
            f"Propose one concise noun phrase (at most {MAX_PHRASE_WORDS} words) naming the target as it "
            "appears in this image, that an open-vocabulary detector can ground. Do not repeat a failed prompt.",
            _answer_with(PROPOSE_SCHEMA),
        ]
    )


def verify_text(goal: str, earlier: int) -> str:
    """Question (iii), Sec. IV-C: is the highlighted candidate the target (sure / uncertain / not)?"""
    context = (
        f"First come {earlier} earlier approach frames with the candidate highlighted, then the current frame"
        if earlier
        else "You see the current frame"
    )
    return "\n".join(
        [
            goal_line(goal),
            "An object detector proposed a candidate for the target while the robot approached it.",
            f"{context} and the same frame with the candidate's mask overlaid.",
            'Is the highlighted object the target? Answer "sure" if you are completely sure it is, "not" if it '
            'is definitely not, and "uncertain" otherwise.',
            _answer_with(VERIFY_SCHEMA),
        ]
    )


def hints_text(goal: str) -> str:
    """ApexNav's category question: confusable objects, a detection threshold and the likely room (no image)."""
    low, high = HINT_THRESHOLDS
    return "\n".join(
        [
            goal_line(goal),
            "Before searching, the robot needs three facts about this kind of object.",
            '"similar_objects": 3 to 5 names of other common indoor objects that an object detector (such as YOLO '
            "or Grounding DINO) may mistake for the target. The robot also detects these, so that an object that "
            "looks more like one of them does not count as the target.",
            f'"threshold": the detection confidence, between {low} and {high}, from which a repeatedly detected '
            f"object counts as the target: higher for large objects that detectors often confuse with others (a "
            f"bed: about {high}), lower for small objects that detectors find only with low confidence (an apple: "
            f"about {low}).",
            f'"room": the kind of room where the target is most likely found, or "{EVERYWHERE}" when it is common '
            "in many kinds of room.",
            _answer_with(HINTS_SCHEMA),
        ]
    )


def repair_text(problem: str, schema: str) -> str:
    """The follow-up sent once after a malformed answer: what was wrong, and the schema again."""
    return f"Your previous answer could not be used: {problem}.\n{_answer_with(schema)}"
