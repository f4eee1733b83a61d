"""Perception and reasoning regimes (docs/regimes.md): every method under several model pairs, one table.

On the embedded benchmarks every method shares two models drivenav defines, the embedded reasoner and the embedded
detector, whose failures were chosen by us. ``drivenav bench ablations --regimes ...`` runs each method under each
:data:`REGIMES` pair into ``DIR/regimes/<regime>/runs/<method>/`` (resumable, as the ablations are) and writes
``DIR/regimes.json``, ``DIR/regimes.md`` and ``DIR/regimes.csv``: SR / SPL with 95 % intervals, paired wins and
losses against ``drive-nav`` in the same regime, failure causes, and which pairwise orderings of SR hold in every
regime. The oracle pair (:mod:`drivenav.semantics.oracle`) with the exact detector bounds what exploration alone
gives; the detector regimes (:func:`drivenav.semantics.embedded_detector.regime_grounder`) say how much of a
method's result is the detector's model.
"""

from __future__ import annotations

import argparse
import json
from collections.abc import Callable, Mapping, Sequence
from dataclasses import asdict, dataclass
from itertools import combinations
from pathlib import Path

from drivenav.analysis.ablation_data import MethodEntry, Paired
from drivenav.analysis.ablation_report import flatten, percent, versus, write_rows
from drivenav.analysis.ablations import FAILURE_CAUSES, method_entry, paired_outcomes, run_methods
from drivenav.analysis.compare import load_runs
from drivenav.episode import Episode
from drivenav.errors import InputError
from drivenav.eval.executor import Executor
from drivenav.eval.provenance import git_commit
from drivenav.eval.runner import RunSpec
from drivenav.jsonstream import JsonObject

REGIMES_DIR = "regimes"
REFERENCE = "drive-nav"
"""Each method is paired with this one in the same regime."""

_Metric = Callable[[MethodEntry], "float | None"]
"""What a pivot table shows of an entry (SR or SPL)."""


@dataclass(frozen=True)
class Regime:
    """One model pair: the reasoner (``--reasoner``), the frame scorer of VLFM and ApexNav (``--scorer``) and the
    embedded detector's preset (``--detector-regime``), with what it stands for."""

    reasoner: str
    scorer: str
    detector_regime: str
    about: str

    def options(self) -> dict[str, str]:
        """The command-line options (their ``argparse`` names) that set this regime."""
        return {"reasoner": self.reasoner, "scorer": self.scorer, "detector_regime": self.detector_regime}


REGIMES: dict[str, Regime] = {
    "paper": Regime("embedded", "embedded", "paper", "the embedded reasoner and detector: every table's default"),
    "exact-detector": Regime("embedded", "embedded", "exact", "the embedded reasoner, the ground-truth grounder"),
    "strong-detector": Regime("embedded", "embedded", "strong", "the embedded reasoner, a SAM3-class detector"),
    "weak-detector": Regime("embedded", "embedded", "weak", "the embedded reasoner, an OWLv2-class detector"),
    "oracle-reasoner": Regime("oracle", "oracle", "paper", "the oracle reasoner and scorer, the embedded detector"),
    "exploration-bound": Regime("oracle", "oracle", "exact", "the oracle reasoner and scorer, the exact detector"),
}
"""The regimes by name, in the order the tables show them."""

REGIME_OPTIONS = ("--reasoner", "--scorer", "--detector-regime")
"""The options a regime sets, refused beside ``--regimes``."""


def parse_regimes(text: str) -> list[str]:
    """Regime names from ``--regimes a,b,...`` (``all``: every one; duplicates dropped, order kept)."""
    if text.strip() == "all":
        return list(REGIMES)
    names = list(dict.fromkeys(name.strip() for name in text.split(",") if name.strip()))
    for name in names or [text]:
        if name not in REGIMES:
            raise InputError("command line", "--regimes", f"all or comma-separated names ({', '.join(REGIMES)})", name)
    return names


def regime_args(args: argparse.Namespace, regime: str) -> argparse.Namespace:
    """The command line of one regime: ``args`` with the regime's options; any of them given too is refused."""
    for option in REGIME_OPTIONS:
        if getattr(args, option[2:].replace("-", "_"), None) is not None:
            raise InputError("command line", option, "not given with --regimes, which sets it per regime", option)
    return argparse.Namespace(**{**vars(args), **REGIMES[regime].options()})


def run_regimes(
    episodes: list[Episode], specs: Mapping[str, Sequence[RunSpec]], out: Path, executor: Executor | None = None
) -> dict[str, dict[str, Path]]:
    """Each regime's methods (``specs``) through :func:`~drivenav.analysis.ablations.run_methods` into
    ``out/regimes/<regime>/`` (finished episodes are skipped): per regime, each method's run directory."""
    return {regime: run_methods(episodes, by, out / REGIMES_DIR / regime, executor) for regime, by in specs.items()}


@dataclass(frozen=True)
class Cell:
    """One method in one regime: its aggregate and its pairing with :data:`REFERENCE` (None for the reference
    itself, or without it)."""

    entry: MethodEntry
    paired: Paired | None

    def to_json(self) -> JsonObject:
        return {**self.entry.to_json(), "paired": None if self.paired is None else self.paired.to_json()}


@dataclass(frozen=True)
class RegimeReport:
    """What ``regimes.json`` holds: the commit, the episode set, each regime's definition and, per regime and
    method, its :class:`Cell`."""

    commit: str | None
    episodes: int
    episode_set: str
    regimes: dict[str, Regime]
    cells: dict[str, dict[str, Cell]]

    def to_json(self) -> JsonObject:
        return {
            "commit": self.commit,
            "episodes": self.episodes,
            "episode_set": self.episode_set,
            "reference": REFERENCE,
            "regimes": {name: asdict(regime) for name, regime in self.regimes.items()},
            "cells": {r: {m: cell.to_json() for m, cell in by.items()} for r, by in self.cells.items()},
        }

    def methods(self) -> list[str]:
        """Every method, in the order of the first regime that ran it."""
        return list(dict.fromkeys(m for by in self.cells.values() for m in by))


def build_regime_report(dirs: Mapping[str, Mapping[str, Path]], episodes: int, episode_set: str) -> RegimeReport:
    """The report of the finished runs ``dirs`` (per regime, each method's run directory)."""
    cells = {}
    for regime, by_method in dirs.items():
        runs = load_runs(dict(by_method))
        paired = paired_outcomes(runs, REFERENCE)
        cells[regime] = {m: Cell(method_entry(list(records.values())), paired.get(m)) for m, records in runs.items()}
    return RegimeReport(git_commit(), episodes, episode_set, {r: REGIMES[r] for r in dirs}, cells)


def write_regime_report(report: RegimeReport, out: Path) -> None:
    """``regimes.json``, ``regimes.md`` and ``regimes.csv`` into ``out``."""
    (out / "regimes.json").write_text(json.dumps(report.to_json(), indent=2) + "\n", encoding="utf-8")
    (out / "regimes.md").write_text(format_regimes(report), encoding="utf-8")
    rows = [
        {"regime": regime, "method": method, **flatten(cell.to_json())}
        for regime, by in report.cells.items()
        for method, cell in by.items()
    ]
    write_rows(rows, out / "regimes.csv", missing="")


def format_regimes(report: RegimeReport) -> str:
    """``regimes.md``: the regimes, the one table (method by regime), SR and SPL pivots, the orderings."""
    lines = [
        "# Methods under perception and reasoning regimes",
        "",
        f"Commit `{report.commit or 'unknown'}`; episodes: {report.episode_set} ({report.episodes}). Paired wins / "
        f"losses against `{REFERENCE}` in the same regime (episodes both measured). docs/regimes.md defines them.",
        "",
        "| regime | reasoner | scorer | detector | what it stands for |",
        "|---|---|---|---|---|",
        *(
            f"| `{name}` | {r.reasoner} | {r.scorer} | {_detector(r)} | {r.about} |"
            for name, r in report.regimes.items()
        ),
        "",
        *_table(report),
        "",
        *_pivot(report, "SR %", lambda e: e.success_rate),
        "",
        *_pivot(report, "SPL %", lambda e: e.spl),
        "",
        *_decomposition(report),
        *_orderings(report),
    ]
    return "\n".join(lines) + "\n"


def _detector(regime: Regime) -> str:
    return "ground truth" if regime.detector_regime == "exact" else f"embedded, {regime.detector_regime}"


def _table(report: RegimeReport) -> list[str]:
    causes = " | ".join(cause.replace("_", " ") for cause in FAILURE_CAUSES)
    lines = [
        "## Every cell",
        "",
        "| method | regime | episodes | SR % [95 % CI] | SPL % [95 % CI] | steps | revisits | errors "
        f"| vs `{REFERENCE}` W / L | {causes} |",
        "|---|---|---|---|---|---|---|---|---|" + "---|" * len(FAILURE_CAUSES),
    ]
    for method in report.methods():
        for regime, by in report.cells.items():
            cell = by.get(method)
            if cell is None:
                continue
            e = cell.entry
            failures = " | ".join(str(e.failure_causes.get(cause, 0)) for cause in FAILURE_CAUSES)
            lines.append(
                f"| `{method}` | `{regime}` | {e.episodes} | {percent(e.success_rate, e.sr_ci95)} | "
                f"{percent(e.spl, e.spl_ci95)} | {_number(e.avg_steps, 1)} | {_number(e.avg_revisits, 3)} | "
                f"{e.errors} | {versus(method, REFERENCE, cell.paired)} | {failures} |"
            )
    return lines


def _pivot(report: RegimeReport, title: str, value: _Metric) -> list[str]:
    regimes = list(report.cells)
    lines = [
        f"## {title} by regime",
        "",
        "| method | " + " | ".join(f"`{r}`" for r in regimes) + " |",
        "|---|" + "---|" * len(regimes),
    ]
    for method in report.methods():
        shown = [_shown(value(report.cells[r][method].entry)) if method in report.cells[r] else "-" for r in regimes]
        lines.append(f"| `{method}` | " + " | ".join(shown) + " |")
    return lines


DECOMPOSITION = ("exploration-bound", "exact-detector", "paper")
"""The regimes whose SRs take a method's failures apart: the bound, the embedded reasoner, the embedded detector."""


def decomposition(report: RegimeReport, method: str) -> tuple[float, float, float] | None:
    """What ``method`` loses to exploration (100 % less its SR in ``exploration-bound``), to reasoning (that SR less
    its SR with the embedded reasoner, ``exact-detector``) and to perception (that less ``paper``'s), in SR points;
    None unless it ran in all three with measured episodes."""
    rates = [report.cells.get(r, {}).get(method) for r in DECOMPOSITION]
    values = [cell.entry.success_rate for cell in rates if cell is not None]
    if len(values) != len(DECOMPOSITION) or any(v is None for v in values):
        return None
    bound, reasoned, perceived = (100.0 * float(v or 0.0) for v in values)
    return 100.0 - bound, bound - reasoned, reasoned - perceived


def _decomposition(report: RegimeReport) -> list[str]:
    rows = [(m, parts) for m in report.methods() if (parts := decomposition(report, m)) is not None]
    if not rows:
        return []
    lines = [
        "## Where each method's failures come from (SR points)",
        "",
        "To exploration: 100 less the SR of `exploration-bound` (oracle reasoner, exact detector); to reasoning: that "
        "SR less `exact-detector`'s (the embedded reasoner); to perception: that less `paper`'s (the embedded "
        "detector). A negative share is a gain (the embedded model beat the oracle's choice on these episodes).",
        "",
        "| method | to exploration | to reasoning | to perception | SR in `paper` |",
        "|---|---|---|---|---|",
    ]
    for method, (exploration, reasoning, perception) in rows:
        paper = 100.0 - exploration - reasoning - perception
        lines.append(f"| `{method}` | {exploration:.1f} | {reasoning:+.1f} | {perception:+.1f} | {paper:.1f} |")
    return [*lines, ""]


def _number(value: float | None, digits: int) -> str:
    return "n/a" if value is None else f"{value:.{digits}f}"


def _shown(value: float | None) -> str:
    return "n/a" if value is None else f"{100 * value:.1f}"


def orderings(report: RegimeReport) -> tuple[list[str], list[str]]:
    """Each pair of methods run in every regime, by SR: those whose order (ties apart) is the same in every regime,
    and those whose order flips, each as one line naming the regimes."""
    regimes = list(report.cells)
    everywhere = [m for m in report.methods() if all(m in report.cells[r] for r in regimes)]
    held, flipped = [], []
    for a, b in combinations(everywhere, 2):
        signs = {
            r: _sign(report.cells[r][a].entry.success_rate, report.cells[r][b].entry.success_rate) for r in regimes
        }
        above = [r for r, s in signs.items() if s > 0]
        below = [r for r, s in signs.items() if s < 0]
        if above and below:
            flipped.append(f"`{a}` above `{b}` in {_names(above)}; below in {_names(below)}")
        elif above or below:
            high, low = (a, b) if above else (b, a)
            ties = [r for r, s in signs.items() if s == 0]
            tied = f" (tied in {_names(ties)})" if ties else ""
            held.append(f"`{high}` above `{low}` in every regime{tied}")
        else:
            held.append(f"`{a}` and `{b}` tied in every regime")
    return held, flipped


def _orderings(report: RegimeReport) -> list[str]:
    held, flipped = orderings(report)
    lines = ["## Orderings by SR", "", "Held in every regime:", ""]
    lines += [f"- {line}" for line in held] or ["- none"]
    lines += ["", "Flipped between regimes:", ""]
    return lines + ([f"- {line}" for line in flipped] or ["- none"])


def _sign(a: float | None, b: float | None) -> int:
    if a is None or b is None:
        return 0
    return (a > b) - (a < b)


def _names(regimes: Sequence[str]) -> str:
    return ", ".join(f"`{r}`" for r in regimes)
