"""Explorers: where an object-navigation method explores next, on the one agent body (:mod:`drivenav.agent.body`).

The body does what every method shares: the maps, the directions pipeline's weighted-FMM solve (every frontier's
path), the target search (grounding, prompt enrichment and cross-frame verification as switched on), the approach
and STOP, collision recovery in the planner, and segments. An :class:`Explorer` is one episode's exploration: made
at reset from its settings section (:class:`ExplorerSetup`), it is its own per-episode memory and is dropped with
the episode. Each step the body calls :meth:`Explorer.observe` after mapping (what the method reads of the frame:
representative views, a value map) and, unless the approach acts, :meth:`Explorer.act`.

An explorer is registered by an :class:`~drivenav.agent.config.ExplorerEntry` under the entry-point group
``drivenav.explorers`` (:mod:`drivenav.agent.explorers`); docs/extending.md walks through a new one.
"""

from __future__ import annotations

import math
from abc import ABC, abstractmethod
from collections.abc import Mapping
from dataclasses import dataclass, fields, is_dataclass
from typing import TYPE_CHECKING, ClassVar

from drivenav.agent.base import CounterValue
from drivenav.agent.trace import MAX_INTEGER
from drivenav.types import Action, GroundTruth, Observation

if TYPE_CHECKING:
    from drivenav.agent.context import StepContext
    from drivenav.agent.handles import StepHandles, Tuning
    from drivenav.mapping.occupancy import OccupancyMapper
    from drivenav.semantics.protocols import CategoryHints, ImageTextScorer, ModelCall


@dataclass(frozen=True)
class ExplorerSetup:
    """What an explorer is made from at an episode's start: its settings section (``config``, an instance of its
    entry's config class), the agent's tuning, the episode's goal text and ground truth (for stand-in models), the
    mapper (its grid), for an explorer that scores frames (:meth:`Explorer.needs_scorer`) the worker's image-text
    scorer, built once per worker, and for one that reads them (:attr:`Explorer.uses_hints`) the reasoner's
    hints on the goal's category."""

    config: object
    tuning: Tuning
    goal_text: str
    truth: GroundTruth | None
    mapper: OccupancyMapper
    scorer: ImageTextScorer | None = None
    hints: CategoryHints | None = None


class Explorer(ABC):
    """One episode's exploration: its memory and its step hooks."""

    uses_scorer: ClassVar[bool] = False
    """Whether the explorer scores frames with the image-text scorer (``models.scorer``) whatever its settings."""

    @classmethod
    def needs_scorer(cls, config: object) -> bool:
        """Whether the explorer scores frames with the image-text scorer under ``config``, its settings section: one
        that uses it only behind a switch says so here, so that a method with the switch off never loads it."""
        return cls.uses_scorer

    uses_hints: ClassVar[bool] = False
    """Whether the explorer reads the reasoner's hints on the goal's category (ApexNav's room for its prompt)."""

    @abstractmethod
    def __init__(self, setup: ExplorerSetup) -> None:
        """The episode's exploration begins: empty memory, made from ``setup`` (its section is ``setup.config``)."""

    def begin(self, handles: StepHandles) -> None:
        """The episode starts (after the body's reset): record the explorer's first events (none by default)."""
        return None

    def observe(
        self, handles: StepHandles, observation: Observation, ctx: StepContext, timings: dict[str, float]
    ) -> None:
        """What the explorer reads of this step's frame and solve, before the target search and the policy (its
        parts timed into ``timings``, in ms); nothing by default."""
        return None

    @abstractmethod
    def act(self, handles: StepHandles, observation: Observation, ctx: StepContext) -> Action:
        """The next action toward where to explore, when the approach does not act (STOP through
        :meth:`~drivenav.agent.handles.StepHandles.stop` when nothing is left to explore)."""

    def resume(self, handles: StepHandles) -> None:
        """The approach gave its target up: exploring goes on from where the explorer left off (nothing to do by
        default)."""
        return None

    @abstractmethod
    def activity(self, escaping: bool) -> str:
        """The name of the explorer's mode for the steps-by-activity counter (``escaping``: the planner is
        recovering from a collision)."""

    def counters(self) -> object:
        """The explorer's counters of the episode, for its record: None, or a dataclass instance whose fields are
        each a number (int or float, finite, >= 0 and below 2**53) or counts by kind (``{kind: int}``, likewise);
        the body checks them every step (:func:`counter_values`), and a violation ends the episode in an error."""
        return None

    def model_calls(self) -> list[ModelCall]:
        """The model calls the explorer made this episode beyond the body's reasoner (e.g. the scorer's)."""
        return []

    def frame_score(self) -> float | None:
        """This step's image-text score of the frame, for an explorer that scores frames (None otherwise): target-
        centric fusion's negative evidence for the target reads it."""
        return None


class ExplorerContractError(Exception):
    """An explorer handed the body what its contract does not allow (counters out of the record's range, an action
    that is no :class:`~drivenav.types.Action`, a trace event that cannot be saved): the episode ends in an
    ``error`` record naming the explorer and what was wrong."""

    def __init__(self, explorer: str, problem: str) -> None:
        super().__init__(f"explorer {explorer!r} broke its contract: {problem}")


def counter_values(counters: object) -> dict[str, CounterValue]:
    """An explorer's :meth:`~Explorer.counters` as the record's mapping (dataclass fields in order); counters the
    record cannot hold are a :class:`ValueError` saying which and why."""
    if counters is None:
        return {}
    if not is_dataclass(counters) or isinstance(counters, type):
        raise ValueError(f"counters() returned a {type(counters).__name__}, not a dataclass instance (or None)")
    values = {item.name: getattr(counters, item.name) for item in fields(counters)}
    for name, value in values.items():
        if not _is_counter(value):
            raise ValueError(f"counter {name} is {_shown(value)}; expected {COUNTER_CONTRACT}")
    return {name: dict(value) if isinstance(value, Mapping) else value for name, value in values.items()}


COUNTER_CONTRACT = f"a number or counts by kind ({{kind: integer}}), each finite, >= 0 and below {MAX_INTEGER}"


def _is_counter(value: object) -> bool:
    """A number, or counts by kind (string keys, integer counts), each finite, >= 0 and below 2**53."""
    if isinstance(value, Mapping):
        return all(isinstance(k, str) and isinstance(v, int) and _in_range(v) for k, v in value.items())
    return isinstance(value, (int, float)) and _in_range(value)


def _in_range(number: int | float) -> bool:
    if isinstance(number, bool):
        return False
    return (isinstance(number, int) or math.isfinite(number)) and 0 <= number < MAX_INTEGER


def _shown(value: object) -> str:
    """A value in an error's line: short (an integer too long for ``repr`` by its size)."""
    if isinstance(value, int) and not isinstance(value, bool) and abs(value) >= MAX_INTEGER:
        return f"an integer of {abs(value).bit_length()} bits"
    text = repr(value)
    return text if len(text) <= 60 else text[:57] + "..."


def sum_counters(counters: list[dict[str, CounterValue]]) -> dict[str, CounterValue]:
    """Counters of several explorers of one episode (one a floor) added up: numbers summed, counts by kind merged
    by kind and summed; one explorer's counters as they are."""
    if len(counters) == 1:
        return counters[0]
    total: dict[str, CounterValue] = {}
    for one in counters:
        for key, value in one.items():
            total[key] = _add(total.get(key), value)
    return total


def _add(a: CounterValue | None, b: CounterValue) -> CounterValue:
    if a is None:
        return b
    if isinstance(a, dict) and isinstance(b, dict):
        merged = dict(a)
        for kind, count in b.items():
            merged[kind] = merged.get(kind, 0) + count
        return dict(sorted(merged.items()))
    if isinstance(a, int | float) and isinstance(b, int | float):
        return a + b
    raise TypeError(f"explorer counters of one key must be numbers or counts by kind alike, got {a!r} and {b!r}")
