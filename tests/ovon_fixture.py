"""A split in HM3D-OVON's released form (``tests/data/ovon-released``), for both test suites.

The fixture is drivenav's own, written by hand in the shape HM3D-OVON's generator writes its files (every episode
field habitat-lab's ``Episode`` serialises, ``children_object_categories``, goal ids as ``"<category>_<n>"``, view
points with ``iou`` 0.0 and ``radius``, floats to 5 decimals, ``info`` with ``geodesic_distance`` and
``euclidean_distance``, the split file ``{"goals_by_category": {}, "episodes": []}``) over two procedural houses
named as HM3D scenes (``hm3d/val/00800-house_00000/house_00000.basis.glb``), with values from drivenav's embedded
scenes. Its cases: a category with children (two with goals, one without a key), a child category's own episode,
a synonym episode ("couch": its goals keyed and categorised "couch", ids ``sofa_<n>``), and episode ids that
repeat across the two content files. The files are plain JSON here and gzipped where a test puts the split.
"""

from __future__ import annotations

import gzip
import json
from pathlib import Path
from typing import Any

from drivenav.envs.habitat.benchmarks import BENCHMARKS

FIXTURE = Path(__file__).parent / "data" / "ovon-released"
SPLIT = "val_seen"


def fixture_files() -> dict[str, Any]:
    """The fixture's documents by their path in the split (``val_seen.json.gz``, ``content/<scene>.json.gz``)."""
    root = FIXTURE / SPLIT
    return {
        str(path.relative_to(root)).removesuffix(".json") + ".json.gz": json.loads(path.read_text())
        for path in sorted(root.rglob("*.json"))
    }


def write_released(data_dir: Path) -> Path:
    """The fixture gzipped where the ``hm3d-ovon`` preset reads its ``val_seen`` split under ``data_dir``; returns
    the split file."""
    split_file = data_dir / BENCHMARKS["hm3d-ovon"].data_path.format(split=SPLIT)
    for name, document in fixture_files().items():
        target = split_file.parent / name
        target.parent.mkdir(parents=True, exist_ok=True)
        target.write_bytes(gzip.compress(json.dumps(document).encode(), mtime=0))
    return split_file


def read_documents(split_file: Path) -> dict[str, Any]:
    """Every document of a written split by its path in the split, as :func:`fixture_files` gives them."""
    root = split_file.parent
    return {
        str(path.relative_to(root)): json.loads(gzip.decompress(path.read_bytes()))
        for path in sorted(root.rglob("*.json.gz"))
    }
