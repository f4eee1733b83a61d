"""The ablation report's section on the methods beyond the paper (``ablations.md``): each method's SR and SPL, steps,
revisits and median direction decisions, paired against the method it builds on, and Table II's comparison with
them (:mod:`drivenav.analysis.beyond`)."""

from __future__ import annotations

from drivenav.analysis.ablation_data import AblationReport, Interval, MethodEntry
from drivenav.analysis.beyond import PairedEntry
from drivenav.analysis.compare import Comparison


def beyond_section(report: AblationReport) -> list[str]:
    """The section's lines; none when no method beyond the paper was run with its base."""
    if not report.beyond:
        return []
    lines = [
        "## Beyond the paper",
        "",
        "Our methods beyond the paper (docs/agent.md), each against the method it builds on, on the episodes both "
        "finished: SR wins / losses (episodes solved by one only), the mean SPL difference in points with its 95 % "
        "interval (percentile bootstrap over the paired episodes), and the median direction decisions per episode "
        "(the method's, then its base's).",
        "",
        "| method | base | SR % | SPL % | avg steps | avg revisits | SR wins / losses | ΔSPL | median decisions |",
        "|---|---|---|---|---|---|---|---|---|",
    ]
    for name, paired in report.beyond.items():
        lines.append(_row(name, report.methods[name], paired))
    if report.table_ii_beyond is not None:
        lines += ["", *_table_ii_beyond(report.table_ii_beyond)]
    return lines


def _row(name: str, entry: MethodEntry, paired: PairedEntry) -> str:
    rates = " | ".join(_percent(value, interval) for value, interval in _rates(entry))
    steps, revisits = _number(entry.avg_steps, "{:.1f}"), _number(entry.avg_revisits, "{:.3f}")
    low, high = paired.spl_delta_ci95
    delta = f"{100 * paired.spl_delta:+.2f} [{100 * low:+.2f}, {100 * high:+.2f}]"
    decisions = f"{_number(paired.median_decisions, '{:g}')} / {_number(paired.base_median_decisions, '{:g}')}"
    wins = f"{paired.sr_wins} / {paired.sr_losses} of {paired.episodes}"
    return f"| `{name}` | `{paired.base}` | {rates} | {steps} | {revisits} | {wins} | {delta} | {decisions} |"


def _rates(entry: MethodEntry) -> list[tuple[float | None, Interval | None]]:
    return [(entry.success_rate, entry.sr_ci95), (entry.spl, entry.spl_ci95)]


def _percent(value: float | None, interval: Interval | None) -> str:
    if value is None or interval is None:
        return "n/a"
    return f"{100 * value:.1f} [{100 * interval[0]:.1f}, {100 * interval[1]:.1f}]"


def _number(value: float | None, template: str) -> str:
    return "-" if value is None else template.format(value)


def _table_ii_beyond(table: Comparison) -> list[str]:
    lines = [
        "### Table II with the methods beyond the paper",
        "",
        f"Episodes every method below solved, start-to-goal geodesic distance > {table.min_distance:g} m: "
        f"n = {table.common_episodes}. Lower is better; revisits and retraced as in Table II.",
        "",
        "| method | avg steps | avg revisits | retraced | retraced m |",
        "|---|---|---|---|---|",
    ]
    for name, compared in table.methods.items():
        common = compared.common
        if common is None:
            lines.append(f"| `{name}` | - | - | - | - |")
            continue
        retraced = " | ".join(
            _number(value, "{:.3f}") for value in (common.avg_retraced_revisits, common.avg_retraced_m)
        )
        steps, revisits = _number(common.avg_steps, "{:.1f}"), _number(common.avg_revisits, "{:.3f}")
        lines.append(f"| `{name}` | {steps} | {revisits} | {retraced} |")
    return lines
