"""The configuration tree: sensor and body, mapper, the paper's constants, agent switches, models, run.

Built in layers with OmegaConf structured configs (as habitat-lab builds its own): the defaults (every value the
paper's), then the ``--agent`` method's preset (:mod:`drivenav.methods`), then each ``--config NAME_OR_FILE`` in
order (a preset shipped in ``drivenav/data/configs/`` or a YAML file), then the dedicated command-line options that
were given (``--seed``, ``--max-steps``, ``--reasoner``, ...), then each ``--set KEY=VALUE`` in order.
``drivenav config show`` prints the result; ``run.json`` records it. A wrong key, type or value is one
:class:`~drivenav.errors.InputError` line naming the key, what was given and what is allowed.
"""

from __future__ import annotations

import dataclasses
import math
from collections.abc import Iterator, Mapping, Sequence
from dataclasses import dataclass, field
from importlib import resources
from pathlib import Path
from typing import Any

import yaml
from omegaconf import DictConfig, OmegaConf
from omegaconf.errors import OmegaConfBaseException

from drivenav.agent.drivenav import AgentConfig
from drivenav.config import DriveNavConfig
from drivenav.errors import InputError
from drivenav.mapping.config import MapTuning
from drivenav.methods import METHODS, REFERENCE_AGENTS, method_named
from drivenav.semantics.registry import ModelSpec
from drivenav.types import SimConfig

PRESETS = "data/configs"


@dataclass(frozen=True)
class RunSettings:
    """Which agent runs (``--agent``) and the run's seed (``--seed``); the step budget is ``sim.max_steps``."""

    agent: str = "drive-nav"
    seed: int = 0


@dataclass(frozen=True)
class Settings:
    """Everything an evaluation is set up with (the paper's values by default)."""

    sim: SimConfig = field(default_factory=SimConfig)
    mapping: MapTuning = field(default_factory=MapTuning)
    paper: DriveNavConfig = field(default_factory=DriveNavConfig)
    agent: AgentConfig = field(default_factory=AgentConfig)
    models: ModelSpec = field(default_factory=ModelSpec)
    run: RunSettings = field(default_factory=RunSettings)


def agent_names() -> list[str]:
    """Every ``--agent`` name: the methods of the paper's tables and the reference agents."""
    return sorted([*REFERENCE_AGENTS, *(m.name for m in METHODS)])


def preset_names() -> list[str]:
    """The ``--config`` presets shipped with drivenav."""
    folder = resources.files("drivenav").joinpath(PRESETS)
    return sorted(item.name[: -len(".yaml")] for item in folder.iterdir() if item.name.endswith(".yaml"))


def load_settings(
    agent: str | None = None,
    configs: Sequence[str] = (),
    overrides: Sequence[str] = (),
    options: Mapping[str, object] | None = None,
) -> Settings:
    """Defaults, then the method preset of ``agent``, then ``configs``, then ``options`` (dotted key -> value, from
    dedicated command-line options), then ``overrides`` (see module docstring)."""
    tree: DictConfig = OmegaConf.structured(Settings)
    if agent is not None:
        tree = _merge(tree, _method_layer(agent), "--agent")
    for config in configs:
        tree = _merge(tree, _config_layer(config), config)
    for key, value in (options or {}).items():
        tree = _merge(tree, _option_layer(key, value), "command line", key, value)
    for override in overrides:
        key, _, value = override.partition("=")
        tree = _merge(tree, _override_layer(override), "--set", key.strip(), value)
    settings = OmegaConf.to_object(tree)
    assert isinstance(settings, Settings)
    check_values(settings)
    return settings


def _method_layer(agent: str) -> DictConfig:
    if agent not in agent_names():
        raise InputError("command line", "--agent", f"one of {', '.join(agent_names())}", agent)
    method = method_named(agent)
    layer = OmegaConf.from_dotlist([*(method.overrides if method else ()), f"run.agent={agent}"])
    return layer


def _config_layer(config: str) -> DictConfig:
    path = Path(config)
    if config in preset_names():
        text = resources.files("drivenav").joinpath(f"{PRESETS}/{config}.yaml").read_text(encoding="utf-8")
    elif path.suffix in (".yaml", ".yml") and path.is_file():
        text = path.read_text(encoding="utf-8")
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
    key, sep, _ = override.partition("=")
    if not sep or not key.strip():
        raise InputError("command line", "--set", "KEY=VALUE with a dotted KEY (see 'drivenav config show')", override)
    return OmegaConf.from_dotlist([override])


def _merge(tree: DictConfig, layer: DictConfig, source: str, key: str = "", given: object = None) -> DictConfig:
    """``layer`` over ``tree``; an error names ``key`` and ``given`` where OmegaConf's does not say them."""
    try:
        merged = OmegaConf.merge(tree, layer)
    except OmegaConfBaseException as error:
        raise _as_input_error(error, tree, source, key, given) from None
    assert isinstance(merged, DictConfig)
    return merged


def _as_input_error(
    error: OmegaConfBaseException, tree: DictConfig, source: str, hint: str, hint_given: object
) -> InputError:
    key = str(getattr(error, "full_key", None) or hint)
    parent, _, leaf = key.rpartition(".")
    node = OmegaConf.select(tree, parent) if parent else tree
    if isinstance(node, DictConfig) and leaf not in node:
        return InputError(source, key, f"a key of '{parent or '(top)'}': {', '.join(map(str, node.keys()))}", leaf)
    current = OmegaConf.select(tree, key) if key else None
    allowed = f"a {type(current).__name__} like {current!r}" if current is not None else "a value of the right type"
    if isinstance(current, DictConfig):
        allowed = f"a mapping with keys {', '.join(map(str, current.keys()))}"
    given = getattr(error, "value", None)
    given = given if given is not None else hint_given
    return InputError(source, key or "<settings>", allowed, given if given is not None else str(error).splitlines()[0])


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
        if is_number and not (math.isfinite(value) and value >= 0):
            raise InputError("settings", key, "a finite number >= 0", value)
        if key in _POSITIVE and value <= 0:
            raise InputError("settings", key, "a number > 0", value)
    rules = (
        ("sim.hfov_deg", settings.sim.hfov_deg < 180.0, "a field of view < 180 degrees"),
        ("sim.min_depth", settings.sim.min_depth < settings.sim.max_depth, "less than sim.max_depth"),
        ("paper.speed.lam", settings.paper.speed.lam < 1.0, "lambda < 1 (the speed field stays positive, Eq. 1)"),
        ("paper.inspection.forward_range_deg", settings.paper.inspection.forward_range_deg <= 360.0, "<= 360"),
    )
    for key, holds, expected in rules:
        if not holds:
            raise InputError("settings", key, expected, leaves[key])


def settings_to_dict(settings: Settings) -> dict[str, Any]:
    """The tree as plain JSON-able data (what ``run.json`` records)."""
    return dataclasses.asdict(settings)


def settings_to_yaml(settings: Settings) -> str:
    """The tree as YAML (``drivenav config show``); it loads back with ``--config``."""
    return OmegaConf.to_yaml(OmegaConf.structured(settings))
