"""The run directory: a lock, what the run was started with (``run.json``), records, traces and the summary.

``DIR/.lock`` is held (``flock``) by the one process writing the directory: a second evaluation into it is
refused at once, and a lock left by a dead process is free again (the kernel drops it with the process).
``DIR/run.json`` records the resolved settings, the episodes' sha256, the package version, the git commit and
whether its tree was dirty, and a plug-in explorer's entry point and distribution; resuming with other settings or
other episodes is refused, naming the first differing key (or ``episodes``), and so is resuming records without
their ``run.json``. On resume the writer cuts a torn last line off ``episodes.jsonl`` (readers never write) and
refuses a second record of an episode or a record of an episode outside the run, naming its line. An episode lost to
a server the run depends on (:func:`lost_to_a_server`: the served grounder or the robot stopped answering, or
restarted, while a request of it waited) is recorded as an error, but is no result of its agent's: a resume takes
its record out and runs it again, and so does it with the episodes that failed to start
(:func:`start_up_failures`: ``error`` records of no step before the first record that is not an error); the
records taken out are kept in ``DIR/redone.jsonl``, which no reader reads.
``DIR/traces/`` holds one trace per episode under a bounded name that no two ids share (:func:`trace_path`); the
record names it, and a trace that cannot be written never costs the record.

Readers (``compare``, ``report``, ``viz``, ``bench ablations``' tables) read a run through :func:`read_run`, which
checks it as a resume does, with the same checker and the same lines: every record's types and ranges
(:meth:`EpisodeRecord.from_json`), one record per episode, only episodes of the run (those of its copy), only
records of the run's agent (``run.json``'s ``run.agent``: a record naming another, ``vlfm`` in a ``drive-nav`` run,
is refused, naming its line and ``record.agent``; :func:`~drivenav.eval.records.check_agent`), and the copy itself
against ``run.json``'s ``episodes_sha256``. Every file a run names is opened through :func:`inside`:
resolved, links included, it must stay inside the run directory.
"""

from __future__ import annotations

import fcntl
import hashlib
import json
import logging
import os
import threading
from collections.abc import Callable, Iterator, Sequence
from contextlib import contextmanager
from dataclasses import dataclass, replace
from functools import partial
from pathlib import Path
from typing import IO, Any

from drivenav.agent.explorers import EXPLORERS
from drivenav.envs.base import EnvSpec
from drivenav.episode import Episode
from drivenav.errors import InputError, RunStoppedError, one_line
from drivenav.eval.episodes import episode_texts, load_episodes, save_episodes
from drivenav.eval.provenance import package_version, source_state
from drivenav.eval.records import EpisodeRecord, cut_torn_tail, read_records
from drivenav.eval.report import Summary
from drivenav.eval.run_info import RunInfo, explorer_plugin, world_json
from drivenav.eval.trace import EpisodeTrace
from drivenav.jsonstream import JsonObject
from drivenav.settings import Settings, missing_explorer, uninstalled_explorer

EPISODES_FILE = "episodes.jsonl"
SUMMARY_FILE = "summary.json"
RUN_FILE = "run.json"
TRACES_DIR = "traces"
LOCK_FILE = ".lock"
EPISODES_COPY = "episodes.json.gz"  # the run's episodes, for pictures and reruns
REDONE_FILE = "redone.jsonl"  # the records a resume took out to run their episodes again (no reader reads them)
READABLE_ID = 64  # an episode id of at most this many file-name-safe characters is its own trace name
LOST_TO_A_SERVER = ("GrounderUnavailableError", "RobotUnavailableError")
"""The errors of a request a server lost (``drivenav.semantics.served`` and ``drivenav.wire.client``: no reply by
its deadline, or a restarted server), by name as a record's ``error`` starts; an ERROR reply (``...RefusedError``)
is an answer, and its record stays."""

log = logging.getLogger(__name__)


def episodes_sha256(episodes: Sequence[Episode]) -> str:
    """A digest of the episodes as written to an episodes file (order included)."""
    digest = hashlib.sha256(b"[")
    for i, text in enumerate(episode_texts(episodes, sort_keys=True)):
        digest.update(f",{text}".encode() if i else text.encode())
    digest.update(b"]")
    return digest.hexdigest()


def file_name(text: str) -> str:
    """A file name for ``text`` that no other text shares: ``text`` itself when it is at most :data:`READABLE_ID`
    letters, digits and ``-_.`` (not only dots), else a readable prefix and a hash of the whole text,
    ``PREFIX~HASH`` (``~`` is in no plain name, so no two texts share a name, and it stays short whatever the
    text's length). Episode ids name their traces with it, run names their folders in a report."""
    plain = "".join(ch if ch.isascii() and (ch.isalnum() or ch in "-_.") else "_" for ch in text)
    if plain == text and 0 < len(text) <= READABLE_ID and text.strip(".") != "":
        return text
    digest = hashlib.sha256(text.encode("utf-8", "surrogatepass")).hexdigest()[:16]
    return f"{plain[:READABLE_ID]}~{digest}"


def lost_to_a_server(record: EpisodeRecord) -> bool:
    """Whether ``record`` is of an episode a server lost (:data:`LOST_TO_A_SERVER`): a resume runs it again."""
    return record.is_error and record.error.split(":", 1)[0] in LOST_TO_A_SERVER


def trace_path(out: Path, episode_id: str) -> Path:
    """The trace file of ``episode_id``: ``ID.json`` for a plain id (as before), else ``PREFIX~HASH.json``
    (:func:`file_name`)."""
    return out / TRACES_DIR / f"{file_name(episode_id)}.json"


def inside(root: Path, name: str | Path) -> Path | None:
    """``root / name`` with every link resolved, or None when it leads out of ``root`` (an absolute name, ``..``,
    a link out of it or a link loop): the only way a reader opens a file that a run directory names."""
    try:
        base = root.resolve()
        path = (base / name).resolve()
    except (OSError, RuntimeError, ValueError):  # a link loop, a NUL in the name
        return None
    return path if path.is_relative_to(base) else None


def write_json_atomic(path: Path, payload: Any) -> None:
    """Write ``payload`` to a fresh temporary file (one left there, a link included, is removed first: nothing is
    written through it) and rename it over ``path``."""
    tmp = path.with_suffix(path.suffix + ".tmp")
    tmp.unlink(missing_ok=True)
    tmp.write_text(json.dumps(payload, indent=2, sort_keys=True) + "\n", encoding="utf-8")
    os.replace(tmp, path)


def make_directory(out: Path) -> None:
    """Create ``out`` (and its parents) as a writable directory, or an :class:`InputError` on ``--out``."""
    if out.exists() and not out.is_dir():
        raise InputError(out, "--out", "a directory (a run directory, rerun to resume)", "an existing file")
    try:
        (out / TRACES_DIR).mkdir(parents=True, exist_ok=True)
    except OSError as error:
        raise InputError(out, "--out", "a directory drivenav can create", error.strerror) from None
    if not os.access(out, os.W_OK | os.X_OK) or not os.access(out / TRACES_DIR, os.W_OK | os.X_OK):
        raise InputError(out, "--out", "a writable directory", "no write permission")


@dataclass(frozen=True)
class RunContents:
    """A run directory as its readers see it, checked (:func:`read_run`): ``run.json`` (None without one), the copy
    of its episodes (None without one: a run killed before writing it), and its records in file order."""

    info: RunInfo | None
    episodes: tuple[Episode, ...] | None
    records: tuple[EpisodeRecord, ...]


def read_run(out: Path) -> RunContents:
    """The run in ``out``, read only and checked as a resume checks it (see the module docstring): the first thing
    that is not what drivenav wrote is one :class:`InputError` naming its file, line and field. Without a copy of
    the episodes the records' episode ids cannot be checked; without ``run.json``, the copy cannot."""
    results = run_file(out, EPISODES_FILE)
    if results is None:
        raise InputError(out, "RUN", "a run directory (episodes.jsonl written by 'drivenav eval')", "no episodes.jsonl")
    info_file = run_file(out, RUN_FILE)
    info = None if info_file is None else RunInfo.from_json(_read_json(info_file), info_file, reading=True)
    copy = run_file(out, EPISODES_COPY)
    episodes = None
    if copy is not None:
        episodes = tuple(load_episodes(copy, require_goals=False))
        if info is not None and episodes_sha256(episodes) != info.episodes_sha256:
            expected = f"the episodes whose sha256 {RUN_FILE} records (episodes_sha256)"
            raise InputError(copy, "episodes", expected, "a copy of other episodes")
    ids = None if episodes is None else frozenset(e.episode_id for e in episodes)
    agent = None if info is None else info.agent
    return RunContents(info, episodes, tuple(read_records(results, ids, agent)))


def run_file(out: Path, name: str) -> Path | None:
    """The run's file ``name`` (None when there is none); an :class:`InputError` when it leads out of the run
    directory (:func:`inside`) or is no regular file (a folder, a pipe)."""
    if inside(out, name) is None:
        raise InputError(out / name, name, "a file inside the run directory", "a link out of it")
    path = out / name
    if not path.exists():
        return None
    if not path.is_file():
        raise InputError(path, name, "a regular file written by 'drivenav eval'", "something else")
    return path


class RunDirectory:
    """An open, locked run directory (see the module docstring); records are appended kill-safely."""

    def __init__(self, out: Path, episode_ids: frozenset[str], agent: str, setup: _Setup) -> None:
        """Open the run's records of ``agent``: ``finished`` holds the episodes they finished (a duplicate or
        foreign record, or one of another agent, is an :class:`InputError` here, before any episode runs)."""
        self.out = out
        self.results = out / EPISODES_FILE
        self._episode_ids = episode_ids
        self._agent = agent
        self._setup = setup
        self.finished = frozenset(r.episode_id for r in self.records())  # checked before any episode runs

    @staticmethod
    @contextmanager
    def open(out: Path, world: EnvSpec, settings: Settings, episodes: Sequence[Episode]) -> Iterator[RunDirectory]:
        """Create or resume ``out`` for a run in ``world`` with ``settings`` over ``episodes``; held locked until
        left. A new run writes ``run.json`` and the copy of its episodes while its first episodes run
        (:class:`_Setup`)."""
        make_directory(out)
        for name in (LOCK_FILE, RUN_FILE, EPISODES_FILE, EPISODES_COPY, SUMMARY_FILE, REDONE_FILE):
            run_file(out, name)  # never written through a link out of the run
        if inside(out, TRACES_DIR) is None:
            raise InputError(out / TRACES_DIR, TRACES_DIR, "a folder inside the run directory", "a link out of it")
        with _locked(out / LOCK_FILE):
            info_file = out / RUN_FILE
            results = out / EPISODES_FILE
            if info_file.exists():
                info = _run_info(world, settings, episodes)
                info.check_resume(_read_json(info_file), info_file)
                setup = _Setup(partial(_repair_episodes_copy, out / EPISODES_COPY, episodes, info.episodes_sha256))
            elif results.exists() and results.stat().st_size:
                raise InputError(
                    info_file,
                    "run.json",
                    "the run.json of the run whose records are in episodes.jsonl, to resume it "
                    "(without it the settings cannot be checked: start a new --out)",
                    "missing",
                )
            else:
                copy = partial(save_episodes, episodes, out / EPISODES_COPY)
                setup = _Setup(copy, run_file=partial(_write_run_file, out, world, settings, episodes))
            cut_torn_tail(results)
            _take_out_reruns(results, settings.run.agent)
            with setup.alongside():
                yield RunDirectory(out, frozenset(e.episode_id for e in episodes), settings.run.agent, setup)

    def records(self) -> list[EpisodeRecord]:
        """The run's records (a duplicate, a record of an episode outside the run or of another agent is an
        :class:`InputError`)."""
        return read_records(self.results, self._episode_ids, self._agent)

    def save(self, record: EpisodeRecord, trace: EpisodeTrace) -> None:
        """The trace first, then the record (naming the trace and the run's agent) appended, flushed and fsync'ed:
        the record marks the episode finished. A trace that cannot be written is logged and the record kept, with
        no trace named."""
        self._setup.wait_ready()
        path = trace_path(self.out, record.episode_id)
        try:
            path.write_text(json.dumps(trace.to_json()), encoding="utf-8")
            named = replace(record, trace=f"{TRACES_DIR}/{path.name}")
        except (OSError, TypeError, ValueError) as error:
            log.warning("episode %r: its trace could not be written (%s); the record is kept", record.episode_id, error)
            named = replace(record, trace="")
        named = replace(named, agent=self._agent)  # the run's, whatever the agent object calls itself (a stand-in)
        with self.results.open("a", encoding="utf-8") as handle:
            handle.write(json.dumps(named.to_json(), sort_keys=True) + "\n")
            handle.flush()
            os.fsync(handle.fileno())

    def write_summary(self, summary: Summary) -> None:
        write_json_atomic(self.out / SUMMARY_FILE, summary.to_json())


JOIN_ON_ERROR_S = 2.0  # how long a run that stops on an error waits for its set-up


def _run_info(world: EnvSpec, settings: Settings, episodes: Sequence[Episode]) -> RunInfo:
    commit, dirty = source_state()
    name = settings.explorer.name
    plugin = EXPLORERS.declared[name] if EXPLORERS.is_plugin(name) else None
    return RunInfo(settings, world_json(world), episodes_sha256(episodes), package_version(), commit, dirty, plugin)


def refuse_missing_explorer(out: Path) -> None:
    """One :class:`InputError` line when ``out`` holds a run whose explorer is not installed (a plug-in since
    uninstalled), naming the entry point and the package to install: what a resume of it says before its
    ``--agent`` is read. Anything else about ``run.json`` is left to the resume's own checks."""
    path = out / RUN_FILE
    if inside(out, RUN_FILE) is None or not path.is_file():
        return
    try:
        data = _read_json(path)
        plugin = explorer_plugin(data, path)
    except InputError:
        return
    name = uninstalled_explorer(data.get("config"))
    if name is not None:
        error = missing_explorer(name, plugin)
        raise InputError(path, f"config.{error.field}", error.expected, error.got)


def _write_run_file(out: Path, world: EnvSpec, settings: Settings, episodes: Sequence[Episode]) -> None:
    write_json_atomic(out / RUN_FILE, _run_info(world, settings, episodes).to_json())


class _Setup:
    """What a run writes besides its records, done in a thread while the first episodes run: a new run's
    ``run.json`` (the episodes' digest takes seconds for 100,000 episodes), then the copy of its episodes (half a
    minute to compress). No record is written before ``run.json`` (:meth:`wait_ready`), so a run killed meanwhile
    leaves no record without it; a copy cut short is written to a temporary name, and a resume writes it again."""

    def __init__(self, copy: Callable[[], None], run_file: Callable[[], None] | None = None) -> None:
        self._copy = copy
        self._run_file = run_file
        self._ready = threading.Event()
        if run_file is None:
            self._ready.set()
        self._failure = ""

    def _run(self) -> None:
        try:
            if self._run_file is not None:
                self._run_file()
                self._ready.set()
            self._copy()
        except Exception as error:  # a full disk must not stop the run here: wait_ready reports a missing run.json
            self._failure = one_line(error)
            log.warning("the run directory's set-up failed (%s); rerun the same command to repair it", self._failure)

    @contextmanager
    def alongside(self) -> Iterator[None]:
        """Run the set-up while the body runs; wait for it when the body ends, at most :data:`JOIN_ON_ERROR_S`
        when it ends in an error or an interrupt."""
        thread = threading.Thread(target=self._run, name="run-setup", daemon=True)
        thread.start()
        try:
            yield
        except BaseException:
            thread.join(JOIN_ON_ERROR_S)
            raise
        thread.join()
        self.wait_ready()

    def wait_ready(self) -> None:
        """Block until ``run.json`` is written; a :class:`RunStoppedError` if it could not be."""
        while not self._ready.wait(0.1):
            if self._failure:
                raise RunStoppedError(f"the run's run.json could not be written ({self._failure}); no record was")


def start_up_failures(records: Sequence[EpisodeRecord]) -> list[EpisodeRecord]:
    """The records of episodes that failed to start: ``error`` records of no step, before the run's first record
    that is not an error (file order). Those are what the fail-fast rule stops on when the first episodes all end
    in one exception as they start (a model that cannot be built, an explorer that raises in its constructor), and
    a resume runs them again. An error after some steps, or after an episode that ended without one, is a result of
    its agent's and stays."""
    first_result = next((i for i, r in enumerate(records) if not r.is_error), len(records))
    return [r for r in records[:first_result] if r.steps == 0]


def _take_out_reruns(results: Path, agent: str) -> None:
    """Take out of ``results`` the records a resume runs again: episodes a server lost and episodes that failed to
    start (:func:`start_up_failures`), each kind said in one line. The records taken out are appended to
    :data:`REDONE_FILE` (flushed and fsync'ed) before a new ``results`` without them replaces the old at once, so a
    kill leaves one or the other and loses no record; readers never read them again."""
    if not results.exists():
        return
    records = read_records(results, agent=agent)
    lost = {r.episode_id for r in records if lost_to_a_server(r)}
    failed = {r.episode_id for r in start_up_failures([r for r in records if r.episode_id not in lost])}
    if not lost and not failed:
        return
    redone = {*lost, *failed}
    lines = results.read_text(encoding="utf-8").splitlines(keepends=True)
    taken = [bool(line.strip()) and json.loads(line)["episode_id"] in redone for line in lines]
    _append_synced(results.with_name(REDONE_FILE), [line for line, out in zip(lines, taken, strict=True) if out])
    fresh = results.with_suffix(results.suffix + ".tmp")
    fresh.unlink(missing_ok=True)  # a leftover, a link even: never written through
    with fresh.open("w", encoding="utf-8") as handle:
        handle.writelines(line for line, out in zip(lines, taken, strict=True) if not out)
        handle.flush()
        os.fsync(handle.fileno())
    os.replace(fresh, results)
    if lost:
        log.warning("%d episodes a server lost (%s) are run again", len(lost), " or ".join(LOST_TO_A_SERVER))
    if failed:
        log.warning(
            "%d episodes that ended in an error as they started, before any episode finished without one, are run "
            "again (their records moved to %s)",
            len(failed),
            REDONE_FILE,
        )


def _append_synced(path: Path, lines: Sequence[str]) -> None:
    """Append ``lines`` to ``path``, flushed and fsync'ed (a link there is removed first: nothing is written
    through it)."""
    if path.is_symlink():
        path.unlink()
    with path.open("a", encoding="utf-8") as handle:
        handle.writelines(lines)
        handle.flush()
        os.fsync(handle.fileno())


def _repair_episodes_copy(path: Path, episodes: Sequence[Episode], sha256: str) -> None:
    """Rewrite the run's copy of its episodes when it is gone or is not these episodes (pictures and reruns read
    it); the resume itself was checked against ``run.json``."""
    try:
        intact = episodes_sha256(load_episodes(path, require_goals=False)) == sha256
    except InputError:
        intact = False
    if not intact:
        log.warning("%s was missing or damaged: written again from the run's episodes", path)
        save_episodes(episodes, path)


def _read_json(path: Path) -> JsonObject:
    try:
        data = json.loads(path.read_text(encoding="utf-8"))
    except (OSError, ValueError) as error:
        raise InputError(path, "<file>", "the JSON object drivenav wrote", str(error)) from None
    if not isinstance(data, dict):
        raise InputError(path, "<file>", "a JSON object", type(data).__name__)
    return data


@contextmanager
def _locked(path: Path) -> Iterator[IO[str]]:
    """Hold an exclusive ``flock`` on ``path``; refuse at once when a live process holds it."""
    handle = path.open("a+", encoding="utf-8")
    try:
        try:
            fcntl.flock(handle, fcntl.LOCK_EX | fcntl.LOCK_NB)
        except BlockingIOError:
            handle.seek(0)
            holder = handle.read().strip() or "another process"
            raise InputError(
                path.parent, "--out", "a run directory no other drivenav run is writing", f"locked by pid {holder}"
            ) from None
        handle.seek(0)
        handle.truncate()
        handle.write(str(os.getpid()))
        handle.flush()
        yield handle
    finally:
        handle.close()
