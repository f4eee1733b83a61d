"""HM3D-OVON's released form through habitat-lab: the fixture (``tests/ovon_fixture.py``) runs on DriveNavSim-v0
with goal ids in the released text form counting for ``target_seen``; a plugin that registers HM3D-OVON's own
dataset name keeps it, and the run reads the split with it."""

from __future__ import annotations

import gzip
import json
import sys
from collections.abc import Iterator
from pathlib import Path

import pytest
from habitat.core.registry import registry
from worlds import SIM_OVERRIDE, settings_for

from drivenav.agents import make_agent
from drivenav.envs.habitat.benchmarks import DATASET_TYPES, OVON, OVON_DATASET_TYPE
from drivenav.envs.habitat.env import HabitatEnv
from drivenav.envs.habitat.ovon import OVONDataset
from drivenav.envs.habitat.spec import HabitatSpec
from drivenav.eval.runner import run_episode
from ovon_fixture import SPLIT, write_released

SMALL = ("sim.width=320", "sim.height=240")
PLUGIN = "ovon_name_plugin"


def _oracle_runs(spec: HabitatSpec) -> dict[str, tuple[int | None, bool | None]]:
    """Each episode's success and ``target_seen``, the oracle stepping through habitat.Env."""
    settings = settings_for("oracle", "hm3d-ovon", *SMALL)
    env = HabitatEnv(spec, settings.sim)
    try:
        outcomes = {}
        for episode in spec.episodes():
            record, _ = run_episode(env, make_agent(settings), episode, 0, settings.sim.max_steps)
            assert record.error == "", record.error
            outcomes[episode.episode_id] = (record.success, env.measures().target_seen)
    finally:
        env.close()
    return outcomes


def test_the_released_form_runs_and_its_ids_give_target_seen(tmp_path: Path) -> None:
    write_released(tmp_path)
    outcomes = _oracle_runs(HabitatSpec("hm3d-ovon", SPLIT, str(tmp_path), (SIM_OVERRIDE,), semantic=True))
    assert len(outcomes) == 6
    assert all(outcome == (1, True) for outcome in outcomes.values()), outcomes


def test_ids_that_name_no_instance_in_view_give_no_target_seen(tmp_path: Path) -> None:
    """The same kettle episode with its goal's id numbered as no instance of the scene: still a success (the view
    points are the same), never seen."""
    split_file = write_released(tmp_path)
    content = split_file.parent / "content" / "house_00000.json.gz"
    document = json.loads(gzip.decompress(content.read_bytes()))
    (kettle,) = document["goals_by_category"]["house_00000.basis.glb_kettle"]
    kettle["object_id"] = "kettle_9999"
    document["episodes"] = document["episodes"][:1]
    content.write_bytes(gzip.compress(json.dumps(document).encode()))
    (split_file.parent / "content" / "house_00001.json.gz").unlink()
    outcomes = _oracle_runs(HabitatSpec("hm3d-ovon", SPLIT, str(tmp_path), (SIM_OVERRIDE,), semantic=True))
    assert outcomes == {"0": (1, False)}


@pytest.fixture
def plugin() -> Iterator[str]:
    """The plugin's module name; afterwards its registration and module are gone (other tests run without it)."""
    yield PLUGIN
    registry.mapping["dataset"].pop(OVON_DATASET_TYPE, None)
    sys.modules.pop(PLUGIN, None)


def test_a_plugin_registering_ovon_v1_keeps_it_and_the_run_reads_with_it(tmp_path: Path, plugin: str) -> None:
    write_released(tmp_path)
    sim = settings_for("oracle", "hm3d-ovon", *SMALL).sim
    spec = HabitatSpec("hm3d-ovon", SPLIT, str(tmp_path), (SIM_OVERRIDE,), plugins=(plugin,))
    env = HabitatEnv(spec, sim)
    try:
        plugin_class = registry.get_dataset(OVON_DATASET_TYPE)
        assert plugin_class.__module__ == PLUGIN  # drivenav's own registration did not replace it
        assert registry.get_dataset(DATASET_TYPES[OVON]) is OVONDataset
        assert type(env.habitat_env._dataset) is plugin_class
        assert len(env.habitat_env.episodes) == 6
    finally:
        env.close()
    chosen = HabitatSpec("hm3d-ovon", SPLIT, str(tmp_path), (SIM_OVERRIDE, "habitat.dataset.type=drivenav-OVON-v1"))
    env = HabitatEnv(chosen, sim)  # the user's override wins
    try:
        assert type(env.habitat_env._dataset) is OVONDataset
    finally:
        env.close()
