"""habitat-lab's configuration for a :class:`~drivenav.envs.habitat.spec.HabitatSpec` (imports habitat-lab).

It starts from the benchmark's habitat-lab config (``benchmark/nav/objectnav/objectnav_*.yaml``), sets what
drivenav's ``sim`` settings say (sensors, body, steps, success distance: one source of truth for both sides), the
split's files under ``--data-dir``, episode order unshuffled, then the user's ``--set habitat.KEY=VALUE``
overrides (they win). Structural edits follow: the look-up/down actions are dropped (DRIVE-Nav never tilts its
camera), the collisions measure is added, for HM3D-OVON the ObjectGoal sensor is dropped (its category maps
are empty; the goal text comes from the episode), and with ``semantic`` a semantic sensor like the depth sensor
is added.
"""

from __future__ import annotations

from typing import TYPE_CHECKING, Any

from drivenav.envs.habitat.benchmarks import OVON
from drivenav.types import SimConfig

if TYPE_CHECKING:
    from omegaconf import DictConfig

    from drivenav.envs.habitat.spec import HabitatSpec

AGENT = "habitat.simulator.agents.main_agent"
SENSORS = f"{AGENT}.sim_sensors"
DROPPED_ACTIONS = ("look_up", "look_down")


def _number(value: float) -> str:
    return str(int(value)) if float(value).is_integer() else repr(float(value))


def _quoted(path: str) -> str:
    """A path as a quoted Hydra string (``{split}`` and other grammar characters kept literally)."""
    return "'" + path.replace("\\", "\\\\").replace("'", "\\'") + "'"


def paper_values(spec: HabitatSpec, sim: SimConfig, dataset_type: str | None = None) -> dict[str, str]:
    """Hydra overrides (key -> value) that make habitat-lab's config match ``sim`` and the spec's split, read with
    ``dataset_type`` (default: the benchmark's, drivenav's own for HM3D-OVON)."""
    data_dir = spec.data_dir.rstrip("/")
    camera = f"[0,{_number(sim.camera_height)},0]"
    values = {
        "habitat.environment.max_episode_steps": str(sim.max_steps),
        "habitat.environment.iterator_options.shuffle": "False",
        "habitat.simulator.turn_angle": _number(sim.turn_angle_deg),
        "habitat.simulator.forward_step_size": _number(sim.forward_step),
        f"{AGENT}.height": _number(sim.agent_height),
        f"{AGENT}.radius": _number(sim.agent_radius),
        "habitat.task.measurements.success.success_distance": _number(sim.success_distance),
        "habitat.dataset.type": dataset_type or spec.bench.dataset_type,
        "habitat.dataset.split": spec.split,
        "habitat.dataset.data_path": _quoted(f"{data_dir}/{spec.bench.data_path}"),
        "habitat.dataset.scenes_dir": _quoted(str(spec.scenes_dir)),
        "habitat.simulator.scene_dataset": _quoted(f"{data_dir}/{spec.bench.scene_dataset}"),
    }
    for sensor in ("rgb_sensor", "depth_sensor"):
        for key, value in (
            ("width", str(sim.width)),
            ("height", str(sim.height)),
            ("hfov", _number(sim.hfov_deg)),
            ("position", camera),
        ):
            values[f"{SENSORS}.{sensor}.{key}"] = value
    values[f"{SENSORS}.depth_sensor.min_depth"] = _number(sim.min_depth)
    values[f"{SENSORS}.depth_sensor.max_depth"] = _number(sim.max_depth)
    return values


def hydra_overrides(spec: HabitatSpec, sim: SimConfig, dataset_type: str | None = None) -> list[str]:
    """drivenav's values, except where the user's overrides set the same key, then the user's."""
    user_keys = {item.partition("=")[0].strip() for item in spec.overrides}
    values = paper_values(spec, sim, dataset_type)
    ours = [f"{key}={value}" for key, value in values.items() if key not in user_keys]
    return [*ours, *spec.overrides]


def habitat_config(spec: HabitatSpec, sim: SimConfig) -> DictConfig:
    """The habitat-lab config of a run (``habitat.get_config`` plus the structural edits above). HM3D-OVON's split
    is read by drivenav's dataset type (registered here), or by HM3D-OVON's own ``OVON-v1`` where a plugin
    imported before registered it (:func:`~drivenav.envs.habitat.ovon.dataset_type`)."""
    import habitat
    from habitat.config import read_write
    from habitat.config.default_structured_configs import (
        CollisionsMeasurementConfig,
        HabitatSimSemanticSensorConfig,
    )

    from drivenav.envs.habitat.ovon import dataset_type

    overrides = hydra_overrides(spec, sim, dataset_type(spec.bench.layout))
    config: DictConfig = habitat.get_config(spec.bench.habitat_config, overrides)
    with read_write(config):
        task: Any = config.habitat.task
        for action in DROPPED_ACTIONS:
            task.actions.pop(action, None)
        task.measurements.collisions = CollisionsMeasurementConfig()
        if spec.bench.layout == OVON:
            task.lab_sensors.pop("objectgoal_sensor", None)
        if spec.semantic:
            depth = config.habitat.simulator.agents.main_agent.sim_sensors.depth_sensor
            semantic = HabitatSimSemanticSensorConfig(
                width=depth.width, height=depth.height, hfov=depth.hfov, position=list(depth.position)
            )
            config.habitat.simulator.agents.main_agent.sim_sensors.semantic_sensor = semantic
    return config


def check_habitat_config(spec: HabitatSpec, sim: SimConfig) -> None:
    """Build the run's habitat-lab config once, before any work: habitat-lab missing, or an override it does not
    take, is one :class:`~drivenav.errors.InputError` line."""
    from drivenav.errors import InputError

    spec.import_plugins()
    try:
        habitat_config(spec, sim)
    except ImportError as error:
        expected = "habitat-lab and habitat-sim installed (check with 'drivenav doctor --env habitat')"
        raise InputError("command line", "--env", expected, str(error).splitlines()[0]) from None
    except Exception as error:  # Hydra's and OmegaConf's errors share no base class
        given = " ".join(spec.overrides) or "(none)"
        detail = " ".join(str(error).split())
        raise InputError("--set", "habitat.*", f"overrides habitat-lab's config takes ({detail})", given) from None
