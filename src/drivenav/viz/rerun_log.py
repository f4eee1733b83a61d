"""An episode as a Rerun recording (``drivenav viz --rerun``; extra ``drivenav[rerun]``).

The streams of the MP4, separately and on a ``step`` timeline: ``camera/rgb``, ``camera/depth`` (metres),
``camera/semantic`` (instance ids), ``topdown`` (map, trajectory, trace markers, view cone), ``events`` (the
trace's decisions, detections and stops as text) and ``timings/<module>`` (per-step module latency, ms, when the
trace has it). The ``.rrd`` file opens in the Rerun viewer: ``rerun FILE.rrd``.
"""

from __future__ import annotations

import json
from pathlib import Path
from typing import Any

import numpy as np

from drivenav.agent.trace import Event
from drivenav.envs.embedded.building import Building
from drivenav.envs.embedded.scene import Scene
from drivenav.episode import Episode
from drivenav.errors import InputError
from drivenav.types import SimConfig
from drivenav.viz.saved_trace import SavedTrace
from drivenav.viz.video import step_frames

RERUN_HINT = 'Rerun logging needs rerun-sdk: pip install -e ".[rerun]"'
EVENT_FIELDS_SKIPPED = ("kind", "step")


def import_rerun() -> Any:
    """The ``rerun`` module, or a clear error naming the extra to install."""
    try:
        import rerun
    except ImportError:
        raise InputError("command line", "--rerun", RERUN_HINT, "rerun-sdk (not installed)") from None
    return rerun


def event_text(event: Event) -> str:
    """One trace event as a log line: its kind, then its fields (the step is the timeline's)."""
    fields = {k: v for k, v in event.to_dict().items() if k not in EVENT_FIELDS_SKIPPED}
    return f"{event.kind}: {json.dumps(fields, sort_keys=True)}"


def write_rerun(path: Path, world: Scene | Building, episode: Episode, trace: SavedTrace, sim: SimConfig) -> Path:
    """Write the episode's streams to ``path`` (an ``.rrd`` recording; a building's views and map from the floor
    the agent is on)."""
    rr = import_rerun()
    recording = rr.RecordingStream("drivenav", recording_id=f"{episode.scene_id}/{episode.episode_id}")
    recording.save(str(path))
    for module, values in sorted(trace.step_ms.items()):
        for step, value in enumerate(values):
            recording.set_time("step", sequence=step)
            recording.log(f"timings/{module}", rr.Scalars(float(value)))
    for event in trace.events:
        recording.set_time("step", sequence=event.step)
        recording.log("events", rr.TextLog(event_text(event)))
    for frame in step_frames(world, episode, trace, sim):
        recording.set_time("step", sequence=frame.step)
        recording.log("camera/rgb", rr.Image(frame.rgb))
        recording.log("camera/depth", rr.DepthImage(frame.depth, meter=1.0))
        recording.log("camera/semantic", rr.SegmentationImage(np.clip(frame.semantic, 0, 65535).astype(np.uint16)))
        recording.log("topdown", rr.Image(np.asarray(frame.panel)))
    recording.flush()
    recording.disconnect()
    return path
