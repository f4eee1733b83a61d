"""Pictures for the ablation report: the same episodes through the compared methods, side by side.

Episodes are taken first from the Table II subset (solved by every compared method, start-goal distance above
10 m: the episodes where steps and revisits are compared, paper Sec. V-C), then in benchmark order. Each method's
top-down picture comes from ``drivenav viz`` on its run directory; the first episode of the first method also gets
its MP4. :func:`render_pictures` is the :class:`~drivenav.analysis.ablations.PictureMaker` the command line hands to
``bench ablations`` (eval itself draws nothing).
"""

from __future__ import annotations

import logging
from collections.abc import Sequence
from pathlib import Path

from drivenav.analysis.ablation_data import Pictures
from drivenav.analysis.compare import TABLE_II_MIN_DISTANCE, RunRecords, common_successes
from drivenav.errors import InputError
from drivenav.eval.rundir import RunContents, read_run
from drivenav.viz.episode import episode_material, render_episode_pictures

log = logging.getLogger(__name__)

PICTURES_DIR = "pictures"
MAX_METHODS = 3


def choose_episodes(runs: RunRecords, order: Sequence[str], count: int) -> list[str]:
    """Up to ``count`` episode ids finished by every method: Table II subset first, then in ``order``."""
    if not runs or count <= 0:
        return []
    finished = set.intersection(*(set(records) for records in runs.values()))
    common = set(common_successes(runs, TABLE_II_MIN_DISTANCE))
    ranked = sorted((i for i in order if i in finished), key=lambda i: i not in common)
    return ranked[:count]


def render_pictures(dirs: dict[str, Path], runs: RunRecords, order: Sequence[str], count: int, out: Path) -> Pictures:
    """Top-down pictures of ``count`` episodes for up to three methods under ``out/pictures/<method>/``, paths
    relative to ``out``; an episode that cannot be drawn is logged and left out (the tables never depend on the
    pictures)."""
    methods = list(dirs)[:MAX_METHODS]
    episodes: dict[str, dict[str, str]] = {}
    video: str | None = None
    contents: dict[str, RunContents] = {}
    for episode_id in choose_episodes({m: runs[m] for m in methods}, order, count):
        for method in methods:
            want_video = video is None and method == methods[0]
            folder = out / PICTURES_DIR / method
            try:
                run = contents.get(method) or contents.setdefault(method, read_run(dirs[method]))
                material = episode_material(dirs[method], run, episode_id)
                paths = render_episode_pictures(material, folder, video=want_video)
            except InputError as error:
                log.warning("no pictures for %s / %s: %s", method, episode_id, error)
                continue
            episodes.setdefault(episode_id, {})[method] = paths[0].relative_to(out).as_posix()
            video = video or next((p.relative_to(out).as_posix() for p in paths if p.suffix == ".mp4"), None)
    return Pictures(episodes, video)
