"""Run summaries and the readable table printed after an evaluation."""

from __future__ import annotations

from collections import Counter
from typing import Any


def _mean(records: list[dict[str, Any]], key: str) -> float:
    values = [float(r[key]) for r in records if r.get(key) is not None]
    return sum(values) / len(values) if values else 0.0


def summarize(records: list[dict[str, Any]]) -> dict[str, Any]:
    """Aggregate episode records into the ``summary.json`` fields."""
    return {
        "episodes": len(records),
        "success_rate": round(_mean(records, "success"), 6),
        "spl": round(_mean(records, "spl"), 6),
        "avg_steps": round(_mean(records, "steps"), 3),
        "avg_revisits": round(_mean(records, "revisits"), 4),
        "avg_path_length": round(_mean(records, "path_length"), 3),
        "avg_geodesic_distance": round(_mean(records, "geodesic_distance"), 3),
        "avg_distance_to_goal": round(_mean(records, "distance_to_goal"), 3),
        "avg_collisions": round(_mean(records, "collisions"), 3),
        "avg_vlm_calls": round(_mean(records, "vlm_calls"), 3),
        "stop_reasons": dict(sorted(Counter(str(r.get("stop_reason")) for r in records).items())),
    }


def format_table(summary: dict[str, Any], title: str = "") -> str:
    """A plain-text table of a summary, for the terminal."""
    rows = [
        ("episodes", f"{summary['episodes']}"),
        ("success rate", f"{100.0 * summary['success_rate']:.1f} %"),
        ("SPL", f"{100.0 * summary['spl']:.1f} %"),
        ("avg steps", f"{summary['avg_steps']:.1f}"),
        ("avg path length", f"{summary['avg_path_length']:.2f} m"),
        ("avg geodesic distance", f"{summary['avg_geodesic_distance']:.2f} m"),
        ("avg distance to goal", f"{summary['avg_distance_to_goal']:.2f} m"),
        ("avg revisits", f"{summary['avg_revisits']:.3f}"),
        ("avg collisions", f"{summary['avg_collisions']:.2f}"),
        ("avg VLM calls", f"{summary['avg_vlm_calls']:.2f}"),
        ("stop reasons", ", ".join(f"{k}: {v}" for k, v in summary["stop_reasons"].items()) or "-"),
    ]
    width = max(len(name) for name, _ in rows)
    lines = [title] if title else []
    lines.append("-" * (width + 24))
    lines.extend(f"{name:<{width}}  {value}" for name, value in rows)
    lines.append("-" * (width + 24))
    return "\n".join(lines)
