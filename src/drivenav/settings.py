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
registered explorer (``explorer.directions``, ``explorer.greedy``, ``explorer.vlfm``, and any plug-in's), each its
entry's config class with the source's constants as defaults. The tree's type is made once per process from the
registered explorers (:func:`explorer_settings_type`).
"""

from __future__ import annotations

import dataclasses
import logging
import math
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
from drivenav.semantics.registry import DETECTORS, DTYPES, REASONERS, SCORERS, ModelSpec
from drivenav.types import SimConfig

log = logging.getLogger(__name__)

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
    config class with its defaults. A plug-in explorer whose entry cannot be loaded gets no section (one warning
    line); choosing it is an error."""
    sections: list[tuple[str, type, Any]] = []
    for name in EXPLORERS.names:
        try:
            config = explorer_entry(name).config
        except InputError as error:
            log.warning("drivenav: %s", error)
            continue
        sections.append((name, config, field(default_factory=config)))
    made = dataclasses.make_dataclass("ExplorerSettings", sections, bases=(ExplorerSettings,), frozen=True)
    made.__module__ = __name__
    return made


def _explorer_settings(name: str = DEFAULT_EXPLORER, sections: Mapping[str, object] | None = None) -> ExplorerSettings:
    """The ``explorer`` section of the tree: ``name`` and every registered explorer's section (defaults for those
    not given)."""
    return explorer_settings_type()(name=name, **(sections or {}))


@dataclass(frozen=True)
class Settings:
    """Everything an evaluation is set up with (the paper's values by default)."""

    sim: SimConfig = field(default_factory=SimConfig)
    mapping: MapTuning = field(default_factory=MapTuning)
    paper: DriveNavConfig = field(default_factory=DriveNavConfig)
    agent: AgentConfig = field(default_factory=AgentConfig)
    explorer: ExplorerSettings = field(default_factory=_explorer_settings)
    models: ModelSpec = field(default_factory=ModelSpec)
    run: RunSettings = field(default_factory=RunSettings)


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
    settings = _resolve(tree)
    check_values(settings)
    return settings


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
    """The typed tree, with ``${...}`` interpolations resolved (one that names no key is an :class:`InputError`)."""
    try:
        settings = OmegaConf.to_object(tree)
    except OmegaConfBaseException as error:
        key = str(getattr(error, "full_key", None) or "<settings>")
        expected = "an interpolation ${...} naming another key that holds a value of this field's type"
        raise InputError("settings", key, expected, str(error).splitlines()[0]) from None
    assert isinstance(settings, Settings)
    return settings


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
        layer = OmegaConf.create(text)
    except (OmegaConfBaseException, yaml.YAMLError) as error:
        raise InputError(config, "<file>", "a YAML mapping of settings", " ".join(str(error).split())) from None
    if not isinstance(layer, DictConfig):
        raise InputError(config, "<file>", "a YAML mapping of settings", type(layer).__name__)
    return layer


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


# ----------------------------------------------------------------------------------------------- values

_POSITIVE = (
    "sim.width",
    "sim.height",
    "sim.hfov_deg",
    "sim.max_depth",
    "sim.forward_step",
    "sim.turn_angle_deg",
    "sim.max_steps",
    "sim.grid_resolution",
    "sim.agent_height",
    "mapping.max_size",
    "mapping.initial_size",
    "mapping.pocket_window",
    "mapping.pixel_stride",
    "paper.speed.r_obs",
    "paper.speed.r_vor",
    "paper.directions.bearing_radius",
    "paper.inspection.forward_range_deg",
    "paper.semantics.verify_frames",
    "paper.semantics.max_images_per_prompt",
)


def _leaves(value: Any, prefix: str = "") -> Iterator[tuple[str, Any]]:
    if dataclasses.is_dataclass(value):
        for item in dataclasses.fields(value):
            yield from _leaves(getattr(value, item.name), f"{prefix}{item.name}.")
    else:
        yield prefix.rstrip("."), value


def check_values(settings: Settings) -> None:
    """Numbers are finite and not negative; sizes, ranges and budgets are positive; the rest as each rule says."""
    leaves = dict(_leaves(settings))
    for key, value in leaves.items():
        is_number = isinstance(value, (int, float)) and not isinstance(value, bool)
        if key in _POSITIVE and not (math.isfinite(value) and value > 0):
            raise InputError("settings", key, "a finite number > 0", value)
        if is_number and not (math.isfinite(value) and value >= 0):
            raise InputError("settings", key, "a finite number >= 0", value)
    rules = (
        ("sim.hfov_deg", settings.sim.hfov_deg < 180.0, "a field of view < 180 degrees"),
        (
            "mapping.min_obstacle_height",
            settings.mapping.min_obstacle_height < settings.sim.agent_height,
            "less than sim.agent_height (the top of the obstacle band)",
        ),
        ("sim.min_depth", settings.sim.min_depth < settings.sim.max_depth, "less than sim.max_depth"),
        ("paper.speed.lam", settings.paper.speed.lam < 1.0, "lambda < 1 (the speed field stays positive, Eq. 1)"),
        ("paper.inspection.forward_range_deg", settings.paper.inspection.forward_range_deg <= 360.0, "<= 360"),
        (
            "mapping.max_size",
            settings.mapping.max_size >= settings.mapping.initial_size,
            "at least mapping.initial_size (the grid starts that large and only grows)",
        ),
        (
            "paper.directions.cluster_span_deg",
            settings.paper.directions.cluster_span_deg < 360.0,
            "a circular gap < 360 degrees (Sec. IV-A b)",
        ),
        ("paper.directions.association_gate_deg", settings.paper.directions.association_gate_deg <= 180.0, "<= 180"),
    )
    for key, holds, expected in rules:
        if not holds:
            raise InputError("settings", key, expected, leaves[key])
    choices = (  # key, allowed names, the option that sets it
        ("run.agent", agent_names(), "--agent"),
        ("models.reasoner", REASONERS, "--reasoner"),
        ("models.detector", DETECTORS, "--detector"),
        ("models.scorer", SCORERS, "--scorer"),
        ("models.dtype", DTYPES, "--dtype"),
        ("explorer.name", EXPLORERS.names, "--set explorer.name=NAME"),
    )
    for key, names, option in choices:
        if leaves[key] not in names:
            raise InputError("settings", key, f"one of {', '.join(names)} (the {option} option)", leaves[key])


def settings_to_dict(settings: Settings) -> JsonObject:
    """The tree as plain JSON-able data (what ``run.json`` records)."""
    return dataclasses.asdict(settings)


def settings_from_dict(tree: JsonObject) -> Settings:
    """The settings a tree of :func:`settings_to_dict` holds (a run's ``run.json``), checked as :func:`load_settings`
    checks its layers: the tree merged over the defaults, then :func:`check_values`. A wrong key, type or value is
    one :class:`~drivenav.errors.InputError` on the source ``settings`` naming the dotted key."""
    try:
        layer = OmegaConf.create(_before_explorers(tree))
    except (OmegaConfBaseException, ValueError) as error:
        expected = "settings as 'drivenav config show' prints them"
        raise InputError("settings", "<settings>", expected, str(error)) from None
    settings = _resolve(_merge(_writable(OmegaConf.structured(Settings)), layer, "settings"))
    check_values(settings)
    return settings


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
