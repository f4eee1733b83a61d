"""An episode's pictures and video for its page: those already drawn are reused, the missing ones drawn once.

A picture already drawn is found, in this order, in the run's ``viz/`` folder (``drivenav viz``, the demo) and in the
``pictures/<method>/`` folder of a ``bench ablations`` directory holding the run; it is copied into the site only
when it stays, links resolved, inside the run directory (the ``bench ablations`` directory for its pictures): a
picture that leads out of it is named on the page, never copied. A missing top-down picture is drawn
when asked: the map with the trajectory, decisions, detections and goals (:func:`drivenav.viz.topdown.draw_episode`,
on a blank floor for worlds whose scenes drivenav cannot draw), or with ``views`` the whole of ``drivenav viz``
(the last decisions' representative views, the start and end views).
"""

from __future__ import annotations

import json
import shutil
from dataclasses import dataclass
from functools import lru_cache
from pathlib import Path

from drivenav.analysis.ablations import RUNS_DIR
from drivenav.envs.embedded.building import Building
from drivenav.envs.embedded.scene import Scene
from drivenav.episode import Episode
from drivenav.eval.records import EpisodeRecord
from drivenav.eval.rundir import EPISODES_COPY, inside, trace_path
from drivenav.jsonstream import JsonObject
from drivenav.viz.episode import EpisodeMaterial, render_episode_pictures, trace_picture
from drivenav.viz.run_pictures import PICTURES_DIR
from drivenav.viz.saved_trace import SavedTrace
from drivenav.viz.topdown import draw_episode
from drivenav.worlds import recorded_world

SUFFIXES = ("_topdown.png", "_start_view.png", "_end_view.png", ".mp4")
"""The files ``drivenav viz`` writes per episode, by the suffix after the episode's stem; the top-down one first."""


@dataclass(frozen=True)
class EpisodeMedia:
    """An episode's pictures (top-down first) and video inside the run's site folder (``None``/empty: none), and
    the pictures found that lead out of their folder's root (not copied)."""

    pictures: tuple[Path, ...] = ()
    video: Path | None = None
    outside: tuple[tuple[Path, str], ...] = ()  # each with the folder it leads out of, in words


@dataclass(frozen=True)
class Source:
    """A folder where pictures of a run may already be, and the folder they must stay inside (links resolved),
    named in words."""

    folder: Path
    root: Path
    root_name: str

    def leads_out(self, path: Path) -> bool:
        """Whether ``path`` (in :attr:`folder`) leads out of :attr:`root`, links resolved."""
        return inside(self.root, path.relative_to(self.root)) is None


def drawn_folders(run_path: Path, run_name: str) -> list[Source]:
    """Where pictures of the run may already be: its ``viz/`` (inside the run) and its ``bench ablations`` pictures
    folder (inside that directory)."""
    folders = [Source(run_path / "viz", run_path, "the run directory")]
    if run_path.parent.name == RUNS_DIR:
        ablations = run_path.parent.parent
        folders.append(Source(ablations / PICTURES_DIR / run_name, ablations, "the bench ablations directory"))
    return folders


def gather(stem: str, target: Path, sources: list[Source]) -> EpisodeMedia:
    """The episode's files in ``target`` (drawn there, or copied there from the first source that has each)."""
    found: list[Path] = []
    outside: list[tuple[Path, str]] = []
    for suffix in SUFFIXES:
        name = f"{stem}{suffix}"
        if not (target / name).is_file():
            source = _first(sources, name, outside)
            if source is None:
                continue
            target.mkdir(parents=True, exist_ok=True)
            shutil.copyfile(source, target / name)
        found.append(target / name)
    pictures = tuple(path for path in found if path.suffix == ".png")
    video = next((path for path in found if path.suffix == ".mp4"), None)
    return EpisodeMedia(pictures, video, tuple(outside))


def _first(sources: list[Source], name: str, outside: list[tuple[Path, str]]) -> Path | None:
    """The first source's file ``name`` (those leading out of their root are added to ``outside``)."""
    for source in sources:
        path = source.folder / name
        if not (path.is_file() or path.is_symlink()):
            continue
        if source.leads_out(path):
            outside.append((path, source.root_name))
        elif path.is_file():
            return path
    return None


PNG_LEVEL = 1  # zlib level of the drawn maps: a third of the default's time to write, for about 1.5 times the bytes
SCENES_KEPT = 16  # scenes kept per drawing process (workers take the pages in scene order)


@lru_cache(maxsize=SCENES_KEPT)
def _scene(world: str, scene_id: str, source: str) -> Scene | Building | None:
    """A scene or building of a recorded world (``world``: its ``run.json`` record as JSON text), or None for worlds
    whose scenes drivenav cannot draw; a few are kept per process."""
    entry, spec = recorded_world(json.loads(world), source)
    return entry.scene(spec, scene_id, Path(source) / EPISODES_COPY)


@dataclass(frozen=True)
class Drawing:
    """What a missing picture is drawn from: the run's folder and world record, the episode, its trace and record."""

    run_path: Path
    world: JsonObject
    episode: Episode
    trace: SavedTrace
    record: EpisodeRecord


def draw(drawing: Drawing, folder: Path, views: bool) -> None:
    """Draw the episode's top-down picture into ``folder`` (with ``views``: every picture ``drivenav viz`` makes,
    but no video)."""
    episode = drawing.episode
    scene = _scene(json.dumps(drawing.world, sort_keys=True), episode.scene_id, str(drawing.run_path))
    if views:
        render_episode_pictures(EpisodeMaterial(scene, episode, drawing.trace, drawing.record), folder, video=False)
        return
    if scene is None:
        trace_picture(episode, drawing.trace, drawing.record, folder)
        return
    picture = draw_episode(scene, episode, drawing.trace, drawing.record)
    folder.mkdir(parents=True, exist_ok=True)
    picture.save(folder / f"{trace_path(folder, episode.episode_id).stem}{SUFFIXES[0]}", compress_level=PNG_LEVEL)
