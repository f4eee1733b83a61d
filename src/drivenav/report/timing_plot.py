"""The per-step module timings of an episode (``step_ms`` of its trace) as a small inline SVG line plot."""

from __future__ import annotations

import numpy as np

from drivenav.eval.trace import StepColumns
from drivenav.report.config import ReportConfig
from drivenav.report.html import element, esc

MARGIN = 36  # px left of the plot for the axis labels
SERIES_CLASSES = 8  # the stylesheet colours series series-0 .. series-7


def _binned(values: list[float], points: int) -> np.ndarray:
    """``values`` averaged over at most ``points`` equal bins of steps."""
    data = np.asarray(values, dtype=np.float64)
    if len(data) <= points:
        return data
    edges = np.linspace(0, len(data), points + 1).astype(int)
    return np.add.reduceat(data, edges[:-1]) / np.diff(edges)


def timing_svg(step_ms: StepColumns, config: ReportConfig) -> str:
    """The plot (ms per step, one line per module), or a sentence when the trace has no timings."""
    series = {name: _binned(values, config.plot_points) for name, values in step_ms.items() if values}
    if not series:
        return element("p", "This trace has no per-step timings.")
    width, height = config.plot_width, config.plot_height
    top = max(float(values.max()) for values in series.values()) or 1.0
    steps = max(len(values) for values in step_ms.values())
    lines, legend = [], []
    for k, (name, values) in enumerate(series.items()):
        xs = MARGIN + np.arange(len(values)) * (width - MARGIN) / max(len(values) - 1, 1)
        ys = height - 16 - values / top * (height - 24)
        points = " ".join(f"{x:.1f},{y:.1f}" for x, y in zip(xs, ys, strict=True))
        css = f"series-{k % SERIES_CLASSES}"
        lines.append(f'<polyline class="{css}" points="{points}"><title>{esc(name)}</title></polyline>')
        legend.append(element("li", esc(f"{name}: median {float(np.median(step_ms[name])):.2f} ms"), {"class": css}))
    axes = (
        f'<text x="2" y="12">{top:.0f} ms</text><text x="2" y="{height - 16}">0</text>'
        f'<text x="{width - 2}" y="{height - 2}" text-anchor="end">step {steps}</text>'
        f'<line x1="{MARGIN}" y1="{height - 16}" x2="{width}" y2="{height - 16}"></line>'
    )
    svg = (
        f'<svg class="timings" role="img" aria-label="module time per step" viewBox="0 0 {width} {height}" '
        f'width="{width}" height="{height}">{axes}{"".join(lines)}</svg>'
    )
    return svg + element("ul", "".join(legend), {"class": "legend"})
