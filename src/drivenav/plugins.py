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

A plug-in's code runs behind one guard (:meth:`Registry.guard`): anything it raises -- ``SystemExit`` and a
``KeyboardInterrupt`` of its own included -- is the one line naming the plug-in, its entry point and its package. Its
command-line options are tried on a scratch copy of the command's parser first (:func:`add_options_of`): options that
clash with the command's (``--scenes``, ``-h``), that every run would need (a positional, a required option), or an
``add_options`` that raises, leave the command as it is, and choosing the plug-in is the line naming why
(:meth:`Registry.chosen`). A real Ctrl-C or SIGTERM is told from a plug-in's own ``KeyboardInterrupt`` by the handler
that marks it (:func:`handle_stop_signals`): it still stops whatever runs.
"""

from __future__ import annotations

import argparse
import importlib
import logging
import signal
import threading
from collections.abc import Callable, Iterator, Mapping, Sequence
from contextlib import contextmanager
from dataclasses import dataclass
from functools import cached_property
from importlib.metadata import entry_points
from types import FrameType, TracebackType
from typing import Any, Generic, TypeAlias, TypeVar, cast

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


_STOPPED_BY_SIGNAL = False
"""Whether this process received a stop signal (Ctrl-C, SIGTERM) through :func:`_stop`."""


def _stop(signum: int, frame: FrameType | None) -> None:
    """The handler of a stop signal (Ctrl-C, SIGTERM): marks the stop as real, then raises ``KeyboardInterrupt``."""
    global _STOPPED_BY_SIGNAL
    _STOPPED_BY_SIGNAL = True
    raise KeyboardInterrupt


def handle_stop_signals() -> None:
    """Ctrl-C and SIGTERM (a scheduler's or ``kill``'s stop) raise ``KeyboardInterrupt``, marked as real: a
    plug-in's own ``KeyboardInterrupt`` is then its failure, never a stop (the command line's handlers)."""
    global _STOPPED_BY_SIGNAL
    _STOPPED_BY_SIGNAL = False
    signal.signal(signal.SIGINT, _stop)
    signal.signal(signal.SIGTERM, _stop)


@contextmanager
def stop_signals_marked() -> Iterator[None]:
    """Ctrl-C marked as real while inside (a run started by a library caller, not the command line): where Python's
    own handler is in place, in the main thread; another handler (the command line's, a caller's) is left alone."""
    if threading.current_thread() is not threading.main_thread():
        yield
        return
    if signal.getsignal(signal.SIGINT) is not signal.default_int_handler:
        yield
        return
    previous = signal.signal(signal.SIGINT, _stop)
    try:
        yield
    finally:
        signal.signal(signal.SIGINT, previous)


def is_part_failure(error: BaseException) -> bool:
    """Whether ``error``, caught around a part's code, is its failure: an ``Exception``, a ``SystemExit``, or a
    ``KeyboardInterrupt`` no stop signal raised (a real Ctrl-C stops the command instead)."""
    if isinstance(error, KeyboardInterrupt):
        return not _STOPPED_BY_SIGNAL
    return isinstance(error, (Exception, SystemExit))


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
        _REGISTRIES.append(self)

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
        except BaseException as error:
            if not (isinstance(error, Exception) or (self.is_plugin(name) and is_part_failure(error))):
                raise
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

    def chosen(self, args: argparse.Namespace, name: str) -> T:
        """The part ``name`` chosen on a command line parsed into ``args``: a plug-in whose options that command
        refused (:func:`add_options_of`) is the line saying why; else :meth:`get`."""
        refused = _refusals(args).get(self._key(name))
        if refused is not None:
            raise refused
        return self.get(name)

    def offered(self, args: argparse.Namespace) -> dict[str, T]:
        """Every part that loads and that the command line parsed into ``args`` did not refuse, by name."""
        refused = _refusals(args)
        return {name: part for name, part in self.usable().items() if self._key(name) not in refused}

    @contextmanager
    def guard(self, name: str, step: str) -> Iterator[None]:
        """Runs the part ``name``'s ``step`` (``build``, ``check``, ``connect``, ``episodes``, ...): for a plug-in,
        anything its code raises -- ``SystemExit`` and its own ``KeyboardInterrupt`` included -- is the one
        :class:`InputError` line naming it and its entry point; its own :class:`InputError` (an option of its own
        that does not fit) is kept as it is. A built-in part's errors are drivenav's own, left as they are."""
        if not self.is_plugin(name):
            yield
            return
        try:
            yield
        except InputError:
            raise
        except BaseException as error:
            if not is_part_failure(error):
                raise
            raise self.broken(name, one_line(error), f"whose {step} works") from None

    def broken(self, name: str, why: str, role: str = "that can be loaded") -> InputError:
        """The one line for the declared part ``name`` that cannot serve: why, what it should be (``role``: loads,
        its step works), and its entry point."""
        declared = self.declared[name]
        article = "an" if self.what[:1] in ("a", "e", "i", "o", "u") else "a"
        expected = f"{article} {self.what} {role} (entry point {self.group}: {declared.entry_point})"
        return InputError(f"plug-in {declared.name}", self.option, expected, why)

    def loaded_plugins(self) -> list[Declared]:
        """The plug-ins of this group imported in this process."""
        return [self.declared[name] for name in self._loaded if self.is_plugin(name)]

    def _key(self, name: str) -> str:
        return f"{self.group} {name}"


_REGISTRIES: list[Registry[Any]] = []
"""Every registry made in this process (each adds itself): where :func:`plugin_in_traceback` looks."""


def plugin_in_traceback(error: BaseException, chosen: Mapping[str, str] | None = None) -> str:
    """The loaded plug-in whose code raised ``error`` (the innermost frame of its traceback in a plug-in's package),
    as ``plug-in NAME, entry point GROUP: NAME = 'module:attribute' of DIST``; empty when no plug-in's code did.
    ``chosen`` (entry-point group -> name: the parts a run uses) narrows it to those, where a package declares
    several parts in one module."""
    modules = [_frame_module(frame) for frame, _ in _frames(error.__traceback__)]
    for module in reversed(modules):
        found = _plugin_of_module(module, chosen)
        if found:
            return found
    return ""


def _frames(tb: TracebackType | None) -> Iterator[tuple[FrameType, int]]:
    while tb is not None:
        yield tb.tb_frame, tb.tb_lineno
        tb = tb.tb_next


def _frame_module(frame: FrameType) -> str:
    return str(frame.f_globals.get("__name__", ""))


def _plugin_of_module(module: str, chosen: Mapping[str, str] | None) -> str:
    """The loaded plug-in (of ``chosen`` where given) whose package holds ``module`` (the one declared nearest to it
    where a package has several), described; empty for drivenav's own modules and modules of no plug-in."""
    package = module.split(".")[0]
    if not package or package == "drivenav":
        return ""
    best: tuple[int, str] = (0, "")
    for registry in _REGISTRIES:
        for declared in registry.loaded_plugins():
            if chosen is not None and chosen.get(registry.group) != declared.name:
                continue
            declared_module = declared.value.partition(":")[0]
            if declared_module.split(".")[0] != package:
                continue
            shared = _shared_parts(module, declared_module)
            if shared > best[0]:
                best = (shared, f"plug-in {declared.name}, entry point {registry.group}: {declared.entry_point}")
    return best[1]


def _shared_parts(one: str, other: str) -> int:
    """How many leading dotted parts two module names share."""
    count = 0
    for a, b in zip(one.split("."), other.split("."), strict=False):
        if a != b:
            break
        count += 1
    return count


OptionAdder: TypeAlias = Callable[[argparse._ArgumentGroup], None]
"""How a part adds its own options to a command's option group (a world's to ``--env``'s, a robot part's)."""


def no_options(group: argparse._ArgumentGroup) -> None:
    """A part with no options of its own."""


REFUSALS = "refused_plugins"
"""The parsed command line's record of the plug-ins whose options it refused (registry key -> the line)."""


def _refusals(args: argparse.Namespace) -> dict[str, InputError]:
    found: dict[str, InputError] = getattr(args, REFUSALS, None) or {}
    return found


def add_options_of(
    parser: argparse.ArgumentParser,
    group: argparse._ArgumentGroup,
    registry: Registry[Any],
    adders: Mapping[str, OptionAdder],
) -> None:
    """Each part's own options (``adders``, by name) in ``group`` of ``parser``; call it once the command's other
    options are in. A built-in's are added as they are. A plug-in's are tried on a scratch copy of the parser first:
    options that clash with the command's (an option string or a destination it has, ``-h`` included), that every
    run would need (a positional or required one), or an ``add_options`` that raises leave ``parser`` untouched, and
    choosing the plug-in is then the one line naming why (:meth:`Registry.chosen`)."""
    for name, add in adders.items():
        if not registry.is_plugin(name):
            add(group)
            continue
        why = _try_options(parser, group, add)
        if why:
            refusal = registry.broken(name, why, "whose options fit the command line")
            log.debug("drivenav: %s", refusal)
            refused = dict(parser.get_default(REFUSALS) or {})
            refused[registry._key(name)] = refusal
            parser.set_defaults(**{REFUSALS: refused})


def _try_options(parser: argparse.ArgumentParser, group: argparse._ArgumentGroup, add: OptionAdder) -> str:
    """Adds ``add``'s options to ``group`` where they fit ``parser`` (tried on a scratch copy first); why they do
    not (empty when added)."""
    scratch = argparse.ArgumentParser(add_help=False)
    scratch._option_string_actions = dict(parser._option_string_actions)
    trial = scratch.add_argument_group(group.title)
    try:
        add(trial)
    except argparse.ArgumentError as error:  # an option string the command has
        return str(error)
    except BaseException as error:
        if not is_part_failure(error):
            raise
        return f"add_options: {one_line(error)}"
    taken = {action.dest for action in parser._actions} | set(parser._defaults)
    for action in trial._group_actions:
        shown = "/".join(action.option_strings) or action.dest
        if not action.option_strings or action.required:
            return f"option {shown}: a positional or required option (every run would need it)"
        if action.dest in taken:
            return f"option {shown}: its destination {action.dest!r} is the command's"
    clash = taken & set(scratch._defaults)
    if clash:
        return f"a default for {sorted(clash)[0]!r}, which is the command's"
    for action in trial._group_actions:
        group._add_action(action)
    parser.set_defaults(**scratch._defaults)
    return ""


def refuse_options(args: argparse.Namespace, flags: Sequence[str], expected: str) -> None:
    """A part's own command-line options (``flags``, e.g. ``--bag``) given in ``args`` while another part of its
    kind is chosen: one :class:`InputError` line saying when the option applies (``expected``)."""
    for flag in flags:
        value = getattr(args, flag.lstrip("-").replace("-", "_"), None)
        if value is not None:
            raise InputError("command line", flag, expected, str(value))
