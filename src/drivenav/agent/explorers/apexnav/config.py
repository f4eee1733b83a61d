"""ApexNav's explorer (Zhang et al., "ApexNav: An Adaptive Exploration Strategy for Zero-Shot Object Navigation with
Target-centric Semantic Fusion", IEEE RA-L 10(11), 2025): its settings section ``explorer.apexnav`` and its
registration.

The constants are those of ApexNav's code (Robotics-STAR-Lab/ApexNav, ``launch/algorithm.xml`` and the sources
named beside each; its issue #40 says the paper's differ) unless marked ours; docs/agent.md's ApexNav section lists
them with their sources and says where our world differs.
"""

from __future__ import annotations

import string
from collections.abc import Mapping
from dataclasses import dataclass
from typing import ClassVar

from drivenav.agent.config import CounterSpec, ExplorerEntry
from drivenav.ranges import (
    COUNT,
    HALF_TURN,
    LENGTH,
    MAX_FACTOR,
    POSITIVE_LENGTH,
    UNIT,
    Range,
    check_declared,
    check_rule,
)

PROMPT_FIELDS = ("target", "room")
"""The fields ApexNav's prompts are formatted with (:class:`~drivenav.semantics.protocols.ScorePrompt`): the goal and
the room the reasoner named."""

MAX_PROMPT_CHARS = 1000
"""The longest prompt template, and the longest text it may format to with the longest names checked
(:data:`LONGEST_NAME` each): ours, some ten times the source's 45 characters, and a bound on the text a scorer
encodes every frame (a format spec such as ``{room:>99999999}`` would make a 100 MB text per frame)."""

LONGEST_NAME = "x" * 100
"""The target and room a template is formatted with at load, to bound its formatted length: longer than any
category or room name of the benchmarks."""

MAX_TSP_SOLUTIONS = 500
"""The most solutions ``tsp_solutions`` may ask for: ten times ours. Each solution costs about as much as the first
(some 0.06 ms per frontier), so 500 solve 8 frontiers in about 30 ms and 30 in 0.3 s, where ApexNav gives LKH-3 a
2 ms budget; more (100,000 took 112 s for one 60-step episode) would buy time, not tours."""

MODES = ("semantic", "geometric")
"""ApexNav's kinds of decision (its ``decisions`` counter): the mode it decided in."""


@dataclass(frozen=True)
class ApexnavConfig:
    """ApexNav's exploration constants (module docstring)."""

    prompt: str = "Seems like there is a {room} or a {target} ahead?"  # get_itm_message_cosine: the value map's ...
    # ... text, with the room the reasoner named
    prompt_anywhere: str = "Seems like there is a {target} ahead?"  # the same, for a room "everywhere"
    min_confidence: float = 0.0  # value_map2d.cpp getFovConfidence: cos^2 over the FOV, not remapped as VLFM's
    decision_threshold: float = 0.0  # value_map2d.cpp updateValueMap: no new data dropped (VLFM drops below 0.35)
    score_half_width: float = 0.1  # getSortedSemanticFrontiers: the 5 x 5 cells (+-2 x 0.05 m) around a centroid
    piece_radius: float = 0.65  # frontier_map2d.cpp: frontiers split (PCA) until every cell is within 0.65 m ...
    # ... of its piece's centroid; a frontier scores its best piece
    value_tie: float = 1e-4  # exploration_manager.h operator<: values closer than 1e-4 tie (then: shorter path)
    sigma_threshold: float = 0.015  # algorithm.xml: semantic mode needs the scores' standard deviation above this
    ratio_threshold: float = 1.10  # algorithm.xml: ... and max / mean above this
    max_to_mean_percentage: float = 0.90  # algorithm.xml: semantic mode keeps s >= max(r_t mean, p max)
    tsp_scale: float = 100.0  # computeATSPTour: costs (metres) x 100 as integers to the solver
    tsp_unreachable: float = 1e4  # computePathCost: a pair without a path costs 1e4
    tsp_diagonal: float = 1e5  # computeATSPCostMatrix: the diagonal
    tsp_solutions: int = 50  # ours: OR-Tools' guided local search stops after this many solutions (ApexNav's ...
    # ... LKH-3 ran under a wall-clock budget; a count keeps every machine's tour the same). 50 found the optimum ...
    # ... of all 60 random instances of 3-7 frontiers we checked by enumeration (tests/test_apexnav.py keeps one)
    dormant_fov_deg: float = 30.0  # dormantSeenFrontiers: a frontier centre within +-30 deg of the heading, ...
    dormant_range: float = 4.0  # ... within 4.0 m and in clear sight, yet still a frontier, is dormant
    frontier_changed: float = 0.2  # frontier_map2d.cpp: a frontier with >= 20 % of its cells gone is a new one
    reached_radius: float = 0.35  # exploration_manager.cpp: the frontier headed for, this close and still there, ...
    held_replans: int = 14  # ... or held this many decisions without the robot moving, is made dormant
    moved: float = 0.05  # callActionPlanner: less than 0.05 m of translation is no motion

    RANGES: ClassVar[Mapping[str, Range]] = {
        "min_confidence": Range(0.0, 1.0, high_open=True, why="a confidence, below the optical axis's 1"),
        "decision_threshold": UNIT,
        "score_half_width": POSITIVE_LENGTH,
        "piece_radius": POSITIVE_LENGTH,
        "value_tie": UNIT,
        "sigma_threshold": UNIT,
        "ratio_threshold": Range(1.0, MAX_FACTOR, why="max / mean of the scores"),
        "max_to_mean_percentage": UNIT,
        "tsp_scale": Range(0.0, MAX_FACTOR, low_open=True, why="integer cost units per metre"),
        "tsp_unreachable": Range(0.0, 1e9, low_open=True, why="metres"),
        "tsp_diagonal": Range(0.0, 1e9, low_open=True, why="metres"),
        "tsp_solutions": Range(1, MAX_TSP_SOLUTIONS, integer=True, why="solutions: ApexNav's budget is 2 ms"),
        "dormant_fov_deg": HALF_TURN,
        "dormant_range": POSITIVE_LENGTH,
        "frontier_changed": Range(0.0, 1.0, low_open=True, why="a share of the frontier's cells"),
        "reached_radius": POSITIVE_LENGTH,
        "held_replans": COUNT,
        "moved": LENGTH,
    }

    def __post_init__(self) -> None:
        check_declared(self)
        for name in ("prompt", "prompt_anywhere"):
            problem = template_problem(getattr(self, name))
            check_rule(self, name, problem is None, f"{TEMPLATE_EXPECTED} ({problem})")


TEMPLATE_EXPECTED = (
    f"a text naming {{target}}, with plain fields {{target}} and {{room}}, of {MAX_PROMPT_CHARS} characters at most"
)
"""What ApexNav's prompt templates accept (:func:`template_problem`), in the one line refusing one."""


def template_problem(template: str) -> str | None:
    """Why ``template`` cannot serve as ApexNav's prompt, or None: it is formatted once here as every frame formats
    it, so that a template that would fail there (an unknown field, an unmatched brace, a positional field) or
    blow up (a huge width) is refused at load. It names ``{target}`` (``{{target}}`` is a literal) with plain fields
    of :data:`PROMPT_FIELDS` only, no conversion or format spec, and it and its text stay within
    :data:`MAX_PROMPT_CHARS`."""
    if len(template) > MAX_PROMPT_CHARS:
        return f"{len(template)} characters"
    try:
        fields = [(name, conversion, spec) for _, name, spec, conversion in string.Formatter().parse(template)]
    except ValueError as error:
        return f"unmatched braces: {error}"
    for name, conversion, spec in fields:
        if name is not None and (name not in PROMPT_FIELDS or conversion or spec):
            given = "{" + name + (f"!{conversion}" if conversion else "") + (f":{spec}" if spec else "") + "}"
            return f"the field {given}"
    if "target" not in (name for name, _, _ in fields):
        return "no {target} field; {{target}} is a literal"
    text = template.format(**dict.fromkeys(PROMPT_FIELDS, LONGEST_NAME))
    if len(text) > MAX_PROMPT_CHARS:
        return f"a text of {len(text)} characters with names of {len(LONGEST_NAME)}"
    return None


EXPLORER = ExplorerEntry(
    "apexnav",
    ApexnavConfig,
    "drivenav.agent.explorers.apexnav.explorer:ApexnavExplorer",
    "ApexNav: semantic (TSP over high-value frontiers) or geometric (nearest) mode by the value map's spread",
    (
        "agent.enrich=false",
        "agent.verify=false",
        "agent.fusion.enabled=true",
        "agent.stop_in_view=false",
        "agent.stop_distance=0.7",
    ),
    counters=(
        CounterSpec("decisions", kind="by_kind", kinds=MODES),
        CounterSpec("tsp_solves", "TSPs"),
        CounterSpec("dormant_frontiers", "dormant"),
        CounterSpec("settled", column=False),
        CounterSpec("goals_skipped", "goals skipped", column=False),
    ),
    activities=("start_scan", "follow", "escape"),
)
"""ApexNav's exploration (``apexnav``, ``explorer.name=apexnav``; :mod:`~drivenav.agent.explorers.apexnav.explorer`)
and the body switches its method sets: no prompt enrichment or cross-frame verification, target-centric fusion
(``agent.fusion``), and a STOP at the approach's end, seen or not (``searchObjectPath``: the path to the object ends
within 0.5 m of it, ``callActionPlanner``: STOP within 0.2 m of that end, so 0.7 m)."""
