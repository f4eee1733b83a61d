"""``drivenav report RUN [RUN ...] --out DIR``: the whole static site, entered at ``DIR/index.html``.

``DIR`` holds everything the pages use (styles, script, pictures, videos, the traces and records they link to),
so the site opens from a file path and can be copied anywhere. Episode pages, and the pictures they lack, are
written by ``workers`` processes, each taking one run's episodes in slices.

The report reads only its runs: each run is checked as a resume checks it
(:func:`drivenav.eval.rundir.read_run`), and every file a run names (a record's ``trace``, a picture in ``viz/``)
is resolved, links included, and copied only when it stays inside the run directory; a record naming a file
outside is shown as such on its page. ``DIR`` holds none of the runs; the files the report writes there are listed
in its manifest (:mod:`drivenav.report.manifest`), and a file it did not write is never overwritten.
"""

from __future__ import annotations

import json
import logging
import shutil
from collections.abc import Sequence
from dataclasses import dataclass
from importlib import resources
from pathlib import Path

from drivenav.episode import Episode
from drivenav.errors import InputError
from drivenav.eval.pool import run_in_pool
from drivenav.eval.records import EpisodeRecord
from drivenav.eval.rundir import TRACES_DIR, inside, trace_path
from drivenav.eval.trace import EpisodeTrace
from drivenav.jsonstream import JsonObject
from drivenav.report.config import PictureChoice, ReportConfig
from drivenav.report.episode_page import EpisodeView, Sibling, episode_html
from drivenav.report.episodes_page import episode_page_path, episodes_html, pivot_html, success_text
from drivenav.report.html import ASSETS, SCRIPT, STYLE
from drivenav.report.index_page import index_html
from drivenav.report.manifest import claim, settle
from drivenav.report.paper_tables import paper_tables_html
from drivenav.report.pictures import SUFFIXES, Drawing, EpisodeMedia, draw, drawn_folders, gather
from drivenav.report.runs import Run, load_run, run_names
from drivenav.viz.saved_trace import SavedTrace

log = logging.getLogger(__name__)

INDEX = "index.html"
PICTURES = "pictures"  # a run's pictures in the site
SLICE = 25  # episodes per task: small enough to share a run's pages between the workers
SHOWN = 80  # characters of a record's trace name shown in a note


@dataclass(frozen=True)
class RunPlace:
    """A run as its workers need it: its name, its folder in the site, its own folder, its world record."""

    name: str
    slug: str
    path: Path
    world: JsonObject | None


@dataclass(frozen=True)
class PageItem:
    """One episode page to write: the run, the record and the episode (None without the run's copy of its
    episodes), whether to draw its missing picture, and the other runs' pages of the episode."""

    run: RunPlace
    record: EpisodeRecord
    episode: Episode | None
    draw: bool
    siblings: tuple[Sibling, ...]


@dataclass(frozen=True)
class PageTask:
    """A slice of the episode pages, written by one worker."""

    items: tuple[PageItem, ...]
    out: Path
    config: ReportConfig


def write_report(paths: Sequence[Path], out: Path, config: ReportConfig | None = None) -> Path:
    """Write the site for the runs in ``paths`` into ``out`` (``config``: the defaults when None); returns
    ``out/index.html``."""
    config = config or ReportConfig()
    if not paths:
        raise InputError("command line", "RUN", "at least one run directory", "none")
    runs = [load_run(path, name) for path, name in zip(paths, run_names(paths), strict=True)]
    _check_out(out, runs)
    files = site_files(runs)
    claim(out, files)
    _copy_assets(out / ASSETS)
    tasks = page_tasks(runs, out, config)
    if config.workers > 1 and len(tasks) > 1:
        for _ in run_in_pool(tasks, write_pages, config.workers, key=_task_key):
            pass
    else:
        for task in tasks:
            write_pages(task)
    (out / "episodes.html").write_text(episodes_html(runs), encoding="utf-8")
    (out / "pivot.html").write_text(pivot_html(runs), encoding="utf-8")
    index = out / INDEX
    index.write_text(index_html(runs, paper_tables_html(runs)), encoding="utf-8")
    settle(out, files)
    return index


def _check_out(out: Path, runs: Sequence[Run]) -> None:
    """Refuse an ``--out`` that is a file, or that is or holds one of the runs (the site would write among the
    runs' own files)."""
    if out.exists() and not out.is_dir():
        raise InputError(out, "--out", "a folder for the site", "an existing file")
    site = out.resolve()
    for run in runs:
        if run.path.resolve().is_relative_to(site):
            raise InputError(out, "--out", "a folder that holds none of the runs", f"it holds the run {run.path}")


def site_files(runs: Sequence[Run]) -> list[str]:
    """Every file the site may hold, relative to its folder: the pages and assets, and per episode its page,
    record, trace and pictures (those it has are written; the manifest lists them all)."""
    files = [INDEX, "episodes.html", "pivot.html", f"{ASSETS}/{STYLE}", f"{ASSETS}/{SCRIPT}"]
    for run in runs:
        for record in run.records:
            stem = run.stem(record.episode_id)
            folder = f"runs/{run.slug}"
            files += [
                f"{folder}/episodes/{stem}.html",
                f"{folder}/records/{stem}.json",
                f"{folder}/{TRACES_DIR}/{stem}.json",
            ]
            files += [f"{folder}/{PICTURES}/{stem}{suffix}" for suffix in SUFFIXES]
    return files


def _task_key(task: PageTask) -> str:
    first, last = task.items[0], task.items[-1]
    return f"pages of {first.run.name}/{first.record.episode_id} .. {last.run.name}/{last.record.episode_id}"


def _copy_assets(folder: Path) -> None:
    folder.mkdir(parents=True, exist_ok=True)
    assets = resources.files("drivenav.report").joinpath(ASSETS)
    for name in (STYLE, SCRIPT):
        (folder / name).write_text(assets.joinpath(name).read_text(encoding="utf-8"), encoding="utf-8")


def _wants_picture(record: EpisodeRecord, config: ReportConfig) -> bool:
    if config.pictures is PictureChoice.NONE:
        return False
    return config.pictures is PictureChoice.ALL or not record.success


def page_tasks(runs: Sequence[Run], out: Path, config: ReportConfig) -> list[PageTask]:
    """Every page, in slices of :data:`SLICE` in scene order over all runs (so that a worker loads few scenes to
    draw); the first ``max_pictures`` episodes of a run that want a picture get one drawn."""
    outcomes = {run.name: {r.episode_id: success_text(r.success) for r in run.records} for run in runs}
    items = []
    for run in runs:
        place = RunPlace(run.name, run.slug, run.path, None if run.info is None else run.info.world)
        drawn = 0
        for record in run.records:
            wanted = _wants_picture(record, config) and (config.max_pictures is None or drawn < config.max_pictures)
            drawn += wanted
            siblings = _siblings(runs, outcomes, run, record.episode_id)
            items.append(PageItem(place, record, run.episodes.get(record.episode_id), wanted, siblings))
    items.sort(key=lambda item: item.record.scene_id)
    return [PageTask(tuple(items[first : first + SLICE]), out, config) for first in range(0, len(items), SLICE)]


def _siblings(
    runs: Sequence[Run], outcomes: dict[str, dict[str, str]], run: Run, episode_id: str
) -> tuple[Sibling, ...]:
    """The other runs' pages of the episode (``outcomes``: per run, each episode's success text)."""
    return tuple(
        Sibling(other.name, episode_page_path(other, episode_id), outcomes[other.name][episode_id])
        for other in runs
        if other is not run and episode_id in outcomes[other.name]
    )


# ---------------------------------------------------------------------------------------------- in the workers


def write_pages(task: PageTask) -> int:
    """Write the task's episode pages (copying traces and records, drawing missing pictures); returns how many
    pictures were drawn."""
    return sum(_write_page(item, task.out / "runs" / item.run.slug, task.config) for item in task.items)


def _read_trace(run: RunPlace, record: EpisodeRecord) -> tuple[Path | None, EpisodeTrace | None, str]:
    """The trace file, the trace, and why there is none (a trace that leads out of the run directory, links
    resolved, is neither read nor copied)."""
    name = record.trace or trace_path(Path(), record.episode_id).as_posix()
    if inside(run.path, name) is None:
        return None, None, f"Its trace {name[:SHOWN]!r} leads out of the run directory: not read, not copied."
    path = run.path / name
    if not path.is_file():
        return None, None, "The run has no trace of this episode."
    try:
        return path, EpisodeTrace.from_json(json.loads(path.read_text(encoding="utf-8")), path), ""
    except (ValueError, InputError) as error:
        return path, None, f"Its trace could not be read: {error}"


def _placed(trace: EpisodeTrace | None, episode: Episode | None) -> tuple[SavedTrace | None, str]:
    """The trace placed in the world, and why it cannot be."""
    if trace is None or episode is None:
        return None, "" if episode is not None else "The run has no copy of this episode (no pictures drawn)."
    try:
        return SavedTrace.of(trace, episode), ""
    except ValueError:
        return None, "Its trace has no poses (the episode ended before its start)."


def _write_page(item: PageItem, site: Path, config: ReportConfig) -> int:
    """Write one episode page (drawing its picture when it wants one and has none); returns 1 if it drew one."""
    run, record = item.run, item.record
    stem = trace_path(site, record.episode_id).stem
    trace_file, trace, note = _read_trace(run, record)
    saved, placement = _placed(trace, item.episode)
    sources = drawn_folders(run.path, run.name)
    media = gather(stem, site / PICTURES, sources)
    notes = [note or placement, *_outside(media)]
    drawn = 0
    if not media.pictures and item.draw and saved is not None and item.episode is not None and run.world is not None:
        try:
            draw(Drawing(run.path, run.world, item.episode, saved, record), site / PICTURES, config.views)
            media, drawn = gather(stem, site / PICTURES, sources), 1
        except (InputError, ValueError, OSError) as error:
            notes.append(f"Its picture could not be drawn: {error}")
            log.warning("%s / %s: %s", run.name, record.episode_id, notes[-1])
    view = EpisodeView(
        run.name,
        record,
        trace,
        saved,
        tuple(f"../{PICTURES}/{p.name}" for p in media.pictures),
        None if media.video is None else f"../{PICTURES}/{media.video.name}",
        _copy_trace(trace_file, site, stem),
        _write_record(record, site, stem),
        item.siblings,
        " ".join(note for note in notes if note),
        item.episode,
    )
    page = site / "episodes" / f"{stem}.html"
    page.parent.mkdir(parents=True, exist_ok=True)
    page.write_text(episode_html(view, config), encoding="utf-8")
    return drawn


def _outside(media: EpisodeMedia) -> list[str]:
    """The notes on the pictures found that lead out of their folder (not copied)."""
    return [f"Its picture {p.parent.name}/{p.name} leads out of {where}: not copied." for p, where in media.outside]


def _copy_trace(path: Path | None, site: Path, stem: str) -> str | None:
    """Copy the episode's trace (inside its run, checked) into the site under the episode's own name."""
    if path is None:
        return None
    target = site / TRACES_DIR / f"{stem}.json"
    target.parent.mkdir(parents=True, exist_ok=True)
    shutil.copyfile(path, target)
    return f"../{TRACES_DIR}/{target.name}"


def _write_record(record: EpisodeRecord, site: Path, stem: str) -> str:
    target = site / "records" / f"{stem}.json"
    target.parent.mkdir(parents=True, exist_ok=True)
    target.write_text(json.dumps(record.to_json(), indent=2, sort_keys=True) + "\n", encoding="utf-8")
    return f"../records/{stem}.json"
