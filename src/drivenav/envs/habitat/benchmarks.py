"""The paper's four Habitat benchmarks (Sec. V-A) as presets over habitat-lab's own ObjectNav configs.

Each preset names habitat-lab's benchmark config it starts from, where its episodes and scenes lie under
``--data-dir`` (habitat's ``data/`` folder), its splits, the episode layout and its dataset type. The sensor and
body settings (640x480, HFOV 79, camera 0.88 m, depth 0.5-5.0 m, 500 steps, 30 degree turns, 0.25 m steps) and
the success distance come from drivenav's ``sim`` settings, pushed into habitat-lab's config; the ``--config``
preset of the same name (``drivenav/data/configs/<name>.yaml``) sets the benchmark's success distance: 0.25 m for
HM3D-OVON (its paper's), habitat-lab's ObjectNav value 0.1 m for the others (``habitat/task/objectnav.yaml``),
both measured to the goals' view points.
"""

from __future__ import annotations

from dataclasses import dataclass

OBJECTNAV_V1 = "objectnav-v1"  # habitat-lab's ObjectNav-v1 layout: goals_by_category, content/<scene>.json.gz
OVON = "ovon"  # HM3D-OVON: the same layout plus children_object_categories; read by drivenav's own dataset type
LAYOUTS = (OBJECTNAV_V1, OVON)
DATASET_TYPES = {OBJECTNAV_V1: "ObjectNav-v1", OVON: "drivenav-OVON-v1"}  # habitat-lab's reader; drivenav's
OVON_DATASET_TYPE = "OVON-v1"  # HM3D-OVON's own OVONDatasetV1, used where a --habitat-plugin registers it


@dataclass(frozen=True)
class HabitatBenchmark:
    """One benchmark: habitat-lab config, data locations (relative to ``--data-dir``), splits and layout."""

    name: str
    habitat_config: str
    data_path: str
    scene_dataset: str
    splits: tuple[str, ...]
    layout: str

    @property
    def dataset_type(self) -> str:
        return DATASET_TYPES[self.layout]


_HM3D = "benchmark/nav/objectnav/objectnav_hm3d.yaml"
_MP3D = "benchmark/nav/objectnav/objectnav_mp3d.yaml"
SCENES_DIR = "scene_datasets"  # under --data-dir, as in habitat's data/ folder
_HM3D_SCENES = f"{SCENES_DIR}/hm3d/hm3d_annotated_basis.scene_dataset_config.json"
_MP3D_SCENES = f"{SCENES_DIR}/mp3d/mp3d.scene_dataset_config.json"

BENCHMARKS: dict[str, HabitatBenchmark] = {
    bench.name: bench
    for bench in (
        HabitatBenchmark(
            "hm3d-ovon",
            _HM3D,
            "datasets/ovon/hm3d/v1/{split}/{split}.json.gz",  # where HM3D-OVON's experiment configs read it
            _HM3D_SCENES,
            ("val_seen", "val_seen_synonyms", "val_unseen"),
            OVON,
        ),
        HabitatBenchmark(
            "hm3d-v1",
            _HM3D,
            "datasets/objectnav/hm3d/v1/{split}/{split}.json.gz",
            _HM3D_SCENES,
            ("val",),
            OBJECTNAV_V1,
        ),
        HabitatBenchmark(
            "hm3d-v2",
            _HM3D,
            "datasets/objectnav/hm3d/v2/{split}/{split}.json.gz",
            _HM3D_SCENES,
            ("val",),
            OBJECTNAV_V1,
        ),
        HabitatBenchmark(
            "mp3d",
            _MP3D,
            "datasets/objectnav/mp3d/v1/{split}/{split}.json.gz",
            _MP3D_SCENES,
            ("val",),
            OBJECTNAV_V1,
        ),
    )
}
