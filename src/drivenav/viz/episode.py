"""Pictures of one finished episode from a run directory (``drivenav viz RUN_DIR EPISODE_ID``)."""

from __future__ import annotations

import json
from pathlib import Path
from typing import Any

import numpy as np
from numpy.typing import NDArray
from PIL import Image

from drivenav.envs.base import Pose, SimConfig
from drivenav.envs.library import SceneLibrary
from drivenav.envs.render import render_views
from drivenav.envs.scene import Scene
from drivenav.errors import InputError
from drivenav.eval.episodes import load_episodes
from drivenav.eval.runner import EPISODES_FILE, RUN_FILE, read_finished, trace_path
from drivenav.viz.topdown import draw_episode


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


def view_strip(scene: Scene, pose: Pose, sim: SimConfig) -> Image.Image:
    """RGB, depth and semantic images side by side for a world pose."""
    rgb, depth, semantic = render_views(scene, pose, sim)
    panels = [rgb, depth_to_rgb(depth, sim.max_depth), semantic_to_rgb(semantic)]
    return Image.fromarray(np.concatenate(panels, axis=1))


def render_episode_pictures(run_dir: Path, episode_id: str, out: Path | None = None) -> list[Path]:
    """Top-down map and first/last egocentric views of an episode; returns the written paths."""
    run = _read_json(run_dir / RUN_FILE, "run")
    episodes = {e.episode_id: e for e in load_episodes(run_dir / "episodes.json.gz")}
    if episode_id not in episodes:
        raise InputError(run_dir / "episodes.json.gz", "EPISODE_ID", "an episode id of this run", episode_id)
    episode = episodes[episode_id]
    trace = _read_json(trace_path(run_dir, episode_id), "trace")
    records = {r["episode_id"]: r for r in read_finished(run_dir / EPISODES_FILE)}
    library = SceneLibrary(str(run["scenes"]), int(run["seed"]))
    scene = library.load(episode.scene_id)
    folder = out or run_dir / "viz"
    folder.mkdir(parents=True, exist_ok=True)
    stem = trace_path(folder, episode_id).stem
    topdown = folder / f"{stem}_topdown.png"
    draw_episode(scene, episode, trace["positions"], trace["yaws"], records.get(episode_id), topdown)
    written = [topdown]
    for label, index in (("start", 0), ("end", -1)):
        x, y = trace["positions"][index]
        path = folder / f"{stem}_{label}_view.png"
        view_strip(scene, Pose(x, y, trace["yaws"][index]), SimConfig()).save(path)
        written.append(path)
    return written
