"""An episode as an MP4: the egocentric RGB beside the top-down map, step by step.

Frames are re-rendered from the trace poses (their heights included: a building's views are from the floor the agent
was on); the map is drawn once and the trajectory and trace markers are added to it as the steps go by. A building
has one map per storey, drawn on as the top-down picture draws them (:mod:`drivenav.viz.floors`); a frame shows the
map of the floor the agent is on. Episodes longer than :data:`MAX_FRAMES` poses show every k-th step (and the
last). Needs the optional ``imageio-ffmpeg`` package (``pip install -e ".[video]"``), which ships ffmpeg.
"""

from __future__ import annotations

import importlib.util
import math
from collections import defaultdict
from collections.abc import Iterator
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np
from numpy.typing import NDArray
from PIL import Image, ImageDraw

from drivenav.agent.trace import Event
from drivenav.envs.embedded.building import Building
from drivenav.envs.embedded.render import Renderer
from drivenav.envs.embedded.scene import Scene
from drivenav.episode import Episode
from drivenav.types import SimConfig
from drivenav.viz.floors import floors_of, move_floors, pose_floors
from drivenav.viz.saved_trace import SavedTrace
from drivenav.viz.topdown import (
    FONT,
    HEADER,
    Canvas,
    draw_event,
    draw_floor,
    draw_floor_change,
    draw_move,
    draw_pose,
    draw_view_cone,
    segment_color,
)

FPS = 8
MAX_FRAMES = 600
CURRENT_COLOR = (0, 0, 0)
VIDEO_HINT = 'MP4 videos need imageio-ffmpeg: pip install -e ".[video]"'


def video_available() -> bool:
    return importlib.util.find_spec("imageio_ffmpeg") is not None


def frame_steps(num_poses: int, max_frames: int = MAX_FRAMES) -> list[int]:
    """The steps shown: all of them, or every k-th (and the last) when there are more than ``max_frames``."""
    stride = max(1, math.ceil(num_poses / max_frames))
    steps = list(range(0, num_poses, stride))
    if steps[-1] != num_poses - 1:
        steps.append(num_poses - 1)
    return steps


def _even(n: int) -> int:
    return n + n % 2


@dataclass(frozen=True)
class StepFrame:
    """What the episode looks like at one shown step: the egocentric images and the top-down panel."""

    step: int
    rgb: NDArray[np.uint8]
    depth: NDArray[np.float32]
    semantic: NDArray[np.int32]
    panel: Image.Image


def step_frames(world: Scene | Building, episode: Episode, trace: SavedTrace, sim: SimConfig) -> Iterator[StepFrame]:
    """Every shown step (:func:`frame_steps`): views re-rendered from the trace pose, and the top-down map of the
    agent's floor with the trajectory and trace markers so far, the current view cone and a title line."""
    canvas = Canvas(world, max_side=sim.height - HEADER)
    floors = floors_of(world)
    layers = [draw_floor(floor, episode, canvas) for floor in floors]
    draws = [ImageDraw.Draw(layer) for layer in layers]
    renderer = Renderer(world, sim)
    events: dict[int, list[Event]] = defaultdict(list)
    for event in trace.events:
        events[event.step].append(event)
    moves = trace.move_segments()
    on = pose_floors(world, trace)
    move_on = move_floors(on)
    count = len(trace.segments())
    shown = set(frame_steps(len(trace)))
    for step in range(len(trace)):
        if step > 0:
            draw_move(draws[move_on[step - 1]], canvas, trace, step - 1, segment_color(int(moves[step - 1]), count))
            if on[step] != on[step - 1]:
                draw_floor_change(draws, canvas, trace, on, step - 1)
        for event in events[step]:
            draw_event(draws[on[step]], canvas, trace, event)
        if step not in shown:
            continue
        pose = trace.pose(step)
        rgb, depth, semantic = renderer.render(pose)
        panel = layers[on[step]].copy()
        overlay = ImageDraw.Draw(panel)
        draw_view_cone(overlay, canvas, pose, math.radians(sim.hfov_deg), CURRENT_COLOR)
        draw_pose(overlay, canvas, (pose.x, pose.y), pose.yaw, CURRENT_COLOR)
        where = f"  {floors[on[step]].title}" if len(floors) > 1 else ""
        overlay.text(
            (6, 7),
            f"episode {episode.episode_id} '{episode.object_category}'  step {step}/{len(trace) - 1}{where}",
            fill=(0, 0, 0),
            font=FONT,
        )
        yield StepFrame(step, rgb, depth, semantic, panel)


def _frames(
    world: Scene | Building, episode: Episode, trace: SavedTrace, sim: SimConfig
) -> Iterator[NDArray[np.uint8]]:
    for shown in step_frames(world, episode, trace, sim):
        frame = Image.new("RGB", (_even(sim.width + shown.panel.width), _even(sim.height)), (255, 255, 255))
        frame.paste(Image.fromarray(shown.rgb), (0, 0))
        frame.paste(shown.panel, (sim.width, 0))
        yield np.asarray(frame)


def write_video(path: Path, world: Scene | Building, episode: Episode, trace: SavedTrace, sim: SimConfig) -> Path:
    """Write ``path`` (MP4, H.264, :data:`FPS` frames per second); raises ImportError without imageio-ffmpeg."""
    import imageio_ffmpeg  # type: ignore[import-untyped,import-not-found,unused-ignore]

    writer: Any = None
    try:
        for frame in _frames(world, episode, trace, sim):
            if writer is None:
                height, width = frame.shape[:2]
                writer = imageio_ffmpeg.write_frames(
                    str(path),
                    (width, height),
                    fps=FPS,
                    macro_block_size=2,
                    ffmpeg_log_level="error",
                    output_params=["-preset", "veryfast"],
                )
                writer.send(None)
            writer.send(np.ascontiguousarray(frame))
    finally:
        if writer is not None:
            writer.close()
    return path
