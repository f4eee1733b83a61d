"""The configuration tree: sensor and body, mapper, the paper's constants, agent switches, models, run.

Built in layers with OmegaConf structured configs (as habitat-lab builds its own): the defaults (every value the
paper's), then the ``--agent`` method's preset (:mod:`drivenav.methods`: its explorer, the body switches the
explorer's entry sets, then the method's own overrides), then each ``--config NAME_OR_FILE`` in
order (a preset shipped in ``drivenav/data/configs/`` or a YAML file), then the dedicated command-line options that
were given (``--seed``, ``--max-steps``, ``--reasoner``, ...), then each ``--set KEY=VALUE`` in order.
``drivenav config show`` prints the result; ``run.json`` records it. A wrong key, type or value is one
:class:`~drivenav.errors.InputError` line naming the key, what was given and what is allowed.

Units: lengths in metres, angles in degrees (the ``*_deg`` fields; :class:`~drivenav.paper.DriveNavConfig` reads
them in radians through properties). The step budget is ``sim.max_steps`` (one value, the world's and the agent's).
``mapping`` holds only the mapper's own tuning (:class:`~drivenav.mapping.config.MapTuning`); depth range, camera
height, agent radius and grid resolution follow from ``sim`` (:meth:`~drivenav.mapping.config.MappingConfig.from_sim`),
so the mapper always matches the sensor.

``explorer`` holds ``explorer.name`` (the exploration method, :mod:`drivenav.agent.explorers`) and the section of
the chosen explorer only (``explorer.directions`` for ``drive-nav``; ``explorer.<key>``, its key from its name by
:func:`~drivenav.agent.explorers.settings_key`), plus the section of any other explorer whose keys the ``--agent``
method's overrides set: its entry's config class with the source's constants as defaults, its declared ranges
checked (:func:`~drivenav.ranges.check_declared`). The section's type is made when an explorer is chosen
(:func:`explorer_settings_type`), so an installed plug-in is imported and configured only when it is chosen, and
anything its code raises then is its one line (:meth:`~drivenav.plugins.Registry.broken`). The explorer is found
before the layers are merged (the last layer that sets ``explorer.name``); a layer setting a key of another
explorer's section is refused in one line. A tree read back (``run.json``, :func:`settings_from_dict`) drops the
sections of other explorers: a run made when every installed explorer had a section reads as one made now.
"""

from __future__ import annotations

import dataclasses
import json
from collections.abc import Iterator, Mapping, Sequence
from dataclasses import dataclass, field
from functools import cache
from importlib import resources
from pathlib import Path
from typing import Any, ClassVar

import yaml
from omegaconf import DictConfig, ListConfig, OmegaConf
from omegaconf.errors import OmegaConfBaseException

from drivenav.agent.config import AgentConfig
from drivenav.agent.explorers import DEFAULT_EXPLORER, EXPLORERS, explorer_entry, explorer_key, section_keys
from drivenav.errors import InputError, one_line
from drivenav.jsonstream import JsonObject
from drivenav.mapping.config import MapTuning
from drivenav.methods import PRESETS, agent_names, method_named, preset_names
from drivenav.paper import DriveNavConfig
from drivenav.plugins import Declared
from drivenav.ranges import MAX_GRID_SIDE, Range, SettingError, check_declared, check_ranges, check_rule
from drivenav.semantics.model_spec import DETECTOR_REGIMES, DTYPES, ModelSpec
from drivenav.semantics.registry import GROUNDER_BACKENDS, REASONER_BACKENDS, SCORER_BACKENDS, SEGMENTER_BACKENDS
from drivenav.types import SimConfig
from drivenav.validation import check_unique_keys, yaml_problem

YAML_HEADER = """\
# drivenav configuration: load it back with --config FILE, change one value with --set KEY=VALUE.
# Units: lengths in metres, angles in degrees (*_deg), sim.max_steps in actions (the step budget).
# sim: sensor and body (Habitat ObjectNav); mapping: the mapper's tuning (its depth range, camera height,
# agent radius and grid resolution come from sim); paper: DRIVE-Nav's constants (Sec. IV); agent: the body's
# switches (Table VI) and tuning; explorer: the exploration method (explorer.name) and each explorer's constants;
# models: reasoner, detector and scorer; run: the agent's name and the run seed.
"""


@dataclass(frozen=True)
class RunSettings:
    """Which agent runs (``--agent``) and the run's seed (``--seed``); the step budget is ``sim.max_steps``."""

    agent: str = "drive-nav"
    seed: int = 0

    def __post_init__(self) -> None:
        check_ranges(self, {"seed": Range(0, integer=True)})


@dataclass(frozen=True)
class ExplorerSettings:
    """The exploration method an agent runs (``explorer.name``) and, in the type :func:`explorer_settings_type`
    makes for it, the sections of :attr:`explorers` (the chosen one first)."""

    explorers: ClassVar[tuple[str, ...]] = ()
    name: str = DEFAULT_EXPLORER

    def __reduce__(self) -> tuple[Any, tuple[tuple[str, ...], str, dict[str, object]]]:
        """Rebuilt in another process (worker processes, Ray), where the type is made anew."""
        sections = {f.name: getattr(self, f.name) for f in dataclasses.fields(self) if f.name != "name"}
        return _explorer_settings, (self.explorers, self.name, sections)


@cache
def explorer_settings_type(explorers: tuple[str, ...] = (DEFAULT_EXPLORER,)) -> type[ExplorerSettings]:
    """:class:`ExplorerSettings` with the section of each of ``explorers`` (made once per process for them): its
    entry's config class with its defaults, under its key (:func:`~drivenav.agent.explorers.explorer_key`). An
    explorer that cannot serve as a section is one :class:`~drivenav.errors.InputError` line
    (:func:`section_class`)."""
    sections: list[tuple[str, type, Any]] = []
    for name in explorers:
        config = section_class(name)
        sections.append((explorer_key(name), config, field(default_factory=config)))
    made = dataclasses.make_dataclass(
        "ExplorerSettings",
        sections,
        bases=(ExplorerSettings,),
        frozen=True,
        namespace={"explorers": explorers},
    )
    made.__module__ = __name__
    return made


def section_class(name: str) -> type:
    """The config class of the explorer ``name``, checked to serve as its settings section: a dataclass whose
    defaults make a section that OmegaConf can hold, within their declared ranges. A plug-in that cannot is one
    :class:`~drivenav.errors.InputError` line naming it and its entry point; whatever its code raises here
    (``SystemExit`` and ``KeyboardInterrupt`` included) is that line, never the command's end."""
    entry = explorer_entry(name)
    config = entry.config
    if not (isinstance(config, type) and dataclasses.is_dataclass(config)):
        raise EXPLORERS.broken(name, f"a config {config!r} that is not a dataclass")
    try:
        defaults = config()
        OmegaConf.structured(defaults)
        check_declared(defaults)
    except BaseException as error:  # the plug-in's own code: configuring it must not end the command
        raise EXPLORERS.broken(name, f"its config's defaults: {one_line(error)}") from None
    return config


def _explorer_settings(
    explorers: tuple[str, ...] = (DEFAULT_EXPLORER,),
    name: str | None = None,
    sections: Mapping[str, object] | None = None,
) -> ExplorerSettings:
    """The ``explorer`` section of the tree: ``name`` (the first of ``explorers`` unless given) and the section of
    each of ``explorers`` (defaults for those not given)."""
    return explorer_settings_type(explorers)(name=name or explorers[0], **(sections or {}))


def explorers_of(name: str, agent: str) -> tuple[str, ...]:
    """The explorers whose sections a tree holds: the chosen one (``name``), then each other explorer whose keys the
    overrides of the method ``agent`` set (none for drivenav's methods today)."""
    keys = section_keys()
    method = method_named(agent)
    named = (override.split("=", 1)[0].split(".") for override in (method.overrides if method else ()))
    others = (keys[parts[1]] for parts in named if len(parts) > 2 and parts[0] == "explorer" and parts[1] in keys)
    return tuple(dict.fromkeys((name, *others)))


@dataclass(frozen=True)
class Settings:
    """Everything an evaluation is set up with (the paper's values by default).

    Each section checks its own numbers where they are declared (:mod:`drivenav.ranges`); the tree checks the rules
    that span sections and the names that pick a method or a model."""

    sim: SimConfig = field(default_factory=SimConfig)
    mapping: MapTuning = field(default_factory=MapTuning)
    paper: DriveNavConfig = field(default_factory=DriveNavConfig)
    agent: AgentConfig = field(default_factory=AgentConfig)
    explorer: ExplorerSettings = field(default_factory=_explorer_settings)
    models: ModelSpec = field(default_factory=ModelSpec)
    run: RunSettings = field(default_factory=RunSettings)

    def __post_init__(self) -> None:
        sim, mapping = self.sim, self.mapping
        largest_map = MAX_GRID_SIDE * sim.grid_resolution
        rules = (
            (
                "mapping.min_obstacle_height",
                mapping.min_obstacle_height < sim.agent_height,
                "less than sim.agent_height (the top of the obstacle band)",
            ),
            (
                "mapping.max_size",
                mapping.max_size <= largest_map,
                f"at most {MAX_GRID_SIDE} cells of sim.grid_resolution a side ({largest_map:g} m): a grid that fits",
            ),
            (
                "sim.max_depth",
                sim.max_depth <= mapping.max_size / 2.0,
                f"at most half of mapping.max_size ({mapping.max_size / 2.0:g} m): the sensor's reach fits the map",
            ),
            *self._explorer_rules(),
        )
        for key, holds, expected in rules:
            check_rule(self, key, holds, expected)
        choices = (  # key, allowed names, the option that sets it
            ("run.agent", agent_names(), "--agent"),
            ("models.reasoner", REASONER_BACKENDS.names, "--reasoner"),
            ("models.detector", GROUNDER_BACKENDS.names, "--detector"),
            ("models.segmenter", SEGMENTER_BACKENDS.names, "--segmenter"),
            ("models.scorer", SCORER_BACKENDS.names, "--scorer"),
            ("models.dtype", DTYPES, "--dtype"),
            ("models.detector_regime", DETECTOR_REGIMES, "--detector-regime"),
            ("explorer.name", EXPLORERS.names, "--set explorer.name=NAME"),
        )
        for key, names, option in choices:
            section, name = key.split(".")
            chosen = getattr(getattr(self, section), name)
            check_rule(self, key, chosen in names, f"one of {', '.join(names)} (the {option} option)")

    def _explorer_rules(self) -> list[tuple[str, bool, str]]:
        """The rules each explorer's entry states between its section and the rest of the tree (VLFM's frontier
        radius within the sensor's reach), keyed ``explorer.<name>.<key>``."""
        rules = []
        for name in self.explorer.explorers:
            key = explorer_key(name)
            section = getattr(self.explorer, key)
            try:  # the plug-in's own code: a rule that raises is its one line
                rules += [
                    (f"explorer.{key}.{k}", bool(h), str(w))
                    for k, h, w in explorer_entry(name).rules(section, self.sim)
                ]
            except BaseException as error:
                raise EXPLORERS.broken(name, f"its rules: {one_line(error)}") from None
        return rules


def explorer_section(settings: Settings, name: str) -> object:
    """The settings section of the explorer ``name`` (its entry's defaults when the tree holds none: an explorer
    other than the chosen one)."""
    if name in settings.explorer.explorers:
        return getattr(settings.explorer, explorer_key(name))
    return explorer_entry(name).config()


def load_settings(
    agent: str | None = None,
    *,
    configs: Sequence[str] = (),
    overrides: Sequence[str] = (),
    options: Mapping[str, object] | None = None,
) -> Settings:
    """Defaults, then the method preset of ``agent``, then ``configs``, then ``options`` (dotted key -> value, from
    dedicated command-line options), then ``overrides`` (see module docstring)."""
    method = None if agent is None else _method_layer(agent)
    layers = [] if method is None else [(method, "--agent")]
    for config in configs:
        layer = _config_layer(config)
        if method is not None:
            _check_same_method(layer, config, method)
        layers.append((layer, config))
    layers += [(_option_layer(key, value), "command line") for key, value in (options or {}).items()]
    layers += [(_override_layer(override), "--set") for override in overrides]
    return _settings_of(layers)


def _settings_of(layers: Sequence[tuple[DictConfig, str]]) -> Settings:
    """The defaults with each of ``layers`` (a layer and its source, for the error lines) merged over them in
    order, the explorer's sections those of the explorer the last layer naming one chooses."""
    name = _last_given(layers, "explorer", "name", DEFAULT_EXPLORER)
    explorers = explorers_of(_chosen(name), _last_given(layers, "run", "agent", RunSettings.agent))
    defaults = _defaults(explorers)
    tree = defaults
    for given, source in layers:
        layer = _held_layer(given, explorers, source)
        tree = _merge(tree, layer, source, defaults)
    try:
        return _resolve(tree, explorers)
    except InputError as error:
        raise _from_layer(error, layers) from None


def _from_layer(error: InputError, layers: Sequence[tuple[DictConfig, str]]) -> InputError:
    """``error``, found once the layers were merged (a value outside its range), named by the source of the last
    of ``layers`` that gave its key a value (the ``--config`` file, ``--set``, an option) rather than by the merged
    ``settings``; as it is when no layer gave it one (a default, or the key of a whole section)."""
    if error.source != "settings":
        return error
    for layer, source in reversed(layers):
        if OmegaConf.select(layer, error.field, default=None, throw_on_resolution_failure=False) is not None:
            return InputError(source, error.field, error.expected, error.got)
    return error


def _last_given(layers: Sequence[tuple[DictConfig, str]], section: str, key: str, default: str) -> str:
    """The value the last of ``layers`` that sets ``section.key`` gives it (``default`` when none does), as text:
    which explorer and method the tree is made for, before any layer is merged."""
    found = default
    for layer, _ in layers:
        node = layer.get(section) if section in layer else None
        value = node.get(key) if isinstance(node, DictConfig) and key in node else None
        if value is not None and not isinstance(value, DictConfig | ListConfig):
            found = str(value)
    return found


def _chosen(name: str) -> str:
    """``name`` when it is a declared explorer, else the one line that says which are."""
    if name not in EXPLORERS.names:
        expected = f"one of {', '.join(EXPLORERS.names)} (the --set explorer.name=NAME option)"
        raise InputError("settings", "explorer.name", expected, name)
    return name


def _defaults(explorers: tuple[str, ...]) -> DictConfig:
    """The defaults' tree with the sections of ``explorers``: what each layer is merged over, and what names the
    keys and types a layer may give."""
    return _writable(OmegaConf.structured(_default_settings(explorers)))


def _default_settings(explorers: tuple[str, ...]) -> Settings:
    """The defaults with the sections of ``explorers``."""
    return Settings(explorer=_explorer_settings(explorers))


def _held_layer(layer: DictConfig, explorers: tuple[str, ...], source: str) -> DictConfig:
    """``layer`` less the sections of declared explorers the tree does not hold that are those explorers' defaults
    (a file an older ``config show`` wrote held every installed explorer's); a key of such a section set to anything
    else (``--set explorer.vlfm.keep_radius=...`` while ``directions`` is chosen) is one :class:`InputError` line:
    that explorer is not configured, so its keys are not read."""
    node = layer.get("explorer") if "explorer" in layer else None
    if not isinstance(node, DictConfig):
        return layer
    held = {explorer_key(name) for name in explorers}
    keys = section_keys()
    dropped = []
    for key in map(str, node.keys()):
        if key == "name" or key in held or key not in keys:
            continue
        if _plain(node[key]) == json.loads(json.dumps(section_defaults(key))):
            dropped.append(key)
            continue
        other = keys[key]
        expected = (
            f"a key of explorer.{explorer_key(explorers[0])}, the chosen explorer's section (explorer.{key} is "
            f"read only when {other} is chosen: --set explorer.name={other})"
        )
        raise InputError(source, f"explorer.{key}", expected)
    if not dropped:
        return layer
    rest = OmegaConf.masked_copy(layer, [str(key) for key in layer if key != "explorer"])
    rest.explorer = OmegaConf.masked_copy(node, [key for key in map(str, node) if key not in dropped])
    return rest


def _writable(tree: DictConfig) -> DictConfig:
    """The tree with every section writable: OmegaConf before 2.4 (habitat-lab's Hydra pins it) marks frozen
    dataclasses read-only, and layers are merged into them."""
    OmegaConf.set_readonly(tree, False)
    for key in tree:
        child = tree._get_node(key)
        if isinstance(child, DictConfig):
            _writable(child)
    return tree


def _resolve(tree: DictConfig, explorers: tuple[str, ...]) -> Settings:
    """The typed tree, with ``${...}`` interpolations resolved (one that names no key is an :class:`InputError`),
    each section's values checked as it is made (a value outside its range is an :class:`InputError` on its
    dotted key; the explorers' sections by their declared ranges, :func:`~drivenav.ranges.check_declared`).
    Anything else a plug-in explorer's section raises as it is made (its ``__post_init__``) is that plug-in's one
    line."""
    try:
        settings = OmegaConf.to_object(tree)
        assert isinstance(settings, Settings)
        for name in explorers:
            check_declared(getattr(settings.explorer, explorer_key(name)))
    except OmegaConfBaseException as error:
        key = str(getattr(error, "full_key", None) or "<settings>")
        expected = "an interpolation ${...} naming another key that holds a value of this field's type"
        raise InputError("settings", key, expected, str(error).splitlines()[0]) from None
    except SettingError as error:
        section = dict(_sections(_default_settings(explorers))).get(error.owner, "")
        key = f"{section}.{error.name}" if section else error.name
        raise InputError("settings", key, error.expected, error.value) from None
    except InputError:
        raise
    except BaseException as error:  # a plug-in's section: its own code raised (caught whatever it is)
        plugin = next((name for name in explorers if EXPLORERS.is_plugin(name)), None)
        if plugin is None:
            raise
        raise EXPLORERS.broken(plugin, f"its section: {one_line(error)}") from None
    return settings


def _sections(config: object, prefix: str = "") -> Iterator[tuple[type, str]]:
    """Each section's dataclass and its dotted key in the tree (``VlfmConfig`` -> ``explorer.vlfm``)."""
    for item in dataclasses.fields(config):  # type: ignore[arg-type]
        value = getattr(config, item.name)
        if dataclasses.is_dataclass(value):
            yield type(value), f"{prefix}{item.name}"
            yield from _sections(value, f"{prefix}{item.name}.")


def _method_layer(agent: str) -> DictConfig:
    """The method's explorer, the body switches its explorer's entry sets, then the method's own overrides."""
    if agent not in agent_names():
        raise InputError("command line", "--agent", f"one of {', '.join(agent_names())}", agent)
    method = method_named(agent)
    preset: list[str] = []
    if method is not None:
        entry = explorer_entry(method.explorer)
        preset = [f"explorer.name={entry.name}", *entry.body, *method.overrides]
    return OmegaConf.from_dotlist([*preset, f"run.agent={agent}"])


def _check_same_method(layer: DictConfig, source: str, method: DictConfig) -> None:
    """A ``--config`` file naming another method than ``--agent`` (``run.agent``) or another explorer than the
    method's (``explorer.name``: a file ``config show --agent apexnav`` wrote, loaded with ``--agent drive-nav``) is
    one line: it would run the file's method recorded under its name, not the method asked for. A file that sets
    neither, or the same, is a layer like any other (the presets, a file of constants)."""
    for section, key in (("run", "agent"), ("explorer", "name")):
        wanted = _last_given([(method, "--agent")], section, key, "")
        given = _last_given([(layer, source)], section, key, wanted)
        if wanted and given != wanted:
            agent = _last_given([(method, "--agent")], "run", "agent", "")
            expected = f"{wanted}, as --agent {agent} sets it (or no {section}.{key} in the file)"
            raise InputError(source, f"{section}.{key}", expected, given)


def _config_layer(config: str) -> DictConfig:
    path = Path(config)
    if config in preset_names():
        text = resources.files("drivenav").joinpath(f"{PRESETS}/{config}.yaml").read_text(encoding="utf-8")
    elif path.suffix in (".yaml", ".yml") and path.is_file():
        try:
            text = path.read_text(encoding="utf-8")
        except (OSError, UnicodeDecodeError) as error:
            raise InputError(config, "<file>", "a readable UTF-8 YAML file", str(error)) from None
    else:
        raise InputError("command line", "--config", f"a preset ({', '.join(preset_names())}) or a YAML file", config)
    try:
        check_unique_keys(text, config)
        layer = OmegaConf.create(text)
    except yaml.YAMLError as error:
        raise InputError(config, "<file>", "a YAML mapping of settings", yaml_problem(error)) from None
    except OmegaConfBaseException as error:
        raise InputError(config, "<file>", "a YAML mapping of settings", " ".join(str(error).split())) from None
    if not isinstance(layer, DictConfig):
        raise InputError(config, "<file>", "a YAML mapping of settings", type(layer).__name__)
    dotted = _dotted_key(layer)
    if dotted is not None:
        where, key = dotted
        section, _, rest = key.partition(".")
        expected = f"nested keys in a file ('{section}:' and under it '  {rest}: ...'); dotted keys are for --set"
        raise InputError(config, where, expected, "a dotted key")
    return layer


def _dotted_key(layer: DictConfig, prefix: str = "") -> tuple[str, str] | None:
    """The first key of a file's layer that holds a dot (``sim.width: 320`` at the top, which OmegaConf would
    read as one key named ``sim.width``): its path from the top and the key itself."""
    for key in layer:
        name = f"{prefix}{key!s}"
        if "." in str(key):
            return name, str(key)
        child = layer._get_node(key)
        if isinstance(child, DictConfig):
            found = _dotted_key(child, f"{name}.")
            if found is not None:
                return found
    return None


def _option_layer(key: str, value: object) -> DictConfig:
    layer: DictConfig = OmegaConf.create({})
    OmegaConf.update(layer, key, value)
    return layer


def _override_layer(override: str) -> DictConfig:
    key, sep, value = override.partition("=")
    if not sep or not key.strip():
        raise InputError("command line", "--set", "KEY=VALUE with a dotted KEY (see 'drivenav config show')", override)
    try:
        return OmegaConf.from_dotlist([override])
    except (OmegaConfBaseException, yaml.YAMLError):
        raise InputError("--set", key.strip(), "a YAML value (a number, true/false, a string)", value) from None


def _merge(tree: DictConfig, layer: DictConfig, source: str, defaults: DictConfig) -> DictConfig:
    """``layer`` over ``tree``, or an :class:`InputError` naming the first key of ``layer`` that does not fit (what
    fits: the keys and types of ``defaults``)."""
    try:
        merged = OmegaConf.merge(tree, layer)
    except OmegaConfBaseException as error:
        raise _as_input_error(error, layer, source, defaults) from None
    assert isinstance(merged, DictConfig)
    return merged


def _as_input_error(error: OmegaConfBaseException, layer: DictConfig, source: str, tree: DictConfig) -> InputError:
    """What is allowed comes from the defaults' tree ``tree`` (the same keys and types at every layer)."""
    key = str(getattr(error, "full_key", None) or _misfit(tree, layer) or "")
    if not key:
        return InputError(
            source, "<settings>", "settings as 'drivenav config show' prints them", str(error).split("\n")[0]
        )
    parent, _, leaf = key.rpartition(".")
    node = OmegaConf.select(tree, parent) if parent else tree
    if isinstance(node, DictConfig) and leaf not in node:
        return InputError(source, key, f"a key of '{parent or '(top)'}': {', '.join(map(str, node.keys()))}", leaf)
    current = OmegaConf.select(tree, key)
    given = OmegaConf.select(layer, key, default=getattr(error, "value", None), throw_on_resolution_failure=False)
    return InputError(source, key, _allowed(current), "null" if given is None else _plain(given))


def _misfit(tree: DictConfig, layer: DictConfig, prefix: str = "") -> str | None:
    """The first key of ``layer`` whose value is not a mapping where ``tree`` has a section (OmegaConf's error for
    that names no key)."""
    for key, value in layer.items():
        name = f"{prefix}{key!s}"
        node = tree.get(key, None)
        if isinstance(node, DictConfig) and not isinstance(value, DictConfig):
            return name
        if isinstance(node, DictConfig) and isinstance(value, DictConfig):
            found = _misfit(node, value, f"{name}.")
            if found is not None:
                return found
    return None


def _allowed(current: object) -> str:
    if isinstance(current, DictConfig):
        return f"a mapping with keys {', '.join(map(str, current.keys()))}"
    kind = type(current).__name__
    return f"{'an' if kind[0] in 'aeiou' else 'a'} {kind} like {current!r}"


def _plain(value: object) -> object:
    """A layer's value as the user wrote it (plain lists and mappings, not OmegaConf nodes)."""
    return OmegaConf.to_container(value) if isinstance(value, (DictConfig, ListConfig)) else value


def settings_to_dict(settings: Settings) -> JsonObject:
    """The tree as plain JSON-able data (what ``run.json`` records)."""
    return dataclasses.asdict(settings)


def settings_from_dict(tree: JsonObject, provider: Declared | None = None) -> Settings:
    """The settings a tree of :func:`settings_to_dict` holds (a run's ``run.json``), checked as :func:`load_settings`
    checks its layers: the tree merged over the defaults, each section checking its values. A wrong key, type or
    value is one :class:`~drivenav.errors.InputError` on the source ``settings`` naming the dotted key. The
    sections of explorers other than the chosen one are dropped (:func:`held_sections_only`: a run of an older
    drivenav recorded every installed explorer's); a chosen explorer that is not installed is one line naming its
    entry point and ``provider``, the package that provided it (:func:`missing_explorer`)."""
    tree = _before_explorers(tree)
    name = uninstalled_explorer(tree)
    if name is not None:
        raise missing_explorer(name, provider)
    tree = held_sections_only(tree)
    try:
        layer = OmegaConf.create(tree)
    except (OmegaConfBaseException, ValueError) as error:
        expected = "settings as 'drivenav config show' prints them"
        raise InputError("settings", "<settings>", expected, str(error)) from None
    return _settings_of([(layer, "settings")])


def held_sections_only(tree: JsonObject) -> JsonObject:
    """``tree`` (of :func:`settings_to_dict`, its ``explorer.name`` a declared explorer) without the sections of
    the explorers a tree made now would not hold (:func:`explorers_of`); any other tree as it is."""
    explorer, run = tree.get("explorer"), tree.get("run")
    if not isinstance(explorer, dict) or explorer.get("name") not in EXPLORERS.names:
        return tree
    agent = run.get("agent") if isinstance(run, dict) else None
    explorers = explorers_of(str(explorer["name"]), agent if isinstance(agent, str) else RunSettings.agent)
    keys = {"name", *(explorer_key(name) for name in explorers)}
    return {**tree, "explorer": {key: value for key, value in explorer.items() if key in keys}}


def uninstalled_explorer(tree: object) -> str | None:
    """The explorer ``tree`` (run.json's settings) chooses when it is not installed (a plug-in since uninstalled),
    else None (an installed one, or a tree that names none: the settings' own checks say what is wrong)."""
    explorer = tree.get("explorer") if isinstance(tree, dict) else None
    name = explorer.get("name") if isinstance(explorer, dict) else None
    return name if isinstance(name, str) and name not in EXPLORERS.names else None


def missing_explorer(name: str, provider: Declared | None = None) -> InputError:
    """The one line for a run whose explorer ``name`` is not installed: the entry point and the package to install
    (``provider``, as ``run.json`` records a plug-in's; unknown for a run of an older drivenav)."""
    if provider is None:
        install = f"a package providing entry point drivenav.explorers: {name}"
    else:
        point = f"{provider.name} = {provider.value!r}"
        install = f"the package {provider.source}, which provides entry point drivenav.explorers: {point}"
    return InputError("settings", "explorer.name", f"an installed explorer (install {install})", name)


_LEGACY_AGENT_KEYS = {  # the agent's keys before explorers had sections of their own -> where they went
    "decision_scan": ("directions",),
    "reidentify_steps": ("directions",),
    "min_goal_distance": ("greedy", "vlfm"),
}


def _before_explorers(tree: JsonObject) -> JsonObject:
    """A tree written before explorers had their own sections (no ``explorer``; ``agent.use_reasoner``,
    ``agent.value_map``, ``agent.vlfm``, ...: a ``run.json`` of an older drivenav) in today's shape, so that older
    run directories are still read; any other tree as it is."""
    agent = tree.get("agent")
    if "explorer" in tree or not isinstance(agent, dict) or "use_reasoner" not in agent:
        return tree
    agent = dict(agent)
    use_reasoner, value_map = agent.pop("use_reasoner"), agent.pop("value_map", False)
    name = "directions" if use_reasoner else "vlfm" if value_map else "greedy"
    sections: dict[str, JsonObject] = {"vlfm": dict(agent.pop("vlfm", {}))}
    for key, targets in _LEGACY_AGENT_KEYS.items():
        if key in agent:
            value = agent.pop(key)
            for target in targets:
                sections.setdefault(target, {})[key] = value
    return {**tree, "agent": agent, "explorer": {"name": name, **sections}}


def settings_to_yaml(settings: Settings) -> str:
    """The tree as YAML under a comment on units and sections (``drivenav config show``); it loads back with
    ``--config``."""
    return YAML_HEADER + OmegaConf.to_yaml(OmegaConf.structured(settings))


def first_difference(
    a: Mapping[str, Any], b: Mapping[str, Any], defaults: Mapping[str, Any] | None = None
) -> str | None:
    """The first dotted key (in sorted order) whose value differs between two trees of
    :func:`settings_to_dict`, or None when they are equal: what refuses a resume into a run directory started with
    other settings. A key present in one tree only differs, except a key ``a`` lacks that ``b`` holds at its value in
    ``defaults`` (a setting added since ``a`` was written, left at its default: a default keeps the behaviour the
    setting's absence had)."""
    return _difference(a, b, "", _ABSENT if defaults is None else defaults)


def _difference(a: object, b: object, prefix: str, defaults: object) -> str | None:
    if a is _ABSENT and defaults is not _ABSENT and b == defaults:
        return None
    if not (isinstance(a, Mapping) and isinstance(b, Mapping)):
        return None if a == b else prefix or "(root)"
    for key in sorted({*a, *b}, key=str):
        default = defaults.get(key, _ABSENT) if isinstance(defaults, Mapping) else _ABSENT
        found = _difference(a.get(key, _ABSENT), b.get(key, _ABSENT), f"{prefix}{'.' if prefix else ''}{key}", default)
        if found is not None:
            return found
    return None


def default_settings(settings: Settings) -> Settings:
    """The defaults of a tree like ``settings``: the same explorers' sections, every value its default."""
    return _default_settings(settings.explorer.explorers)


_ABSENT = object()  # a key missing from one tree (unequal to every value, None included)


def section_defaults(key: str) -> JsonObject | None:
    """The default section ``explorer.<key>`` of the installed explorer holding settings key ``key`` (None when no
    installed explorer holds it, or its section cannot be made): what a run that does not hold that section would
    have held, for readers comparing runs of several explorers."""
    name = section_keys().get(key)
    if name is None:
        return None
    try:
        defaults: JsonObject = dataclasses.asdict(section_class(name)())
    except InputError:
        return None
    return defaults
