"""Registries open to other packages: Python entry points, one group per kind of part.

drivenav's own parts are declared twice over, on purpose: as entry points in ``pyproject.toml`` (what an installed
wheel advertises, and the model a plug-in copies) and in the ``built_ins`` table each registry is given here (what a
source checkout without installed metadata still finds, e.g. the Habitat venv's ``.pth`` or ``PYTHONPATH=src``);
``tests/test_plugins.py`` keeps the two equal for every group. Another package adds a part with one entry point in its
own metadata, e.g. ``[project.entry-points."drivenav.explorers"] mine = "my_pkg.explorer:EXPLORER"``.

The groups and the object each entry point names: ``drivenav.explorers`` an
:class:`~drivenav.agent.config.ExplorerEntry`; ``drivenav.worlds`` a :class:`~drivenav.worlds.entry.WorldEntry`;
``drivenav.reasoners``, ``drivenav.grounders`` and ``drivenav.scorers`` a
:class:`~drivenav.semantics.registry.Backend`; ``drivenav.robot_sources`` a
:class:`~drivenav.robot.registry.SourceEntry` and ``drivenav.robot_motions`` a
:class:`~drivenav.robot.registry.MotionEntry`. docs/extending.md walks through each.

Names are listed without importing anything (``--help`` stays fast); a part is imported when it is used. A plug-in
that cannot be imported, or whose object is of the wrong kind, is one :class:`~drivenav.errors.InputError` line
naming the plug-in and its entry point, raised only when that name is used: the built-in names never depend on a
plug-in. A plug-in that takes a built-in name is ignored with one warning line naming both: the built-in keeps it.
Parts that add command-line options (worlds, robot parts) are loaded when the command line is built, each that
loads (:meth:`Registry.usable`); a broken one adds no option and is refused, as above, when it is chosen.
"""

from __future__ import annotations

import argparse
import importlib
import logging
from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass
from functools import cached_property
from importlib.metadata import entry_points
from typing import Generic, TypeAlias, TypeVar, cast

from drivenav.errors import InputError, one_line

log = logging.getLogger(__name__)

T = TypeVar("T")

GROUPS = (
    "drivenav.explorers",
    "drivenav.worlds",
    "drivenav.reasoners",
    "drivenav.grounders",
    "drivenav.segmenters",
    "drivenav.scorers",
    "drivenav.robot_sources",
    "drivenav.robot_motions",
    "drivenav.methods",
)
"""Every entry-point group drivenav reads, one per kind of part."""


@dataclass(frozen=True)
class Declared:
    """One declared part: its name, the ``module:attribute`` it loads, and who declared it (``drivenav`` or the
    distribution of a plug-in)."""

    name: str
    value: str
    source: str

    @property
    def entry_point(self) -> str:
        return f"{self.name} = {self.value!r} of {self.source}"


def plugins_of(group: str) -> list[Declared]:
    """The parts other packages declare in ``group``, by name (drivenav's own metadata left out: the built-ins)."""
    found = []
    for point in sorted(entry_points(group=group), key=lambda p: p.name):
        source = point.dist.name if point.dist is not None else "an unknown distribution"
        if source != "drivenav":
            found.append(Declared(point.name, point.value, source))
    return found


def load_object(value: str) -> object:
    """The object ``module:attribute`` (dotted attributes allowed) names, imported now."""
    module, _, attribute = value.partition(":")
    found: object = importlib.import_module(module)
    for part in attribute.split(".") if attribute else ():
        found = getattr(found, part)
    return found


class Registry(Generic[T]):
    """The parts of one entry-point group by name: drivenav's own first (in ``built_ins`` order), then plug-ins by
    name. ``accepts`` says whether a loaded object is a part of this kind; ``option`` is the command-line option
    (or setting) that names one, for the error lines. ``named``, for parts that carry their own name (an explorer's
    settings section, a world's ``run.json`` record), gives it: a part registered under another name is broken."""

    def __init__(
        self,
        group: str,
        built_ins: Mapping[str, str],
        accepts: Callable[[object], bool],
        what: str,
        option: str,
        named: Callable[[T], str] | None = None,
    ) -> None:
        if group not in GROUPS:
            raise ValueError(f"unknown entry-point group {group}")
        self.group = group
        self.built_ins = dict(built_ins)
        self.accepts = accepts
        self.what = what
        self.option = option
        self.named = named
        self._loaded: dict[str, T] = {}

    @cached_property
    def declared(self) -> dict[str, Declared]:
        """Every declared part by name (nothing imported): the built-ins, then the plug-ins' entry points."""
        found = {name: Declared(name, value, "drivenav") for name, value in self.built_ins.items()}
        for plugin in plugins_of(self.group):
            if plugin.name in found:
                log.warning(
                    "drivenav: %s plug-in %s is ignored: the name is taken by %s",
                    self.what,
                    plugin.entry_point,
                    found[plugin.name].entry_point,
                )
                continue
            found[plugin.name] = plugin
        return found

    @property
    def names(self) -> tuple[str, ...]:
        return tuple(self.declared)

    def is_plugin(self, name: str) -> bool:
        declared = self.declared.get(name)
        return declared is not None and declared.source != "drivenav"

    def get(self, name: str) -> T:
        """The part called ``name``, imported and checked; an unknown name, or a plug-in that cannot be loaded, is
        one :class:`InputError` line."""
        if name in self._loaded:
            return self._loaded[name]
        declared = self.declared.get(name)
        if declared is None:
            raise InputError("command line", self.option, f"one of {', '.join(self.names)}", name)
        try:
            part = load_object(declared.value)
        except Exception as error:
            raise self.broken(name, one_line(error)) from None
        if not self.accepts(part):
            raise self.broken(name, f"{type(part).__name__}, not {self.what}")
        loaded = cast(T, part)  # ``accepts`` checked its kind
        if self.named is not None and self.named(loaded) != name:
            raise self.broken(name, f"an entry named {self.named(loaded)!r}")
        self._loaded[name] = loaded
        return loaded

    def usable(self) -> dict[str, T]:
        """Every part that loads, by name, imported now (what the command line's options are built from): a broken
        plug-in is left out here and refused with its one line when it is named."""
        found = {}
        for name in self.names:
            try:
                found[name] = self.get(name)
            except InputError as error:
                log.debug("drivenav: %s", error)
        return found

    def broken(self, name: str, why: str) -> InputError:
        """The one line for the declared part ``name`` that cannot serve: why, and its entry point."""
        declared = self.declared[name]
        article = "an" if self.what[:1] in ("a", "e", "i", "o", "u") else "a"
        expected = f"{article} {self.what} that can be loaded (entry point {self.group}: {declared.entry_point})"
        return InputError(f"plug-in {declared.name}", self.option, expected, why)


OptionAdder: TypeAlias = Callable[[argparse._ArgumentGroup], None]
"""How a part adds its own options to a command's option group (a world's to ``--env``'s, a robot part's)."""


def no_options(group: argparse._ArgumentGroup) -> None:
    """A part with no options of its own."""


def refuse_options(args: argparse.Namespace, flags: Sequence[str], expected: str) -> None:
    """A part's own command-line options (``flags``, e.g. ``--bag``) given in ``args`` while another part of its
    kind is chosen: one :class:`InputError` line saying when the option applies (``expected``)."""
    for flag in flags:
        value = getattr(args, flag.lstrip("-").replace("-", "_"), None)
        if value is not None:
            raise InputError("command line", flag, expected, str(value))
