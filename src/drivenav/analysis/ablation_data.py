"""The ablation report as typed records: what ``ablations.json`` holds, built once by
:func:`drivenav.analysis.ablations.build_report` and read by attribute by :mod:`drivenav.analysis.ablation_report`.

Each record's ``to_json`` writes the keys ``ablations.json`` has always had, in the same order (other tools read
the file); ``from_json`` reads them back. Intervals (``sr_ci95``, ``spl_ci95``) are ``[lo, hi]`` lists in JSON.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import asdict, dataclass, field
from pathlib import Path
from typing import TypeVar

from drivenav.analysis.beyond import PairedEntry
from drivenav.analysis.compare import Comparison
from drivenav.errors import InputError
from drivenav.eval.report import CallCounts, with_calls
from drivenav.jsonstream import DOCUMENT, JsonObject

Interval = tuple[float, float]
_Record = TypeVar("_Record")


def _interval_json(interval: Interval | None) -> list[float] | None:
    return None if interval is None else [interval[0], interval[1]]


def _interval(value: list[float] | None) -> Interval | None:
    return None if value is None else (value[0], value[1])


def _each(values: JsonObject, read: Callable[[JsonObject], _Record]) -> dict[str, _Record]:
    return {name: read(value) for name, value in values.items()}


@dataclass(frozen=True)
class MethodEntry:
    """One method's aggregate over its episodes: SR and SPL with 95 % intervals (None without a measured episode),
    steps, revisits, model calls (in all; by model under ``calls``, None in a report written before it), failures by
    cause, missed targets by cause, and per-episode means of the decision counters (``decisions.REASON``,
    ``steps.ACTIVITY``) and the plug-in explorers whose counters these are (``plugins``: their declarations title
    their columns; drivenav's own are always known). ``errors`` counts the episodes an exception ended, never
    navigation failures."""

    episodes: int
    errors: int
    success_rate: float | None
    spl: float | None
    avg_steps: float | None
    avg_revisits: float | None
    sr_ci95: Interval | None
    spl_ci95: Interval | None
    avg_retraced_revisits: float | None
    vlm_calls: float | None
    median_vlm_calls: float | None
    failure_causes: dict[str, int]
    missed_target_causes: dict[str, int] = field(default_factory=dict)
    decisions: dict[str, float | None] = field(default_factory=dict)
    plugins: tuple[str, ...] = ()
    calls: CallCounts | None = None

    def to_json(self) -> JsonObject:
        """The entry's keys; ``plugins`` only where there are some, as one text (``a,b``: a CSV cell), so that the
        files of drivenav's own methods keep their keys; the calls by model flat at the end (none in a report
        written before them)."""
        data = asdict(self)
        data.update(sr_ci95=_interval_json(self.sr_ci95), spl_ci95=_interval_json(self.spl_ci95))
        plugins = data.pop("plugins")
        if plugins:
            data["plugins"] = ",".join(plugins)
        return with_calls(data)

    @staticmethod
    def from_json(data: JsonObject) -> MethodEntry:
        values = {
            **CallCounts.without(data),
            "sr_ci95": _interval(data["sr_ci95"]),
            "spl_ci95": _interval(data["spl_ci95"]),
        }
        plugins = data.get("plugins", "")
        values["plugins"] = tuple(plugins.split(",")) if plugins else ()
        return MethodEntry(**values, calls=CallCounts.from_json(data))


@dataclass(frozen=True)
class SplitEntry:
    """One method on the episodes of one vocabulary split (HM3D-OVON reports SR and SPL per split): episodes,
    errors, SR and SPL with their 95 % intervals, as in :class:`MethodEntry`."""

    episodes: int
    errors: int
    success_rate: float | None
    spl: float | None
    sr_ci95: Interval | None
    spl_ci95: Interval | None

    @staticmethod
    def of(entry: MethodEntry) -> SplitEntry:
        """The split's columns of a :class:`MethodEntry` computed over the split's records."""
        return SplitEntry(entry.episodes, entry.errors, entry.success_rate, entry.spl, entry.sr_ci95, entry.spl_ci95)

    def to_json(self) -> JsonObject:
        data = asdict(self)
        data.update(sr_ci95=_interval_json(self.sr_ci95), spl_ci95=_interval_json(self.spl_ci95))
        return data

    @staticmethod
    def from_json(data: JsonObject) -> SplitEntry:
        values = {**data, "sr_ci95": _interval(data["sr_ci95"]), "spl_ci95": _interval(data["spl_ci95"])}
        return SplitEntry(**values)


Splits = dict[str, dict[str, SplitEntry]]
"""Per split (``val_seen``, ...), per method, its :class:`SplitEntry`."""


@dataclass(frozen=True)
class Paired:
    """One method against ``reference`` on the episodes both measured (no error in either): how many, and how many
    this method solved and the reference did not (``wins``) or the other way round (``losses``)."""

    reference: str
    shared: int
    wins: int
    losses: int

    def to_json(self) -> JsonObject:
        return asdict(self)

    @staticmethod
    def from_json(data: JsonObject) -> Paired:
        return Paired(data["reference"], data["shared"], data["wins"], data["losses"])


@dataclass(frozen=True)
class GroupEntry:
    """One method on one floor group of episodes: the per-split columns (:class:`SplitEntry`) and the successes
    behind its SR (a group can be small: its count says more than a rate)."""

    results: SplitEntry
    successes: int

    def to_json(self) -> JsonObject:
        return {**self.results.to_json(), "successes": self.successes}

    @staticmethod
    def from_json(data: JsonObject) -> GroupEntry:
        results = SplitEntry.from_json({key: value for key, value in data.items() if key != "successes"})
        return GroupEntry(results, data["successes"])


ONE_FLOOR, SAME_FLOOR, CROSS_FLOOR = "one_floor", "same_floor", "cross_floor"
FLOOR_GROUPS = {ONE_FLOOR: "one-floor homes", SAME_FLOOR: "same floor", CROSS_FLOOR: "cross floor"}
"""The floor groups by key, in the report's order, with the names the tables show: episodes in scenes of one storey
(no ``info["cross_floor"]``), in a home of several storeys with a goal on the start floor (``cross_floor`` false),
and needing a floor change (``cross_floor`` true)."""


@dataclass(frozen=True)
class Floors:
    """Each method per floor group (:data:`FLOOR_GROUPS`: groups without a record left out), and each other method
    against ``reference`` episode by episode within each group (``paired``: groups where the reference was run)."""

    reference: str
    groups: dict[str, dict[str, GroupEntry]]
    paired: dict[str, dict[str, Paired]] = field(default_factory=dict)

    def to_json(self) -> JsonObject:
        return {
            "reference": self.reference,
            "groups": {group: {m: e.to_json() for m, e in by.items()} for group, by in self.groups.items()},
            "paired": {group: {m: p.to_json() for m, p in by.items()} for group, by in self.paired.items()},
        }

    @staticmethod
    def from_json(data: JsonObject) -> Floors:
        groups = {group: _each(by, GroupEntry.from_json) for group, by in data["groups"].items()}
        paired = {group: _each(by, Paired.from_json) for group, by in data["paired"].items()}
        return Floors(data["reference"], groups, paired)

    @property
    def reference_run(self) -> bool:
        """Whether the reference has a record in some group (else nothing is paired)."""
        return any(self.reference in by_method for by_method in self.groups.values())

    def size(self, group: str) -> int:
        """The group's episodes: the most any method has a record of."""
        return max(entry.results.episodes for entry in self.groups[group].values())


@dataclass(frozen=True)
class ModelCalls:
    """One kind of model call over the runs: how many, how many per episode of the runs that make it, mean
    latency, and calls per episode of each method that makes it (methods call a kind at very different rates:
    VLFM scores every frame, ``drive-nav-plus`` only its representative views)."""

    calls: int
    calls_per_episode: float
    mean_latency_ms: float
    by_method: dict[str, float] = field(default_factory=dict)

    def to_json(self) -> JsonObject:
        """``by_method`` is left out when empty, as reports written before it have it."""
        data = asdict(self)
        if not self.by_method:
            del data["by_method"]
        return data

    @staticmethod
    def from_json(data: JsonObject) -> ModelCalls:
        """Reads reports written before ``by_method`` existed as well (it is then empty)."""
        return ModelCalls(**data)


@dataclass(frozen=True)
class Latency:
    """Median, 90th percentile and mean of per-step latencies, in ms (:func:`drivenav.eval.timings.summary`)."""

    median_ms: float
    p90_ms: float
    mean_ms: float

    @staticmethod
    def from_json(data: JsonObject) -> Latency:
        return Latency(data["median_ms"], data["p90_ms"], data["mean_ms"])


@dataclass(frozen=True)
class ModuleTiming:
    """One row of Table VII: when the module runs, and its latency (timed every step) or its invocation count."""

    invocation: str
    latency: Latency | None = None
    invocations: int | None = None

    def to_json(self) -> JsonObject:
        data: JsonObject = asdict(self.latency) if self.latency else {}
        if self.invocations is not None:
            data["invocations"] = self.invocations
        data["invocation"] = self.invocation
        return data

    @staticmethod
    def from_json(data: JsonObject) -> ModuleTiming:
        latency = Latency.from_json(data) if "median_ms" in data else None
        return ModuleTiming(data["invocation"], latency, data.get("invocations"))


@dataclass(frozen=True)
class ComputeTable:
    """Table VII's agent compute (paper Sec. V-E): one method's timed steps, their compute per step (models
    excluded), and each module's row (:func:`drivenav.eval.timings.runtime_table`)."""

    agent: str
    width: int
    height: int
    episodes: int
    steps: int
    latency: Latency
    modules: dict[str, ModuleTiming]

    def to_json(self) -> JsonObject:
        head = {"agent": self.agent, "width": self.width, "height": self.height, "episodes": self.episodes}
        modules = {name: module.to_json() for name, module in self.modules.items()}
        return {**head, "steps": self.steps, **asdict(self.latency), "modules": modules}

    @staticmethod
    def from_json(data: JsonObject) -> ComputeTable:
        """Also the reader of :func:`~drivenav.eval.timings.runtime_table`'s result."""
        modules = _each(data["modules"], ModuleTiming.from_json)
        size = (data["width"], data["height"])
        return ComputeTable(data["agent"], *size, data["episodes"], data["steps"], Latency.from_json(data), modules)


@dataclass(frozen=True)
class Runtime:
    """Table VII from the runs: agent compute (None when no trace has timings) and model calls by kind."""

    compute: ComputeTable | None
    model_calls: dict[str, ModelCalls]

    def to_json(self) -> JsonObject:
        compute = None if self.compute is None else self.compute.to_json()
        return {"compute": compute, "model_calls": {kind: calls.to_json() for kind, calls in self.model_calls.items()}}

    @staticmethod
    def from_json(data: JsonObject) -> Runtime:
        compute = None if data["compute"] is None else ComputeTable.from_json(data["compute"])
        return Runtime(compute, _each(data["model_calls"], ModelCalls.from_json))


@dataclass(frozen=True)
class Pictures:
    """The report's pictures: per episode id, each method's top-down picture, and one video; paths relative to
    the report's directory. Empty when none were drawn."""

    episodes: dict[str, dict[str, str]] = field(default_factory=dict)
    video: str | None = None

    def to_json(self) -> JsonObject:
        return asdict(self)

    @staticmethod
    def from_json(data: JsonObject | None) -> Pictures:
        return Pictures() if not data else Pictures(data["episodes"], data["video"])


@dataclass(frozen=True)
class ReportModels:
    """The reasoner and detector the methods ran with."""

    reasoner: str
    detector: str


@dataclass(frozen=True)
class AblationReport:
    """``ablations.json``: every method's entry, the Table II comparison, Table VII, and what the runs were; with
    episodes of vocabulary splits (``info["split"]``, benchmark v2), each method per split under ``splits`` (a key
    the file has only then); with ``drive-nav`` among the methods, each method's paired wins and losses against it
    under ``paired`` (likewise); with methods beyond the paper, each against its base under ``beyond`` and Table
    II's comparison with them under ``table_ii_beyond`` (:mod:`drivenav.analysis.beyond`; keys the file has only
    then); with episodes carrying ``info["cross_floor"]`` (benchmark v3), each method per floor group under
    ``floors`` (:class:`Floors`; likewise)."""

    methods: dict[str, MethodEntry]
    table_ii: Comparison
    runtime: Runtime
    episodes: int
    seed: int
    scenes: str | None
    max_steps: int
    models: ReportModels
    commit: str | None
    pictures: Pictures = field(default_factory=Pictures)
    splits: Splits = field(default_factory=dict)
    paired: dict[str, Paired] = field(default_factory=dict)
    beyond: dict[str, PairedEntry] = field(default_factory=dict)
    table_ii_beyond: Comparison | None = None
    floors: Floors | None = None

    def to_json(self) -> JsonObject:
        """The ``ablations.json`` object."""
        data: JsonObject = {
            "methods": {name: entry.to_json() for name, entry in self.methods.items()},
            "table_ii": self.table_ii.to_json(),
            "runtime": self.runtime.to_json(),
            "episodes": self.episodes,
            "seed": self.seed,
            "scenes": self.scenes,
            "max_steps": self.max_steps,
            "models": asdict(self.models),
            "commit": self.commit,
            "pictures": self.pictures.to_json(),
        }
        if self.splits:
            data["splits"] = {name: {m: e.to_json() for m, e in by.items()} for name, by in self.splits.items()}
        if self.paired:
            data["paired"] = {name: paired.to_json() for name, paired in self.paired.items()}
        if self.beyond:
            data["beyond"] = {name: entry.to_json() for name, entry in self.beyond.items()}
        if self.table_ii_beyond is not None:
            data["table_ii_beyond"] = self.table_ii_beyond.to_json()
        if self.floors is not None:
            data["floors"] = self.floors.to_json()
        return data

    @staticmethod
    def from_json(data: JsonObject, source: str | Path = "ablations.json") -> AblationReport:
        """The report :meth:`to_json` wrote; a document of another shape is one :class:`InputError`."""
        try:
            return AblationReport(
                _each(data["methods"], MethodEntry.from_json),
                Comparison.from_json(data["table_ii"]),
                Runtime.from_json(data["runtime"]),
                data["episodes"],
                data["seed"],
                data["scenes"],
                data["max_steps"],
                ReportModels(**data["models"]),
                data["commit"],
                Pictures.from_json(data.get("pictures")),
                {name: _each(by_method, SplitEntry.from_json) for name, by_method in data.get("splits", {}).items()},
                _each(data.get("paired", {}), Paired.from_json),
                _each(data.get("beyond", {}), PairedEntry.from_json),
                Comparison.from_json(data["table_ii_beyond"]) if "table_ii_beyond" in data else None,
                Floors.from_json(data["floors"]) if "floors" in data else None,
            )
        except (KeyError, TypeError, AttributeError, IndexError) as error:
            expected = "an ablations.json written by 'drivenav bench ablations'"
            raise InputError(source, DOCUMENT, expected, f"{type(error).__name__}: {error}") from None
