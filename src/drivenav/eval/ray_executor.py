"""Episodes as Ray tasks (``--executor ray``, extra ``drivenav[ray]``): a laptop's pool, scaled to a cluster.

Each episode is one Ray task; a Ray worker process builds its scene library, environment and agent once and
reuses them, exactly as a local pool process does, so the records are the same. Results stream back to the
driver in completion order and the driver alone writes the run directory (kill-safe appends, resume), as with
``--workers``.

``address`` None starts a private local Ray instance for this run (``workers`` CPUs) and stops it afterwards;
otherwise it is passed to ``ray.init`` (``auto``, ``HOST:6379`` or ``ray://HOST:10001``). Every node of a
cluster needs drivenav installed and the scenes at the same paths (the packaged floor plans, ``maps``, travel
with drivenav).

A cluster started by ``ray start --head`` of Ray 2.60 or later authenticates with a token. Ray itself turns token
authentication on in a driver only for ``auto`` on the head node, so a driver given ``HOST:PORT`` needs
``RAY_AUTH_MODE=token`` and the cluster's token (``RAY_AUTH_TOKEN``, ``RAY_AUTH_TOKEN_PATH`` or
``~/.ray/auth_token``) in its environment; a cluster that refuses the driver for its token, or for any other reason
Ray gives, is one line naming Ray's words and what to set (:func:`check_workers_start`).
"""

from __future__ import annotations

import itertools
import json
import os
import queue
import re
import signal
import subprocess
import sys
import threading
import time
from collections.abc import Callable, Iterator, Sequence
from contextlib import contextmanager
from typing import IO, Any, Final, TypeVar

from drivenav.errors import InputError, RunStoppedError, WorkerDiedError
from drivenav.threads import single_thread_env

Item = TypeVar("Item")
Result = TypeVar("Result")


def import_ray() -> Any:
    """The ``ray`` module, or a clear error naming the extra to install."""
    try:
        import ray
    except ImportError:
        raise InputError(
            "command line", "--executor", "Ray installed (pip install 'drivenav[ray]')", "ray (not installed)"
        ) from None
    return ray


WORKER_START_S = 20.0  # a Ray worker that has not run a first task by then is reported (it dies as it starts)
TOKEN_HELP: Final[str] = (
    "set RAY_AUTH_MODE=token and the cluster's token in drivenav's environment (RAY_AUTH_TOKEN, RAY_AUTH_TOKEN_PATH "
    "or ~/.ray/auth_token; 'ray get-auth-token' on the head node prints it)"
)
"""What a driver refused by a token-authenticated cluster must set (docs: Ray's token authentication)."""
_AUTH_REFUSED = re.compile(r"InvalidAuthToken|Unauthenticated|AuthenticationError", re.IGNORECASE)
_INPUT_ERROR = "drivenav input error: "  # the probe's InputError, a JSON list of its fields, on its last line
_RAY_LOG_PREFIX = re.compile(r"^\[[^\]]*\]\s*(\S+\.(cc|py):\d+:\s*)?")


def run_on_ray(
    items: Sequence[Item],
    function: Callable[[Item], Result],
    workers: int | None,
    address: str | None,
    key: Callable[[Item], str] = str,
) -> Iterator[Result]:
    """``function(item)`` for every item as Ray tasks (one CPU each); yields results as they finish.

    At most ``workers`` tasks (default: every CPU of the cluster) are in flight; a new one is submitted as each
    finishes. ``function`` should keep its expensive state per worker process (Ray reuses the processes). A worker
    that cannot start stops the run with a :class:`RunStoppedError` within :data:`WORKER_START_S`; one that dies
    running an item, with a :class:`WorkerDiedError` naming it (``key``).
    """
    if not items:
        return
    with ray_session(workers, address) as ray:
        limit = workers or max(1, int(ray.cluster_resources().get("CPU", 1)))
        task = ray.remote(num_cpus=1, max_retries=0)(function)
        queue = iter(items)
        running = {task.remote(item): item for item in itertools.islice(queue, limit)}
        while running:
            (ready,), _ = ray.wait(list(running), num_returns=1)
            item = running.pop(ready)
            try:
                result: Result = ray.get(ready)
            except ray.exceptions.WorkerCrashedError:
                raise WorkerDiedError([key(item)], []) from None
            running.update((task.remote(item), item) for item in itertools.islice(queue, 1))
            yield result


def _worker_pid() -> int:
    return os.getpid()


def check_workers_start(address: str | None) -> None:
    """Start Ray and run one task in a separate process first, and give up after :data:`WORKER_START_S`: when
    Ray's workers die as they start (a broken environment on a node), Ray retries them without a word, and
    ``ray.init`` itself can wait forever holding the interpreter, so no thread of this process could say so. What
    Ray says meanwhile is read as it comes: a cluster refusing the driver's authentication is said at once."""
    command = [sys.executable, "-m", "drivenav.eval.ray_executor", address or ""]
    probe = subprocess.Popen(command, stdout=subprocess.DEVNULL, stderr=subprocess.PIPE, start_new_session=True)
    said: list[str] = []
    try:
        _read_probe(probe, address, said)
    finally:
        if probe.poll() is None:
            os.killpg(probe.pid, signal.SIGKILL)
        probe.wait()
        assert probe.stderr is not None
        probe.stderr.close()
    last = said[-1] if said else ""
    if probe.returncode == 2:
        refusal = last.removeprefix(_INPUT_ERROR) if last.startswith(_INPUT_ERROR) else ""
        if refusal:
            source, field, expected, got = json.loads(refusal)
            raise InputError(source, field, expected, got)
        raise InputError("command line", "--ray-address", "a reachable Ray cluster", last or address)
    if probe.returncode != 0:
        raise RunStoppedError(f"a Ray worker could not run a task: {last or probe.returncode}")


def _read_probe(probe: subprocess.Popen[bytes], address: str | None, said: list[str]) -> None:
    """Collect the probe's error lines in ``said`` until it exits; a refused authentication is an
    :class:`InputError` at once, no task run within :data:`WORKER_START_S` a :class:`RunStoppedError` quoting Ray."""
    assert probe.stderr is not None
    lines: queue.Queue[str | None] = queue.Queue()
    threading.Thread(target=_forward_lines, args=(probe.stderr, lines), daemon=True).start()
    deadline = time.monotonic() + WORKER_START_S
    while True:
        try:
            line = lines.get(timeout=max(0.0, deadline - time.monotonic()))
        except queue.Empty:
            quoted = f" (Ray's last words: {_ray_words(said[-1])})" if said else ""
            raise RunStoppedError(
                f"no Ray worker ran a task within {WORKER_START_S:.0f} s: Ray's workers die as they start (see the "
                "raylet logs, /tmp/ray/session_latest/logs on each node), or the cluster has no free CPU" + quoted
            ) from None
        if line is None:
            return
        if line.strip():
            said.append(line.strip())
        if _AUTH_REFUSED.search(line) and not line.startswith(_INPUT_ERROR):
            raise _auth_refused(address, _ray_words(line))


def _forward_lines(stream: IO[bytes], lines: queue.Queue[str | None]) -> None:
    for raw in stream:
        lines.put(raw.decode(errors="replace"))
    lines.put(None)


def _ray_words(line: str) -> str:
    """A line of Ray's log without its time, process and source prefix (an RPC error: its last part, the cause)."""
    words = _RAY_LOG_PREFIX.sub("", line.strip())
    return words.rsplit("RPC error: ", 1)[-1]


def _auth_refused(address: str | None, words: str) -> InputError:
    """The one line for a cluster that refused the driver's authentication: Ray's words and what to set."""
    where = f"the Ray cluster at {address}" if address else "the local Ray instance"
    expected = f"a Ray cluster that admits this driver: {where} refused its authentication ({TOKEN_HELP})"
    return InputError("command line", "--ray-address", expected, words)


def _probe(address: str | None) -> int:
    """``python -m drivenav.eval.ray_executor [ADDRESS]``: one task on Ray (exit 2: no cluster there)."""
    ray = import_ray()
    try:
        _init(ray, 1, address)
    except InputError as error:
        fields = [error.source, error.field, error.expected, None if error.got is None else str(error.got)]
        print(_INPUT_ERROR + json.dumps(fields), file=sys.stderr)
        return 2
    try:
        ray.get(ray.remote(num_cpus=1, max_retries=0)(_worker_pid).remote())
    finally:
        ray.shutdown()
    return 0


@contextmanager
def ray_session(workers: int | None, address: str | None) -> Iterator[Any]:
    """The ``ray`` module, connected: Ray is started (or joined at ``address``) unless it already is, and then
    stopped on leaving; an enclosing session makes the runs inside it share one connection."""
    ray = import_ray()
    started_here = not ray.is_initialized()
    if started_here:
        check_workers_start(address)
        _init(ray, workers, address)
    try:
        yield ray
    finally:
        if started_here:
            ray.shutdown()


def _init(ray: Any, workers: int | None, address: str | None) -> None:
    options: dict[str, object] = {
        "include_dashboard": False,
        "log_to_driver": False,
        "runtime_env": {"env_vars": single_thread_env()},
    }
    if address is None:
        options["num_cpus"] = workers or None
    try:
        ray.init(address=address, **options)
    except getattr(ray.exceptions, "AuthenticationError", ()) as exc:  # Ray 2.60 and later: token mode, no token
        where = f"the Ray cluster at {address}" if address else "the local Ray instance"
        expected = (
            f"a token for {where}: RAY_AUTH_MODE=token is set but Ray found none (set RAY_AUTH_TOKEN, "
            "RAY_AUTH_TOKEN_PATH or ~/.ray/auth_token; 'ray get-auth-token' on the head node prints it)"
        )
        raise InputError("command line", "--ray-address", expected, str(exc)) from None
    except (ConnectionError, RuntimeError, ValueError) as exc:
        raise InputError("command line", "--ray-address", "a reachable Ray cluster", f"{address} ({exc})") from None


if __name__ == "__main__":
    sys.exit(_probe(sys.argv[1] if len(sys.argv) > 1 and sys.argv[1] else None))
