"""A plugin that registers a dataset under HM3D-OVON's own name, ``OVON-v1``, as ``--habitat-plugin ovon`` does
with HM3D-OVON's ``OVONDatasetV1`` (tests only; HM3D-OVON's code is not used here). Its class reads like
drivenav's; what a test checks is whose class a run builds."""

from __future__ import annotations

from habitat.core.registry import registry

from drivenav.envs.habitat.benchmarks import OVON_DATASET_TYPE
from drivenav.envs.habitat.ovon import OVONDataset


@registry.register_dataset(name=OVON_DATASET_TYPE)
class PluginDataset(OVONDataset):  # type: ignore[misc]
    """The plugin's dataset class."""
