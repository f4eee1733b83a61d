"""``eval --share-detector``: one grounder server for all of a run's workers, started and stopped by the run.

The run's detector is served by ``drivenav serve grounder`` in a subprocess on a free loopback port (it prints
its endpoint first; its log goes to ``DIR/grounder-server.log``), and the workers ground through
``--detector remote`` at that endpoint (:mod:`drivenav.semantics.served`): one model copy whatever the number of
workers, their frames batched. The run directory records the detector itself (``models.detector``: the
detections are the same), so a rerun resumes with or without sharing. The server is stopped when the run ends,
fails or is interrupted; an episode it lost (it died, or stalled past ``models.detector_timeout_s``) is recorded as
an error and run again by a resume (:func:`drivenav.eval.rundir.lost_to_a_server`). A server gone at an episode's
start stops the run with a line that says to rerun the same command (it serves a new one), not to restart a server
the user never started.

The run chooses the endpoint and speaks to the server on loopback, so ``--detector-url`` and ``--detector-keys``
are refused with ``--share-detector``, never ignored: a server of the user's is reached with ``--detector remote``.
"""

from __future__ import annotations

import contextlib
import queue
import re
import subprocess
import sys
import threading
from collections.abc import Iterator
from dataclasses import replace
from pathlib import Path
from typing import IO, Final

from drivenav.errors import InputError, RunStoppedError
from drivenav.eval.executor import Executor
from drivenav.semantics.model_spec import ModelSpec
from drivenav.semantics.remote import GrounderGoneError, reach_server
from drivenav.semantics.serve_config import DEFAULT_BIND, takes_model_options

LOG_FILE: Final[str] = "grounder-server.log"
START_S: Final[float] = 600.0
"""The longest the server may take to load its model and bind (full-size SAM3 from a slow disk)."""
STOP_S: Final[float] = 10.0
"""How long the server is given to exit after SIGTERM before it is killed."""
_ENDPOINT = re.compile(r" on (tcp://\S+)")


def check_shareable(models: ModelSpec, executor: Executor) -> None:
    """A detector run in process, by local workers (the server listens on loopback only), and no endpoint or keys
    of the user's (the run serves on a free loopback port of its own)."""
    if models.detector == "remote":
        raise InputError("command line", "--share-detector", "a detector run in process (not remote)", "remote")
    given = [f"--detector-url {models.detector_url}"] if models.detector_url != DEFAULT_BIND else []
    given += [f"--detector-keys {models.detector_keys}"] if models.detector_keys else []
    if given:
        expected = (
            "no --detector-url or --detector-keys with it (the run serves its detector on a free loopback port of its "
            "own; to use a server of yours: --detector remote --detector-url URL)"
        )
        raise InputError("command line", "--share-detector", expected, ", ".join(given))
    if executor.kind == "ray":
        raise InputError("command line", "--share-detector", "the local executor (the server is on loopback)", "ray")


def server_command(models: ModelSpec) -> list[str]:
    """``drivenav serve grounder`` for ``models``' detector on a free loopback port (its model options only for a
    detector that takes them: :func:`~drivenav.semantics.serve_config.takes_model_options`)."""
    model = [
        f"--detector-model={models.detector_model}",
        f"--dtype={models.dtype}",
        f"--device={models.detector_device}",
        f"--segmenter={models.segmenter}",
        f"--segmenter-model={models.segmenter_model}",
        *(["--compile"] if models.compile else []),
    ]
    serve = [sys.executable, "-m", "drivenav.cli", "serve", "grounder", f"--detector={models.detector}"]
    return [*serve, *(model if takes_model_options(models.detector) else []), "--bind=tcp://127.0.0.1:*"]


@contextlib.contextmanager
def shared_detector(models: ModelSpec, out: Path, start_s: float = START_S) -> Iterator[ModelSpec]:
    """The server of ``models``' detector, running for the duration; yields the workers' models (``remote`` at
    its endpoint). A server that does not start stops the run with its last log line."""
    log_path = out / LOG_FILE
    with log_path.open("ab") as log:
        process = subprocess.Popen(server_command(models), stdout=subprocess.PIPE, stderr=log, text=True)
        try:
            endpoint = _endpoint(process, log_path, start_s)
            served = replace(
                models, detector="remote", detector_url=endpoint, detector_keys="", detector_served=models.detector
            )
            reach_server(served)
            yield served
        except GrounderGoneError as error:
            raise RunStoppedError(
                f"{error.cause} (at an episode's start): the run's own grounder server stopped (its log: {log_path}); "
                "finished episodes are saved: rerun the same command to resume, it serves a new one"
            ) from None
        finally:
            _stop(process)


def _endpoint(process: subprocess.Popen[str], log_path: Path, start_s: float) -> str:
    """The endpoint the server prints first; a server that exits or stays silent stops the run."""
    assert process.stdout is not None
    lines: queue.Queue[str] = queue.Queue()
    threading.Thread(target=_first_line, args=(process.stdout, lines), daemon=True).start()
    try:
        line = lines.get(timeout=start_s)
    except queue.Empty:
        line = ""
    found = _ENDPOINT.search(line)
    if found is None:
        said = _last_line(log_path) or f"no endpoint within {start_s:g} s"
        raise RunStoppedError(f"the shared grounder server did not start: {said} (log: {log_path})")
    return found.group(1)


def _first_line(stream: IO[str], lines: queue.Queue[str]) -> None:
    lines.put(stream.readline())


def _last_line(log_path: Path) -> str:
    text = log_path.read_text(encoding="utf-8", errors="replace").strip().splitlines()
    return text[-1] if text else ""


def _stop(process: subprocess.Popen[str]) -> None:
    """SIGTERM, then SIGKILL after :data:`STOP_S`."""
    if process.poll() is None:
        process.terminate()
        try:
            process.wait(STOP_S)
        except subprocess.TimeoutExpired:
            process.kill()
            process.wait()
    if process.stdout is not None:
        process.stdout.close()
