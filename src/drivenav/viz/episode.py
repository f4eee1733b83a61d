"""Pictures and a video of one finished episode (``drivenav viz RUN_DIR EPISODE_ID``).

What is drawn is given typed (:class:`EpisodeMaterial`: the scene, the episode, its trace and record); a caller that
has read its run already (the report, ``bench ablations``' pictures, the demo) builds it with
:func:`episode_material`, and :func:`load_episode` reads one from a run directory for the command line. Writes
``<id>_topdown.png`` (the map with the trace, a legend and the last decisions' representative views),
``<id>_start_view.png`` and ``<id>_end_view.png`` (RGB, depth, semantics) and ``<id>.mp4`` (needs imageio-ffmpeg).
Everything is re-rendered from the saved trace with the default camera (:class:`SimConfig`), each view from the height
the trace gives its pose (a building's views from the floor the agent was on). A building's top-down picture has one
map per storey (:func:`~drivenav.viz.topdown.draw_episode`). A Habitat run gets the top-down picture only, its trace,
decisions and goals on a blank floor (:func:`trace_scene`).
"""

from __future__ import annotations

import json
import logging
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np
from numpy.typing import NDArray
from PIL import Image

from drivenav.envs.embedded.building import Building
from drivenav.envs.embedded.render import Renderer
from drivenav.envs.embedded.scene import Material, Scene
from drivenav.episode import Episode
from drivenav.errors import InputError
from drivenav.eval.records import EpisodeRecord
from drivenav.eval.rundir import EPISODES_COPY, RUN_FILE, RunContents, inside, read_run, trace_path
from drivenav.eval.trace import EpisodeTrace
from drivenav.grid import GridSpec
from drivenav.types import Pose, SimConfig
from drivenav.viz.coverage import explored_floors
from drivenav.viz.rerun_log import import_rerun, write_rerun
from drivenav.viz.saved_trace import SavedTrace
from drivenav.viz.thumbnails import decision_views
from drivenav.viz.topdown import draw_episode, save_png, stack
from drivenav.viz.video import VIDEO_HINT, video_available, write_video
from drivenav.worlds import recorded_world

log = logging.getLogger(__name__)


def _read_json(path: Path, what: str) -> Any:
    if not path.is_file():
        raise InputError(path, what, "a file written by 'drivenav eval'")
    try:
        return json.loads(path.read_text(encoding="utf-8"))
    except ValueError:
        raise InputError(path, what, "valid JSON") from None


def depth_to_rgb(depth: NDArray[np.float32], max_depth: float) -> NDArray[np.uint8]:
    """Depth as a grey image (near bright, far dark)."""
    grey = np.clip(255.0 * (1.0 - depth / max_depth), 0, 255).astype(np.uint8)
    return np.repeat(grey[..., None], 3, axis=2)


def semantic_to_rgb(semantic: NDArray[np.int32]) -> NDArray[np.uint8]:
    """Instance ids as distinct colours (0 black)."""
    ids = semantic.astype(np.uint32)
    rgb = np.stack([(ids * 97) % 256, (ids * 57 + 80) % 256, (ids * 181 + 40) % 256], axis=-1).astype(np.uint8)
    rgb[semantic == 0] = 0
    return rgb


def view_strip(renderer: Renderer, pose: Pose) -> Image.Image:
    """RGB, depth and semantic images side by side for a world pose."""
    rgb, depth, semantic = renderer.render(pose)
    panels = [rgb, depth_to_rgb(depth, renderer.config.max_depth), semantic_to_rgb(semantic)]
    return Image.fromarray(np.concatenate(panels, axis=1))


TRACE_MARGIN = 2.0  # metres of blank floor around a trace drawn without a scene model


def trace_scene(episode: Episode, trace: SavedTrace, resolution: float = 0.05) -> Scene:
    """A blank floor under the trace and the goals: the canvas of worlds whose scenes drivenav cannot draw (Habitat
    runs draw their trajectory, decisions and goals on it)."""
    points = np.array([*(trace.xy(k) for k in range(len(trace))), *episode.view_points_xy()], dtype=np.float64)
    low = points.min(axis=0) - TRACE_MARGIN
    cells = np.ceil((points.max(axis=0) + TRACE_MARGIN - low) / resolution).astype(int)
    grid = GridSpec(resolution, (float(low[0]), float(low[1])), (int(cells[1]), int(cells[0])))
    return Scene(episode.scene_id, grid, np.full(grid.shape, Material.FREE, dtype=np.uint8))


def trace_picture(episode: Episode, trace: SavedTrace, record: EpisodeRecord | None, folder: Path) -> Path:
    """The top-down picture of a trace on a blank floor (worlds whose scenes drivenav cannot draw, a live robot's
    episode): ``folder/<id>_topdown.png``."""
    topdown = draw_episode(trace_scene(episode, trace), episode, trace, record)
    return save_png(topdown, folder / f"{trace_path(folder, episode.episode_id).stem}_topdown.png")


@dataclass(frozen=True)
class EpisodeMaterial:
    """What an episode's pictures are drawn from: its scene or building (None for worlds whose scenes drivenav cannot
    draw), the episode, its trace and its record (None when the run holds none)."""

    scene: Scene | Building | None
    episode: Episode
    trace: SavedTrace
    record: EpisodeRecord | None


def load_episode(run_dir: Path, episode_id: str) -> EpisodeMaterial:
    """The episode ``episode_id`` of the run in ``run_dir``, the run read and checked as every reader reads it
    (:func:`~drivenav.eval.rundir.read_run`)."""
    return episode_material(run_dir, read_run(run_dir), episode_id)


def episode_material(run_dir: Path, run: RunContents, episode_id: str) -> EpisodeMaterial:
    """The episode's scene, episode, trace and record, from a run already read (its trace must stay inside the run
    directory too)."""
    if run.info is None:
        raise InputError(run_dir / RUN_FILE, "run", "a file written by 'drivenav eval'")
    copy = run_dir / EPISODES_COPY
    if run.episodes is None:
        expected = "the run's copy of its episodes (written as its first episodes run; a resume writes it again)"
        raise InputError(copy, "RUN_DIR", expected, "missing")
    episode = next((e for e in run.episodes if e.episode_id == episode_id), None)
    if episode is None:
        raise InputError(copy, "EPISODE_ID", "an episode id of this run", episode_id)
    path = trace_path(run_dir, episode_id)
    if inside(run_dir, path.relative_to(run_dir)) is None:
        raise InputError(path, "trace", "a file inside the run directory", "a link out of it")
    try:
        trace = SavedTrace.of(EpisodeTrace.from_json(_read_json(path, "trace"), path), episode)
    except (KeyError, TypeError, ValueError):
        raise InputError(path, "trace", "positions, yaws and events as written by 'drivenav eval'") from None
    record = next((r for r in run.records if r.episode_id == episode_id), None)
    world, spec = recorded_world(run.info.world, run_dir / RUN_FILE)
    return EpisodeMaterial(world.scene(spec, episode.scene_id, copy), episode, trace, record)


def render_episode_pictures(
    material: EpisodeMaterial, folder: Path, video: bool = True, rerun: bool = False
) -> list[Path]:
    """Top-down map (with the last decisions' views), first/last egocentric views and, when ``video`` is set and
    imageio-ffmpeg is installed, an MP4 of the episode, into ``folder``; with ``rerun``, also a Rerun recording
    (``.rrd``) of the same streams. Returns the written paths."""
    if rerun:
        import_rerun()  # fail before any work without rerun-sdk
    scene, episode, trace, record = material.scene, material.episode, material.trace, material.record
    stem = trace_path(folder, episode.episode_id).stem
    if scene is None:  # a Habitat or robot run: scenes drivenav does not render
        log.warning("not an embedded run: the top-down picture shows the trace and goals only (no scene, views, video)")
        return [trace_picture(episode, trace, record, folder)]
    sim = SimConfig()
    renderer = Renderer(scene, sim)
    topdown = draw_episode(scene, episode, trace, record, explored_floors(scene, trace, sim))
    views = decision_views(renderer, trace, topdown.width)
    written = [save_png(stack([topdown] if views is None else [topdown, views]), folder / f"{stem}_topdown.png")]
    for label, step in (("start", 0), ("end", len(trace) - 1)):
        written.append(save_png(view_strip(renderer, trace.pose(step)), folder / f"{stem}_{label}_view.png"))
    if video and video_available():
        written.append(write_video(folder / f"{stem}.mp4", scene, episode, trace, sim))
    elif video:
        log.warning(VIDEO_HINT)
    if rerun:
        written.append(write_rerun(folder / f"{stem}.rrd", scene, episode, trace, sim))
    return written
