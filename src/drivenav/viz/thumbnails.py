"""Representative-view thumbnails of the last few direction decisions, re-rendered from the trace.

A candidate direction's view is the frame from the latest :class:`~drivenav.agent.trace.ViewCaptured` event for its
label at or before the decision step: the world pose at that event's step is ``positions[step]``, ``yaws[step]``.
"""

from __future__ import annotations

from PIL import Image, ImageDraw

from drivenav.agent.trace import DirectionSelected, ViewCaptured
from drivenav.envs.embedded.render import Renderer
from drivenav.viz.directions import label_color
from drivenav.viz.saved_trace import SavedTrace
from drivenav.viz.topdown import FONT, SMALL_FONT, darker, stack

THUMB_SIZE = (160, 120)
DECISIONS_SHOWN = 3
CAPTION_WIDTH = 130
TILE_GAP = 10
TILE_CAPTION = 18
CHOSEN_BORDER, OTHER_BORDER = 6, 2
NO_VIEW = (200, 200, 200)


def capture_step(trace: SavedTrace, label: int, decision_step: int) -> int | None:
    """Step of the latest view recorded for ``label`` at or before ``decision_step`` (None if none was)."""
    steps = [e.step for e in trace.of_type(ViewCaptured) if e.label == label and e.step <= decision_step]
    return max(steps, default=None)


def _tile(renderer: Renderer, trace: SavedTrace, label: int, decision_step: int, chosen: bool) -> Image.Image:
    width, height = THUMB_SIZE
    border = CHOSEN_BORDER if chosen else OTHER_BORDER
    color = label_color(label)
    tile = Image.new("RGB", (width + 2 * border, height + 2 * border + TILE_CAPTION), (255, 255, 255))
    draw = ImageDraw.Draw(tile)
    step = capture_step(trace, label, decision_step)
    caption = f"D{label}" + (" chosen" if chosen else "") + (f"   view: step {step}" if step is not None else "")
    draw.text((border, 3), caption, fill=darker(color, 0.8), font=SMALL_FONT)
    draw.rectangle([0, TILE_CAPTION, tile.width - 1, tile.height - 1], fill=color)
    if step is None:
        draw.rectangle([border, TILE_CAPTION + border, border + width, TILE_CAPTION + border + height], fill=NO_VIEW)
        draw.text((border + width / 2, TILE_CAPTION + border + height / 2), "no view", fill=(0, 0, 0), anchor="mm")
    else:
        rgb = Image.fromarray(renderer.render(trace.pose(step))[0]).resize(THUMB_SIZE, Image.Resampling.LANCZOS)
        tile.paste(rgb, (border, TILE_CAPTION + border))
    return tile


def _decision_row(renderer: Renderer, trace: SavedTrace, event: DirectionSelected, width: int) -> Image.Image:
    step, chosen = event.step, event.label
    per_row = max(1, (width - CAPTION_WIDTH) // (THUMB_SIZE[0] + 2 * CHOSEN_BORDER + TILE_GAP))
    labels = sorted(event.candidates, key=lambda label: label != chosen)[:per_row]
    tiles = [_tile(renderer, trace, label, step, label == chosen) for label in labels]
    row = Image.new("RGB", (width, max(t.height for t in tiles) + TILE_GAP), (255, 255, 255))
    draw = ImageDraw.Draw(row)
    lines = (f"step {step}", f"chose D{chosen}", f"({event.reason})")
    for k, line in enumerate(lines):
        draw.text((8, 24 + 18 * k), line, fill=(0, 0, 0), font=FONT if k < 2 else SMALL_FONT)
    x = CAPTION_WIDTH
    for tile in tiles:
        row.paste(tile, (x, 0))
        x += tile.width + TILE_GAP
    return row


def decision_views(renderer: Renderer, trace: SavedTrace, width: int) -> Image.Image | None:
    """Rows of candidate views for the last :data:`DECISIONS_SHOWN` decisions (None without decisions)."""
    decisions = trace.of_type(DirectionSelected)[-DECISIONS_SHOWN:]
    if not decisions:
        return None
    header = Image.new("RGB", (width, 30), (255, 255, 255))
    ImageDraw.Draw(header).text(
        (8, 8),
        f"representative views the reasoner chose among, last {len(decisions)} decisions (re-rendered from the trace)",
        fill=(0, 0, 0),
        font=FONT,
    )
    return stack([header, *(_decision_row(renderer, trace, event, width) for event in decisions)])
