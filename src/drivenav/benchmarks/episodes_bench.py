"""``drivenav bench episodes``: what a large episode file costs before its first episode runs (the goal: a
100,000-episode file starts within about 10 s and holds under 5 KB per episode).

The file repeats 200 generated episodes under new ids, as a large benchmark repeats a scene's goals: the cost of
reading it (streamed), of checking it against the scenes, of the episodes' digest that ``run.json`` records, and of
writing the run's copy of it (done alongside the first episodes), and the memory the episodes hold.
"""

from __future__ import annotations

import gc
import gzip
import json
import tempfile
import time
import tracemalloc
from pathlib import Path

from drivenav.benchmarks.generate import generate_episodes
from drivenav.envs.embedded.library import SceneLibrary
from drivenav.eval.episodes import episode_to_dict, load_episodes, save_episodes, validate_for_scenes
from drivenav.eval.rundir import episodes_sha256
from drivenav.types import SimConfig

DISTINCT = 200  # generated episodes the file repeats
SCENES = "procedural"


def write_repeated(path: Path, count: int, distinct: int = DISTINCT, seed: int = 0) -> None:
    """An episodes file of ``count`` episodes: ``distinct`` generated ones repeated under new ids."""
    base = [episode_to_dict(e) for e in generate_episodes(SceneLibrary(SCENES, seed), min(count, distinct), seed)]
    with gzip.open(path, "wt", encoding="utf-8", compresslevel=6) as out:
        out.write('{"episodes":[')
        for k in range(count):
            item = {**base[k % len(base)], "episode_id": f"ep{k:07d}"}
            out.write(("," if k else "") + json.dumps(item, separators=(",", ":")))
        out.write("]}")


def _seconds(start: float) -> float:
    return round(time.perf_counter() - start, 2)


def bench_episodes(count: int) -> dict[str, object]:
    """Seconds to read, check and digest a ``count``-episode file and to write its copy; the memory the episodes
    hold once read and at the peak of reading (traced, in a separate read)."""
    with tempfile.TemporaryDirectory() as folder:
        source = Path(folder) / "episodes.json.gz"
        write_repeated(source, count)
        held, peak = traced_read(source)
        start = time.perf_counter()
        episodes = load_episodes(source)
        read_s = _seconds(start)
        start = time.perf_counter()
        validate_for_scenes(episodes, SceneLibrary(SCENES, 0), source, SimConfig())
        check_s = _seconds(start)
        start = time.perf_counter()
        episodes_sha256(episodes)
        digest_s = _seconds(start)
        start = time.perf_counter()
        save_episodes(episodes, Path(folder) / "copy.json.gz")
        copy_s = _seconds(start)
        file_mb = round(source.stat().st_size / 1e6, 1)
    return {
        "episodes": count,
        "file_mb": file_mb,
        "read_s": read_s,
        "check_s": check_s,
        "digest_s": digest_s,
        "copy_s": copy_s,
        "held_bytes_per_episode": round(held / count),
        "peak_bytes_per_episode": round(peak / count),
    }


def traced_read(source: Path) -> tuple[int, int]:
    """Bytes the read episodes hold, and the peak while reading (tracemalloc)."""
    gc.collect()
    tracemalloc.start()
    try:
        episodes = load_episodes(source)
        held, peak = tracemalloc.get_traced_memory()
    finally:
        tracemalloc.stop()
    del episodes
    return held, peak
