"""`drivenav viz`: pictures and video of a tiny evaluated episode, trace frames, coverage, graceful degradation."""

from __future__ import annotations

import importlib.util
import itertools
import json
import logging
import math
import sys
from pathlib import Path

import numpy as np
import pytest
from PIL import Image

from drivenav.agent.trace import ViewCaptured
from drivenav.benchmarks.generate import generate_episodes
from drivenav.envs.embedded.env import EmbeddedSpec
from drivenav.envs.embedded.library import SceneLibrary
from drivenav.errors import InputError
from drivenav.eval.episodes import load_episodes
from drivenav.eval.rundir import trace_path
from drivenav.eval.runner import RunSpec, evaluate
from drivenav.eval.trace import EpisodeTrace
from drivenav.grid import wrap_angle
from drivenav.settings import load_settings
from drivenav.types import SimConfig
from drivenav.viz import episode as viz_episode
from drivenav.viz.coverage import explored_cells
from drivenav.viz.episode import load_episode, render_episode_pictures
from drivenav.viz.saved_trace import SavedTrace
from drivenav.viz.topdown import LEGEND_WIDTH, Canvas
from drivenav.viz.video import VIDEO_HINT, frame_steps

MAX_STEPS = 40


@pytest.fixture(scope="module")
def run_dir(tmp_path_factory: pytest.TempPathFactory) -> Path:
    """One drive-nav episode of at most 40 steps (geometric reasoner, ground-truth detector: fast)."""
    out = tmp_path_factory.mktemp("run")
    library = SceneLibrary("procedural:1", 0)
    episodes = generate_episodes(library, 1, seed=0)
    models = {"models.reasoner": "geometric", "models.detector": "ground-truth", "sim.max_steps": MAX_STEPS}
    spec = RunSpec(EmbeddedSpec("procedural:1", 0), load_settings("drive-nav", options=models))
    evaluate(episodes, spec, out, show_progress=False)
    return out


def _trace(run_dir: Path) -> SavedTrace:
    episode = load_episodes(run_dir / "episodes.json.gz")[0]
    path = trace_path(run_dir, episode.episode_id)
    return SavedTrace.of(EpisodeTrace.from_json(json.loads(path.read_text()), path), episode)


def test_pictures_and_video(run_dir: Path, tmp_path: Path) -> None:
    paths = render_episode_pictures(load_episode(run_dir, "0"), tmp_path)
    names = [p.name for p in paths]
    assert names[:3] == ["0_topdown.png", "0_start_view.png", "0_end_view.png"]
    assert all(p.stat().st_size > 0 for p in paths)
    sim = SimConfig()
    for view in paths[1:3]:
        assert Image.open(view).size == (3 * sim.width, sim.height)
    library = SceneLibrary("procedural:1", 0)
    canvas = Canvas(library.load(library.scene_ids[0]))
    width, height = Image.open(paths[0]).size
    assert width == canvas.size[0] + LEGEND_WIDTH
    assert height > canvas.size[1]  # the representative views lie under the map
    if importlib.util.find_spec("imageio_ffmpeg") is None:
        assert len(paths) == 3
        return
    import imageio_ffmpeg

    assert names[3] == "0.mp4"
    frames, _ = imageio_ffmpeg.count_frames_and_secs(str(paths[3]))
    assert frames == len(frame_steps(len(_trace(run_dir)))) == len(_trace(run_dir))  # one frame per pose
    reader = imageio_ffmpeg.read_frames(str(paths[3]))
    meta = next(reader)
    reader.close()
    assert meta["size"][1] == sim.height and meta["size"][0] % 2 == 0


def test_without_ffmpeg_writes_pictures_and_a_hint(
    run_dir: Path, tmp_path: Path, monkeypatch: pytest.MonkeyPatch, caplog: pytest.LogCaptureFixture
) -> None:
    monkeypatch.setattr(viz_episode, "video_available", lambda: False)
    with caplog.at_level(logging.WARNING):
        paths = render_episode_pictures(load_episode(run_dir, "0"), tmp_path)
    assert [p.suffix for p in paths] == [".png"] * 3
    assert VIDEO_HINT in caplog.text and 'pip install -e ".[video]"' in VIDEO_HINT
    assert not list(tmp_path.glob("*.mp4"))


def test_no_video_when_not_asked(run_dir: Path, tmp_path: Path) -> None:
    paths = render_episode_pictures(load_episode(run_dir, "0"), tmp_path, video=False)
    assert len(paths) == 3 and not list(tmp_path.glob("*.mp4"))


def test_missing_episode_names_it(run_dir: Path, tmp_path: Path) -> None:
    with pytest.raises(InputError, match="no-such-episode"):
        render_episode_pictures(load_episode(run_dir, "no-such-episode"), tmp_path)


def test_rerun_recording_has_the_streams(run_dir: Path, tmp_path: Path) -> None:
    chunk = pytest.importorskip("rerun.chunk")
    paths = render_episode_pictures(load_episode(run_dir, "0"), tmp_path, video=False, rerun=True)
    assert [p.name for p in paths][-1] == "0.rrd"
    rows: dict[str, int] = {}
    for part in chunk.RrdReader(paths[-1]).stream().collect().stream():
        rows[str(part.entity_path)] = rows.get(str(part.entity_path), 0) + part.num_rows
    trace = _trace(run_dir)
    for stream in ("camera/rgb", "camera/depth", "camera/semantic", "topdown"):
        assert rows[f"/{stream}"] == len(trace)  # one image per pose (short episode: every step shown)
    assert rows["/events"] == len(trace.events)
    assert rows["/timings/directions.fmm"] == len(trace) - 1  # one latency per agent step
    assert len(trace.step_ms["mapping"]) == len(trace) - 1


def test_rerun_without_the_sdk_names_the_extra(run_dir: Path, tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.setitem(sys.modules, "rerun", None)
    with pytest.raises(InputError, match=r"\.\[rerun\]"):
        render_episode_pictures(load_episode(run_dir, "0"), tmp_path, rerun=True)
    assert not list(tmp_path.iterdir())  # nothing written before the error


def test_trace_frames_agree(run_dir: Path) -> None:
    """View yaws (episode frame) through the start pose give the world yaws at their steps."""
    trace = _trace(run_dir)
    views = trace.of_type(ViewCaptured)
    assert views, "a 40-step drive-nav episode records representative views"
    for event in views:
        assert wrap_angle(trace.world_yaw(event.yaw) - trace.pose(event.step).yaw) == pytest.approx(0, abs=1e-3)
    assert trace.to_world((0.0, 0.0)) == pytest.approx(trace.xy(0), abs=1e-3)


def test_segments_cover_the_trajectory(run_dir: Path) -> None:
    trace = _trace(run_dir)
    segments = trace.segments()
    assert segments[0][0] == 0 and segments[-1][1] == len(trace) - 1
    assert all(a[1] == b[0] for a, b in itertools.pairwise(segments))
    moves = trace.move_segments()
    assert len(moves) == len(trace) - 1 and np.all(np.diff(moves) >= 0)


def test_explored_area_is_near_the_trajectory(run_dir: Path) -> None:
    trace = _trace(run_dir)
    library = SceneLibrary("procedural:1", 0)
    scene = library.load(library.scene_ids[0])
    explored = explored_cells(scene, trace, SimConfig())
    cells = scene.grid.cell_to_world(np.argwhere(explored))
    assert len(cells) > 100
    nearest = np.min(np.linalg.norm(cells[:, None, :] - trace.positions[None, :, :], axis=-1), axis=1)
    assert nearest.max() <= 5.0 + scene.grid.resolution


def test_frame_steps_cap_long_episodes() -> None:
    assert frame_steps(41) == list(range(41))
    capped = frame_steps(1001, max_frames=300)
    assert len(capped) <= 301 and capped[0] == 0 and capped[-1] == 1000
    assert len(set(np.diff(capped[:-1]))) == 1 and math.ceil(1001 / 300) == capped[1]
