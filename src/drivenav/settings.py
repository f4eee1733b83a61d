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

``explorer`` holds ``explorer.name`` (the exploration method, :mod:`drivenav.agent.explorers`) and one section per
registered explorer (``explorer.directions``, ``explorer.greedy``, ``explorer.vlfm``, ``explorer.apexnav`` and any
plug-in's), each its entry's config class with the source's constants as defaults. The tree's type is made once per
process from the registered explorers (:func:`explorer_settings_type`).
"""

from __future__ import annotations

import dataclasses
from collections.abc import Iterator, Mapping, Sequence
from dataclasses import dataclass, field
from functools import cache
from importlib import resources
from pathlib import Path
from typing import Any

import yaml
from omegaconf import DictConfig, ListConfig, OmegaConf
from omegaconf.errors import OmegaConfBaseException

from drivenav.agent.config import AgentConfig
from drivenav.agent.explorers import DEFAULT_EXPLORER, EXPLORERS, explorer_entry
from drivenav.errors import InputError
from drivenav.jsonstream import JsonObject
from drivenav.mapping.config import MapTuning
from drivenav.methods import PRESETS, agent_names, method_named, preset_names
from drivenav.paper import DriveNavConfig
from drivenav.ranges import MAX_GRID_SIDE, Range, SettingError, check_ranges, check_rule
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
    makes, one section per registered explorer."""

    name: str = DEFAULT_EXPLORER

    def __reduce__(self) -> tuple[Any, tuple[str, dict[str, object]]]:
        """Rebuilt in another process (worker processes, Ray), where the type is made anew."""
        sections = {f.name: getattr(self, f.name) for f in dataclasses.fields(self) if f.name != "name"}
        return _explorer_settings, (self.name, sections)


@cache
def explorer_settings_type() -> type[ExplorerSettings]:
    """:class:`ExplorerSettings` with a section per registered explorer (made once per process): each its entry's
    config class with its defaults. A plug-in explorer whose entry cannot be loaded gets no section (nothing is said
    until it is chosen: then it is one :class:`~drivenav.errors.InputError` line)."""
    sections: list[tuple[str, type, Any]] = [
        (name, entry.config, field(default_factory=entry.config)) for name, entry in EXPLORERS.usable().items()
    ]
    made = dataclasses.make_dataclass("ExplorerSettings", sections, bases=(ExplorerSettings,), frozen=True)
    made.__module__ = __name__
    return made


def _explorer_settings(name: str = DEFAULT_EXPLORER, sections: Mapping[str, object] | None = None) -> ExplorerSettings:
    """The ``explorer`` section of the tree: ``name`` and every registered explorer's section (defaults for those
    not given)."""
    return explorer_settings_type()(name=name, **(sections or {}))


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
        for name in EXPLORERS.names:
            section = getattr(self.explorer, name, None)
            if section is None:
                continue
            entry = explorer_entry(name)
            rules += [(f"explorer.{name}.{key}", holds, why) for key, holds, why in entry.rules(section, self.sim)]
        return rules


def explorer_section(settings: Settings, name: str) -> object:
    """The settings section of the explorer ``name`` (its entry's defaults when the tree has none: a plug-in
    that could not be loaded when the tree's type was made)."""
    section = getattr(settings.explorer, name, None) if name != "name" else None
    return section if section is not None else explorer_entry(name).config()


def load_settings(
    agent: str | None = None,
    *,
    configs: Sequence[str] = (),
    overrides: Sequence[str] = (),
    options: Mapping[str, object] | None = None,
) -> Settings:
    """Defaults, then the method preset of ``agent``, then ``configs``, then ``options`` (dotted key -> value, from
    dedicated command-line options), then ``overrides`` (see module docstring)."""
    tree = _writable(OmegaConf.structured(Settings))
    if agent is not None:
        tree = _merge(tree, _method_layer(agent), "--agent")
    for config in configs:
        tree = _merge(tree, _config_layer(config), config)
    for key, value in (options or {}).items():
        tree = _merge(tree, _option_layer(key, value), "command line")
    for override in overrides:
        tree = _merge(tree, _override_layer(override), "--set")
    return _resolve(tree)


def _writable(tree: DictConfig) -> DictConfig:
    """The tree with every section writable: OmegaConf before 2.4 (habitat-lab's Hydra pins it) marks frozen
    dataclasses read-only, and layers are merged into them."""
    OmegaConf.set_readonly(tree, False)
    for key in tree:
        child = tree._get_node(key)
        if isinstance(child, DictConfig):
            _writable(child)
    return tree


def _resolve(tree: DictConfig) -> Settings:
    """The typed tree, with ``${...}`` interpolations resolved (one that names no key is an :class:`InputError`),
    each section's values checked as it is made (a value outside its range is an :class:`InputError` on its
    dotted key)."""
    try:
        settings = OmegaConf.to_object(tree)
    except OmegaConfBaseException as error:
        key = str(getattr(error, "full_key", None) or "<settings>")
        expected = "an interpolation ${...} naming another key that holds a value of this field's type"
        raise InputError("settings", key, expected, str(error).splitlines()[0]) from None
    except SettingError as error:
        section = _SECTIONS.get(error.owner, "")
        key = f"{section}.{error.name}" if section else error.name
        raise InputError("settings", key, error.expected, error.value) from None
    assert isinstance(settings, Settings)
    return settings


def _sections(config: object, prefix: str = "") -> Iterator[tuple[type, str]]:
    """Each section's dataclass and its dotted key in the tree (``ValueMapConfig`` -> ``agent.vlfm``)."""
    for item in dataclasses.fields(config):  # type: ignore[arg-type]
        value = getattr(config, item.name)
        if dataclasses.is_dataclass(value):
            yield type(value), f"{prefix}{item.name}"
            yield from _sections(value, f"{prefix}{item.name}.")


_SECTIONS: dict[type, str] = dict(_sections(Settings()))
"""Where each section's dataclass sits in the tree, to name a key its own check refuses."""


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


def _merge(tree: DictConfig, layer: DictConfig, source: str) -> DictConfig:
    """``layer`` over ``tree``, or an :class:`InputError` naming the first key of ``layer`` that does not fit."""
    try:
        merged = OmegaConf.merge(tree, layer)
    except OmegaConfBaseException as error:
        raise _as_input_error(error, layer, source) from None
    assert isinstance(merged, DictConfig)
    return merged


def _as_input_error(error: OmegaConfBaseException, layer: DictConfig, source: str) -> InputError:
    """What is allowed comes from the defaults' tree (the same keys and types at every layer)."""
    tree: DictConfig = OmegaConf.structured(Settings)
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


def settings_from_dict(tree: JsonObject) -> Settings:
    """The settings a tree of :func:`settings_to_dict` holds (a run's ``run.json``), checked as :func:`load_settings`
    checks its layers: the tree merged over the defaults, each section checking its values. A wrong key, type or
    value is one :class:`~drivenav.errors.InputError` on the source ``settings`` naming the dotted key."""
    try:
        layer = OmegaConf.create(_before_explorers(tree))
    except (OmegaConfBaseException, ValueError) as error:
        expected = "settings as 'drivenav config show' prints them"
        raise InputError("settings", "<settings>", expected, str(error)) from None
    return _resolve(_merge(_writable(OmegaConf.structured(Settings)), layer, "settings"))


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


def first_difference(a: Mapping[str, Any], b: Mapping[str, Any]) -> str | None:
    """The first dotted key (in sorted order) whose value differs between two trees of
    :func:`settings_to_dict`, or None when they are equal: what refuses a resume into a run directory started with
    other settings. A key present in one tree only differs."""
    return _difference(a, b, "")


def _difference(a: object, b: object, prefix: str) -> str | None:
    if not (isinstance(a, Mapping) and isinstance(b, Mapping)):
        return None if a == b else prefix or "(root)"
    for key in sorted({*a, *b}, key=str):
        found = _difference(a.get(key, _ABSENT), b.get(key, _ABSENT), f"{prefix}{'.' if prefix else ''}{key}")
        if found is not None:
            return found
    return None


_ABSENT = object()  # a key missing from one tree (unequal to every value, None included)
