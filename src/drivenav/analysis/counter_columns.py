"""The columns of the report's decisions and steps tables, from what the explorers declare
(:class:`~drivenav.agent.config.CounterSpec`, ``ExplorerEntry.activities``) and the keys the runs' records hold.

The decisions table has the columns drivenav's own explorers declare, in their registration order (a counter two
explorers share, DRIVE-Nav's and ApexNav's ``decisions``, is one total column and each one's kinds), then those of
the other explorers that made the runs (when installed; a plug-in's counter is shown with its title), then every
counter key of the records that no explorer declares (titled by its key). The steps table has the activities of
drivenav's own methods shown since the first report (:data:`STEP_COLUMNS`), then every other activity of the
records but the body's ``stop`` and ``stairs`` (declared ones first).
"""

from __future__ import annotations

from collections.abc import Iterable, Mapping, Sequence
from dataclasses import dataclass, fields

from drivenav.agent.base import BodyCounters
from drivenav.agent.config import CounterSpec, ExplorerEntry
from drivenav.agent.explorers import BUILT_IN_EXPLORERS, explorer_entry
from drivenav.errors import InputError

STEP_COLUMNS = ("start_scan", "scan", "sweep", "follow", "escape", "approach", "enrich")
"""The activities of drivenav's own methods the steps table shows, in its order (the body's ``approach`` and
``escape`` among the explorers')."""
BODY_ACTIVITIES = ("approach", "escape", "stop", "stairs")
"""The activities the body names itself (``stop`` and ``stairs`` are not shown)."""
STEPS = "steps."
BODY_KEYS = frozenset(item.name for item in fields(BodyCounters))
"""The body's counters among a method's means (:func:`drivenav.analysis.ablations.decision_means`)."""


@dataclass(frozen=True)
class Column:
    """One column of the decisions table: the key of its mean, its title and format, how a run aggregates it, and
    its ``family``: the keys of which one at least must be there for the method to keep this counter (a kind's
    column: every declared kind of its counter; counters are written sparsely)."""

    key: str
    title: str
    family: tuple[str, ...]
    format: str = "{:.2f}"
    aggregate: str = "mean"

    def cell(self, means: Mapping[str, float | None], episodes: int) -> str:
        """The column's value for a method (``episodes``: those its means are over); ``-`` where it keeps no such
        counter, ``overflow`` where its mean left the floats' range (None)."""
        if not any(key in means for key in self.family):
            return "-"
        value = means.get(self.key, 0.0)
        if value is None:
            return "overflow"
        return self.format.format(value * episodes if self.aggregate == "sum" else value)


def _spec_columns(spec: CounterSpec) -> list[Column]:
    """A declared counter's columns: its total, then its declared kinds."""
    total = Column(spec.name, spec.heading, (spec.name,), spec.format, spec.aggregate)
    kinds = tuple(f"{spec.name}.{kind}" for kind in spec.kinds)
    return [
        total,
        *(Column(key, kind, kinds, spec.format, spec.aggregate) for key, kind in zip(kinds, spec.kinds, strict=True)),
    ]


def explorer_entries(names: Iterable[str]) -> list[ExplorerEntry]:
    """drivenav's own explorers, then those of ``names`` that are installed (a run's explorer that is not is left
    out: its counters are shown undeclared)."""
    entries = [explorer_entry(name) for name in BUILT_IN_EXPLORERS]
    for name in dict.fromkeys(names):
        if name in BUILT_IN_EXPLORERS:
            continue
        try:
            entries.append(explorer_entry(name))
        except InputError:
            continue
    return entries


def decision_columns(means: Sequence[Mapping[str, float | None]], explorers: Iterable[str]) -> list[Column]:
    """The decisions table's columns for methods with these ``means`` whose runs were made by ``explorers``."""
    entries = explorer_entries(explorers)
    columns: dict[str, Column] = {}
    for spec in (spec for entry in entries for spec in entry.counters if spec.column):
        for column in _spec_columns(spec):
            columns.setdefault(column.key, column)
    declared = {spec.name for entry in entries for spec in entry.counters}
    for key in sorted({key for one in means for key in one}):
        counter = key.split(".")[0]
        if key in BODY_KEYS or key.startswith(STEPS) or counter in declared or key in columns:
            continue
        columns[key] = Column(key, key, (counter,))
    return list(columns.values())


def step_columns(means: Sequence[Mapping[str, float | None]], explorers: Iterable[str]) -> list[str]:
    """The steps table's activities: :data:`STEP_COLUMNS`, then the other activities of the records but the
    body's hidden ones (those the runs' explorers declare first, in their order)."""
    hidden = set(STEP_COLUMNS) | set(BODY_ACTIVITIES)
    found = {key[len(STEPS) :] for one in means for key in one if key.startswith(STEPS)} - hidden
    declared = [name for entry in explorer_entries(explorers) for name in entry.activities if name in found]
    return [*STEP_COLUMNS, *dict.fromkeys([*declared, *sorted(found)])]
