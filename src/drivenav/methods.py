"""The methods of the paper's tables as presets over the configuration tree: one list, used by the agent registry,
``bench ablations`` and the docs.

Each method is an explorer (``explorer.name``, :mod:`drivenav.agent.explorers`) plus dotted overrides of
:class:`~drivenav.settings.Settings` on top of the paper's defaults: the body's switches (``agent.enrich``,
``agent.verify``) and constants. The explorer's entry may set body switches of its own first (VLFM and the greedy
baseline turn enrichment and verification off); the method's overrides come after. ``drive-nav`` is the defaults
themselves. "Full Directional Reasoning Pipeline" (Tables V, VI) is DRIVE-Nav without prompt enrichment and
cross-frame verification.

Other packages bring methods too: an entry point of group ``drivenav.methods`` names a :class:`Method` or a tuple of
them (a plug-in explorer's rows and ablation variants, e.g. ``farthest-near = "my_pkg.methods:ROWS"``), and an
explorer another package registers (group ``drivenav.explorers``) is a method of its own name unless one of those
rows takes it. A plug-in method whose name a built-in method or reference agent has is ignored with one warning; an
entry that cannot be loaded is refused with its one line when its entry-point name is chosen.
"""

from __future__ import annotations

import logging
from dataclasses import dataclass
from importlib import resources
from typing import Literal, TypeAlias

from drivenav.errors import InputError
from drivenav.plugins import Registry, plugins_of

log = logging.getLogger(__name__)

PaperTable = Literal["I", "II", "V", "VI"]
"""I: comparison with the state of the art (SR / SPL per benchmark); II: analytical comparison; V: directional
components; VI: module ablation."""

_DIRECTIONAL = ("agent.enrich=false", "agent.verify=false")

_PLUS = (
    "explorer.directions.skip_void_events=true",
    "explorer.directions.return_aware=true",
    "explorer.directions.settle_steps=3",
    "explorer.directions.target_check=0.5",
)
"""drive-nav-plus's rules beyond the paper (docs/agent.md "Beyond the paper"), each an ``explorer.directions``
switch."""


def _plus_without(switch: str) -> tuple[str, ...]:
    """drive-nav-plus with the rule ``switch`` off: its ablation row."""
    return tuple(rule for rule in _PLUS if not rule.startswith(f"explorer.directions.{switch}="))


@dataclass(frozen=True)
class Method:
    """One agent variant: its ``--agent`` name, the paper's tables it appears in (none: a method beyond the paper),
    what it is, its overrides, the explorer it runs (``plugin``: one another package registers, a method of its own
    name) and, for a method beyond the paper, the method it is measured against (``base``: the report pairs them)."""

    name: str
    tables: tuple[PaperTable, ...]
    description: str
    overrides: tuple[str, ...] = ()
    explorer: str = "directions"
    plugin: bool = False
    base: str = ""


_METHODS: tuple[Method, ...] = (
    Method(
        "frontier",
        ("VI",),
        "raw frontiers as candidates (no clustering), a 360 deg scan at every decision",
        (*_DIRECTIONAL, "paper.directions.cluster_span_deg=0.0", "explorer.directions.decision_scan=true"),
    ),
    Method(
        "directional",
        ("V", "VI"),
        "the full directional reasoning pipeline (no enrichment, no verification)",
        _DIRECTIONAL,
    ),
    Method("directional-enrich", ("VI",), "directional + prompt enrichment (Sec. IV-B)", ("agent.verify=false",)),
    Method(
        "directional-verify", ("VI",), "directional + cross-frame verification (Sec. IV-C)", ("agent.enrich=false",)
    ),
    Method("drive-nav", ("I", "II", "VI"), "DRIVE-Nav: everything on, the paper's constants"),
    Method(
        "no-weighted-fmm",
        ("V",),
        "directional, uniform FMM speed instead of the weighted field (Eqs. 1-3)",
        (*_DIRECTIONAL, "paper.speed.weighted=false"),
    ),
    Method(
        "no-240",
        ("V",),
        "directional, inspection over the full 360 deg instead of the forward 240 deg",
        (*_DIRECTIONAL, "paper.inspection.restrict_forward=false"),
    ),
    Method(
        "direction-360",
        ("II",),
        "DRIVE-Nav with a full 360 deg scan at every decision",
        ("explorer.directions.decision_scan=true",),
    ),
    Method("nearest-frontier", ("II",), "greedy nearest frontier: no views, no reasoner", explorer="greedy"),
    Method(
        "vlfm",
        ("I", "II"),
        "VLFM (Yokoyama et al. 2024): value map from image-text scores, highest-value frontier",
        explorer="vlfm",
    ),
    Method(
        "apexnav",
        ("I",),
        "ApexNav (Zhang et al. 2025): semantic (TSP) or geometric exploration, target-centric fusion",
        ("paper.speed.weighted=false",),  # ApexNav's paths are A*'s shortest ones, not kept clear of obstacles
        explorer="apexnav",
    ),
    Method(
        "drive-nav-plus",
        (),
        "DRIVE-Nav beyond the paper: settled directions, no void questions, near remainder first, target check",
        _PLUS,
        base="drive-nav",
    ),
    Method(
        "drive-nav-plus-no-void",
        (),
        "drive-nav-plus asking the reasoner after every inspection event",
        _plus_without("skip_void_events"),
        base="drive-nav-plus",
    ),
    Method(
        "drive-nav-plus-no-return",
        (),
        "drive-nav-plus following a turn back to its farthest point, as the paper",
        _plus_without("return_aware"),
        base="drive-nav-plus",
    ),
    Method(
        "drive-nav-plus-no-check",
        (),
        "drive-nav-plus judging a promising new view only at the next decision, as the paper",
        _plus_without("target_check"),
        base="drive-nav-plus",
    ),
    Method(
        "drive-nav-plus-no-settle",
        (),
        "drive-nav-plus starting an inspection event at a direction's first sight, as the paper",
        _plus_without("settle_steps"),
        base="drive-nav-plus",
    ),
)
"""DRIVE-Nav, its baselines / ablations and the peers it is compared with (paper Tables I, II, V, VI), in the order of
the ablation report, then the methods beyond the paper (no table of the paper: ``drive-nav-plus`` and its ablation
rows, each without one rule)."""

FLOORS_OFF = ("drive-nav", "vlfm", "apexnav", "nearest-frontier", "direction-360", "drive-nav-plus")
"""The methods measured with floors off too (docs/floors.md): Table I's, Table II's and drive-nav-plus."""


def _floors_off(method: Method) -> Method:
    """A method with the body's floors off: one planar map, no stairs taken (the method as published)."""
    return Method(
        f"{method.name}-floors-off",
        (),
        f"{method.name} with floors off: one planar map, no stairs taken (as published)",
        (*method.overrides, "agent.floors.enabled=false"),
        method.explorer,
        base=method.name,
    )


METHODS: tuple[Method, ...] = (*_METHODS, *(_floors_off(m) for m in _METHODS if m.name in FLOORS_OFF))
"""Every method: the paper's tables', the methods beyond the paper, then the floors-off rows of :data:`FLOORS_OFF`."""


REFERENCE_AGENTS: dict[str, str] = {
    "oracle": "drivenav.agent.oracle:OracleAgent",  # follows the ground-truth shortest path to the goal
    "random": "drivenav.agent.random_agent:RandomAgent",  # a random walk
}
"""The agents that are not DRIVE-Nav variants, the one list of them: ``--agent`` name -> ``module:Class`` (a class
built from the simulator's set-up alone, imported when a run uses it, so the command line lists the names without
loading agent code). A new reference agent is its module and one line here."""


ALL_METHODS = tuple(method.name for method in METHODS if method.tables)
"""The methods of the paper's tables, in the order ``bench ablations`` runs them by default."""

BEYOND_PAPER = tuple(method.name for method in METHODS if not method.tables)
"""Our methods beyond the paper (``bench ablations --methods`` runs them; the report pairs each with its base)."""

METHOD_NAMES = (*ALL_METHODS, *BEYOND_PAPER)
"""Every method of :data:`METHODS`, in its order."""

PRESETS = "data/configs"  # the --config presets shipped with drivenav, under the package


Rows: TypeAlias = "Method | tuple[Method, ...]"
"""What an entry point of group ``drivenav.methods`` names: one method, or several (a plug-in's rows)."""


def _are_rows(part: object) -> bool:
    """Whether ``part`` is a :class:`Method` or a non-empty tuple of them."""
    if isinstance(part, tuple):
        return bool(part) and all(isinstance(method, Method) for method in part)
    return isinstance(part, Method)


BUILT_IN_METHODS = {"drivenav": "drivenav.methods:METHODS"}
"""drivenav's own methods as one entry (also declared in pyproject.toml): :data:`METHODS`."""

METHOD_ROWS: Registry[Rows] = Registry(
    "drivenav.methods", BUILT_IN_METHODS, _are_rows, "method (drivenav.methods.Method) or tuple of methods", "--agent"
)
"""Every entry of methods: drivenav's own (:data:`METHODS`), then other packages' by entry-point name."""

_WARNED: set[tuple[str, str]] = set()
"""The (entry point, method) clashes already warned about: one warning per process."""


def _rows_of(part: Rows) -> tuple[Method, ...]:
    return part if isinstance(part, tuple) else (part,)


def _plugin_rows() -> dict[str, Method]:
    """The methods other packages declare (group ``drivenav.methods``) by name, their entries loaded in entry-point
    order: a name taken by a built-in method, a reference agent or an earlier entry is ignored with one warning, an
    entry that cannot be loaded is left out here (:func:`method_named` refuses it when its name is chosen)."""
    taken = {*METHOD_NAMES, *REFERENCE_AGENTS}
    rows: dict[str, Method] = {}
    for entry in METHOD_ROWS.names:
        if not METHOD_ROWS.is_plugin(entry):
            continue
        try:
            part = METHOD_ROWS.get(entry)
        except InputError as error:
            log.debug("drivenav: %s", error)
            continue
        for method in _rows_of(part):
            if method.name in taken or method.name in rows:
                _warn_taken(entry, method.name)
                continue
            rows[method.name] = method
    return rows


def _warn_taken(entry: str, name: str) -> None:
    if (entry, name) in _WARNED:
        return
    _WARNED.add((entry, name))
    point = METHOD_ROWS.declared[entry].entry_point
    log.warning("drivenav: method %s of method plug-in %s is ignored: the name is taken", name, point)


def _broken_entries(rows: dict[str, Method]) -> list[str]:
    """The plug-in entries of methods that cannot be loaded, by entry-point name (chosen by that name, each is
    refused with its one line); an entry whose name one of ``rows`` has is not one."""
    broken = []
    for entry in METHOD_ROWS.names:
        if METHOD_ROWS.is_plugin(entry) and entry not in rows:
            try:
                METHOD_ROWS.get(entry)
            except InputError:
                broken.append(entry)
    return broken


def _plugin_explorer_methods(taken: set[str]) -> dict[str, Method]:
    """The explorers other packages register (by entry-point name, nothing imported), each a method of its own
    name; a name in ``taken`` (a method, reference agent or plug-in row) stays theirs."""
    return {
        p.name: Method(p.name, (), f"the {p.name} explorer of {p.source}", explorer=p.name, plugin=True)
        for p in plugins_of("drivenav.explorers")
        if p.name not in taken
    }


def plugin_methods() -> dict[str, Method]:
    """Every method other packages bring, by name: their rows (group ``drivenav.methods``), then their explorers'
    own methods."""
    rows = _plugin_rows()
    return {**rows, **_plugin_explorer_methods({*METHOD_NAMES, *REFERENCE_AGENTS, *rows})}


def method_named(name: str) -> Method | None:
    """The method called ``name`` (an ``--agent`` name), or None for a reference agent or an unknown name; the name of
    a plug-in entry of methods that cannot be loaded is its one :class:`InputError` line."""
    found = next((m for m in METHODS if m.name == name), None) or plugin_methods().get(name)
    if found is None and METHOD_ROWS.is_plugin(name) and name not in REFERENCE_AGENTS:
        METHOD_ROWS.get(name)  # a broken entry: its one line (a loaded one holds no method of its entry's name)
    return found


def agent_names() -> list[str]:
    """Every ``--agent`` name: the methods of the paper's tables, the reference agents, the methods other packages
    bring, and the names of plug-in entries of methods that cannot be loaded (chosen, each is refused in one line)."""
    plugins = plugin_methods()
    return sorted({*REFERENCE_AGENTS, *METHOD_NAMES, *plugins, *_broken_entries(plugins)})


def preset_names() -> list[str]:
    """The ``--config`` presets shipped with drivenav."""
    folder = resources.files("drivenav").joinpath(PRESETS)
    return sorted(item.name[: -len(".yaml")] for item in folder.iterdir() if item.name.endswith(".yaml"))
