"""The agent body's own settings and how an exploration method registers itself: plain frozen dataclasses, so the
settings layer reads them without importing agent behaviour.

The body (:mod:`drivenav.agent.body`) does what every method shares -- mapping, grounding with enrichment and
cross-frame verification where switched on, the approach and STOP, collision recovery, segments -- with the tuning
of :class:`AgentConfig`; the paper's constants are :class:`~drivenav.paper.DriveNavConfig` beside it. Where to
explore next is an *explorer*'s (:mod:`drivenav.agent.explorer`), registered by an :class:`ExplorerEntry`.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass, field
from typing import Any

from drivenav.mapping.stairs import StairTuning
from drivenav.ranges import COUNT, LENGTH, POSITIVE_LENGTH, STEPS, UNIT, check_ranges, check_rule
from drivenav.types import SimConfig


@dataclass(frozen=True)
class PlannerConfig:
    """The local planner's tuning (ours: the paper names a low-level planner but not its parameters)."""

    lookahead: float = 0.8  # metres: radius of the pursuit circle
    stuck_steps: int = 16  # forward steps over which progress is measured
    stuck_progress: float = 0.15  # metres of net progress below which those steps count as stuck
    escape_turns: int = 2  # turns per blocked forward step in a row before the escape step
    max_turns: int = 12  # turns in a row after which the planner reports spinning

    def __post_init__(self) -> None:
        ranges = {
            "lookahead": POSITIVE_LENGTH,
            "stuck_steps": COUNT,
            "stuck_progress": LENGTH,
            "escape_turns": COUNT,
            "max_turns": COUNT,
        }
        check_ranges(self, ranges)


@dataclass(frozen=True)
class FusionConfig:
    """Target-centric semantic fusion (ApexNav, Zhang et al., RA-L 2025; code Robotics-STAR-Lab/ApexNav,
    ``object_map2d.cpp`` and ``map_ros.cpp``), the body's way of accepting detections when ``enabled``
    (:mod:`drivenav.agent.fusion`): every frame the target and the reasoner's confusable objects are detected as
    competing labels and fused per object, and an object becomes the target when the target's label leads, its
    fused confidence reaches the category's threshold and it was detected ``min_detections`` times. The
    constants are the code's (its launch file and sources); where our maps differ the docstrings of
    :mod:`~drivenav.agent.fusion` say how they are read."""

    enabled: bool = False
    min_detections: int = 2  # isConfidenceObject: n_obs of the target's label >= 2
    association_distance: float = 0.08  # searchSingleObjectCluster: a detection joins the first object with a ...
    # ... cell within 0.08 m of one of its cells
    count_voxel: float = 0.04  # detectedObjectCloudCallback: clouds voxelled at 0.04 m; a detection weighs ...
    # ... as many points as its voxels (here the 0.04 m cells of its footprint)
    max_range: float = 4.9  # detectedObjectCloudCallback: points farther than 4.9 m from the camera are dropped
    evidence_voxel: float = 0.1  # getObservationObjectsCloud: object and depth clouds voxelled at 0.1 m
    evidence_distance: float = 0.11  # inputObservationObjectsCloud: an object point with a depth point within ...
    # ... 0.11 m is in view; an object in view and not detected gets that many points of negative evidence
    goal_views: int = 4  # the goal cells of an object: seen as the target at least min(4, most seen) times
    suspicious_confidence: float = 0.01  # planNextBestPoint: with nothing left to explore, the object of highest ...
    # ... target confidence above 0.01 is approached even below the threshold

    def __post_init__(self) -> None:
        ranges = {
            "min_detections": COUNT,
            "association_distance": LENGTH,
            "count_voxel": POSITIVE_LENGTH,
            "max_range": LENGTH,
            "evidence_voxel": POSITIVE_LENGTH,
            "evidence_distance": LENGTH,
            "goal_views": COUNT,
            "suspicious_confidence": UNIT,
        }
        check_ranges(self, ranges)


@dataclass(frozen=True)
class FloorsConfig:
    """The body's floors (:mod:`drivenav.agent.floors`). Heights in metres, steps in actions.

    ``enabled``: floors on (off: one planar map, the method as published); ``level_tolerance`` 0.3: a height this close
    to a level is on it (habitat's navmesh keeps a floor within a few centimetres; a ramp's first step is 0.2 m);
    ``new_level`` 2.0: a steady height this far from every known level is a new floor (storeys are at least 2.4 m apart,
    a half landing half that); ``probe_steps`` 8: forward steps from a stairs' entry that change the height by less than
    half a step (0.1 m) before the stairs are dropped (2 m); ``climb_steps`` 120: steps on stairs before they are given
    up (a 5 m flight is 20 forward steps); ``approach_steps`` 150: steps toward an entry; ``entry_tolerance`` 0.35: how
    near the entry the agent sets off; ``ask``: the floor question (off: a floor is left only once explored);
    ``confirm`` 1: ``other`` answers in a row that set off (2 won nothing on our development set); ``share`` 1.0: the
    share of the steps left on arriving on a floor that the agent spends on it before it sets off for a floor not yet
    visited, when it knows a way there (0.5: the steps split evenly with the next floor; 1: never, the default: on our
    development set 0.5 lost more episodes on the start floor than it won on others); ``min_floor_steps`` 100: steps on
    a floor before it is first asked (ASCENT keeps at least T/10 = 50 steps between floor changes; on our development
    set, asked from step 60 on, the question judged a goal on the start floor to be on another floor in 6 episodes, from
    step 100 on in 2); ``ask_every`` 25: steps between two questions on a floor; ``near_frontier`` 0 (off): metres
    within which a frontier of the floor's map holds the question back (ASCENT's timing: asked only once no frontier
    is that near, looked at every step; on our development sets 2 m saved no same-floor episode and lost a
    cross-floor one); ``near_way`` 3.0: metres within which a way's entry must lie for a floor judged without the
    target to be left (looked at every step once judged; 0: any way, however far; 3 m, about a room: on our three
    development sets one same-floor and one cross-floor episode more, none fewer, than any way);
    ``recheck`` (on): the floor question is also asked on a floor whose every way leads to a floor judged without
    the target (a floor reached after ``other``), and ``other`` there sends the agent back by the nearest way (on
    our three development sets one same-floor episode more, none fewer);
    ``retry_steps`` 40: steps before a way whose entry the map could not reach is tried again (the body's
    ``blacklist_steps``; before, it was tried at the next step, and an agent could set off at every step);
    ``railings`` (off): ways down suspected behind railing-high lines (:func:`~drivenav.mapping.stairs.find_railings`)
    count as ways to an unknown floor below while none is known: the floor question is asked, and on ``other`` (or
    exhaustion) the agent goes to look from beyond the line's open end, however far; off by default, as kitchen
    counters give such lines too, so that one-floor records stay as they were; ``look_steps`` 6: forward steps
    toward the point to look from, off the map's navigable floor;
    ``album_every`` 15 and ``album_size``
    12: a floor's album (what the question shows), a frame every 15 steps, thinned to every other one and half as often
    past 12, so that it spans the stay on the floor; ``stairs``: how stairs are read from depth.
    """

    enabled: bool = True
    level_tolerance: float = 0.3
    new_level: float = 2.0
    probe_steps: int = 8
    climb_steps: int = 120
    approach_steps: int = 150
    entry_tolerance: float = 0.35
    ask: bool = True
    confirm: int = 1
    share: float = 1.0
    min_floor_steps: int = 100
    ask_every: int = 25
    near_frontier: float = 0.0
    near_way: float = 3.0
    recheck: bool = True
    retry_steps: int = 40
    railings: bool = False
    look_steps: int = 6
    album_every: int = 15
    album_size: int = 12
    stairs: StairTuning = field(default_factory=StairTuning)

    def __post_init__(self) -> None:
        check_ranges(
            self,
            {
                "level_tolerance": POSITIVE_LENGTH,
                "new_level": POSITIVE_LENGTH,
                "probe_steps": COUNT,
                "climb_steps": COUNT,
                "approach_steps": COUNT,
                "entry_tolerance": LENGTH,
                "confirm": COUNT,
                "share": UNIT,
                "min_floor_steps": STEPS,
                "ask_every": COUNT,
                "near_frontier": LENGTH,
                "near_way": LENGTH,
                "retry_steps": COUNT,
                "look_steps": STEPS,
                "album_every": COUNT,
                "album_size": COUNT,
            },
        )


@dataclass(frozen=True)
class AgentConfig:
    """The body's switches (paper Table VI: ``enrich``, ``verify``) and its own tuning (ours: the paper does not give
    these); the paper's constants are a :class:`~drivenav.paper.DriveNavConfig` beside them and the exploration
    method's are its explorer's section (``explorer.<name>``)."""

    enrich: bool = True  # prompt enrichment (Sec. IV-B)
    verify: bool = True  # cross-frame verification (Sec. IV-C)
    stop_distance: float = 0.9  # metres from the target's nearest observed point within which to STOP ...
    # ... once the target is in the current frame (goal view points are positions that see the object).
    give_up_distance: float = 1.0  # a stuck approach this close to the target still STOPs
    blacklist_steps: int = 40  # steps a direction, frontier goal or target that could not be reached is left out
    replan_shift: float = 0.3  # metres the approach goal may move before this step's path is re-planned
    approach_detour_steps: int = 60  # steps an approach may go through frontiers before the target is set aside
    stop_in_view: bool = True  # STOP within stop_distance only with the target in the current frame (else at once)
    planner: PlannerConfig = field(default_factory=PlannerConfig)
    fusion: FusionConfig = field(default_factory=FusionConfig)  # ApexNav's acceptance of detections (off: ours)
    floors: FloorsConfig = field(default_factory=FloorsConfig)  # a map per floor, stairs taken (off: one planar map)

    def __post_init__(self) -> None:
        ranges = {
            "stop_distance": LENGTH,
            "give_up_distance": LENGTH,
            "blacklist_steps": STEPS,
            "replan_shift": LENGTH,
            "approach_detour_steps": STEPS,
        }
        check_ranges(self, ranges)
        expected = "false while agent.fusion.enabled is true (fused objects are accepted by fusion, not verified)"
        check_rule(self, "verify", not (self.verify and self.fusion.enabled), expected)


Rule = tuple[str, bool, str]
"""A rule between an explorer's section and the rest of the settings: the section's key, whether it holds, what the
key accepts."""


def no_rules(config: Any, sim: SimConfig) -> tuple[Rule, ...]:
    """An explorer whose section's ranges are all its own (checked where they are declared)."""
    return ()


COUNT_KINDS = ("count", "by_kind", "metres", "seconds", "number")
"""What a counter holds: a count, counts by kind (``{kind: count}``), metres, seconds, or another number."""
AGGREGATES = ("mean", "sum")
"""How a run aggregates a counter over its episodes (those an exception did not end): the mean per episode, or the
sum."""
MARKERS = ("circle", "square", "cross", "triangle", "diamond")
"""The marker shapes a trace event can be drawn with."""
RGB = tuple[int, int, int]


def _formats_number(template: str) -> bool:
    """Whether ``template`` formats one number (``"{:.2f}"``)."""
    try:
        template.format(1.5)
    except (ValueError, KeyError, IndexError, TypeError, AttributeError):
        return False
    return True


@dataclass(frozen=True)
class CounterSpec:
    """One counter an explorer keeps (a field of its :meth:`~drivenav.agent.explorer.Explorer.counters`) and how the
    report shows it: ``kind`` (:data:`COUNT_KINDS`), ``aggregate`` (:data:`AGGREGATES`), the decisions table's
    column ``title`` (the name when empty) and value ``format``; for counts by kind, the ``kinds`` shown as columns
    of their own (each titled by its kind; none: only the total). ``column`` false keeps the counter in the records
    and the episode pages but out of the table."""

    name: str
    title: str = ""
    kind: str = "count"
    aggregate: str = "mean"
    format: str = "{:.2f}"
    kinds: tuple[str, ...] = ()
    column: bool = True

    def __post_init__(self) -> None:
        check_rule(self, "kind", self.kind in COUNT_KINDS, f"one of {', '.join(COUNT_KINDS)}")
        check_rule(self, "aggregate", self.aggregate in AGGREGATES, f"one of {', '.join(AGGREGATES)}")
        check_rule(self, "kinds", not self.kinds or self.kind == "by_kind", "empty for a counter not by kind")
        check_rule(self, "format", _formats_number(self.format), "a format of one number, e.g. '{:.2f}'")

    @property
    def heading(self) -> str:
        """The column's title."""
        return self.title or self.name


@dataclass(frozen=True)
class EventSpec:
    """One trace event kind an explorer writes (:class:`~drivenav.agent.trace.Event` subclass of that ``kind``) and
    how pictures draw it: its ``fields`` (shown on the episode page, in this order; all when empty), the ``marker``
    (:data:`MARKERS`) and its ``color``, drawn where the agent was at the event's step or, with ``at``, at the
    episode-frame point in that field; ``label`` names it in the legend (the kind when empty)."""

    kind: str
    fields: tuple[str, ...] = ()
    marker: str = "circle"
    color: RGB = (0, 150, 160)
    label: str = ""
    at: str = ""

    def __post_init__(self) -> None:
        check_rule(self, "marker", self.marker in MARKERS, f"one of {', '.join(MARKERS)}")
        valid = len(self.color) == 3 and all(isinstance(c, int) and 0 <= c <= 255 for c in self.color)
        check_rule(self, "color", valid, "three integers in [0, 255] (red, green, blue)")

    @property
    def legend(self) -> str:
        """The event's name in a picture's legend."""
        return self.label or self.kind


@dataclass(frozen=True)
class ExplorerEntry:
    """An exploration method's registration (the object an entry point of group ``drivenav.explorers`` names).

    ``name`` is its settings section (``explorer.<name>``) and the value of ``explorer.name`` that picks it;
    ``config`` the frozen dataclass of that section, whose defaults are the method's source's constants;
    ``explorer`` the ``module:Class`` of its :class:`~drivenav.agent.explorer.Explorer`, imported when an agent is
    built; ``body`` the dotted overrides of the body's switches its method preset sets (``agent.enrich=false``);
    ``rules`` the rules its section must keep with the rest of the settings (given the section and ``sim``; the
    section's own ranges are checked by its dataclass, :mod:`drivenav.ranges`). A plug-in explorer is also an
    ``--agent`` name: its own method, ``explorer.name=<name>`` plus ``body``.

    What it records is declared too, for the report and the pictures: ``counters`` (:class:`CounterSpec`, in the
    decisions table's order; a counter left undeclared is shown under its own name), ``activities`` (the names its
    :meth:`~drivenav.agent.explorer.Explorer.activity` gives, for the steps table) and ``events`` (:class:`EventSpec`:
    the trace events of its own kinds; an undeclared one is drawn as a plain marker with its kind).
    """

    name: str
    config: type
    explorer: str
    description: str
    body: tuple[str, ...] = ()
    rules: Callable[[Any, SimConfig], tuple[Rule, ...]] = no_rules
    counters: tuple[CounterSpec, ...] = ()
    activities: tuple[str, ...] = ()
    events: tuple[EventSpec, ...] = ()

    def counter(self, name: str) -> CounterSpec | None:
        """The declaration of counter ``name`` (None when undeclared)."""
        return next((spec for spec in self.counters if spec.name == name), None)

    def event(self, kind: str) -> EventSpec | None:
        """The declaration of the event kind ``kind`` (None when undeclared)."""
        return next((spec for spec in self.events if spec.kind == kind), None)
