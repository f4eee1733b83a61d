"""Episodes as Ray tasks (``--executor ray``, extra ``drivenav[ray]``): a laptop's pool, scaled to a cluster.

Each episode is one Ray task; a Ray worker process builds its scene library, environment and agent once and
reuses them, exactly as a local pool process does, so the records are the same. Results stream back to the
driver in completion order and the driver alone writes the run directory (kill-safe appends, resume), as with
``--workers``.

``address`` None starts a private local Ray instance for this run (``workers`` CPUs) and stops it afterwards;
otherwise it is passed to ``ray.init`` (``auto``, ``HOST:6379`` or ``ray://HOST:10001``). Every node of a
cluster needs drivenav installed and the scenes at the same paths (the packaged floor plans, ``maps``, travel
with drivenav).
"""

from __future__ import annotations

import itertools
import os
import signal
import subprocess
import sys
from collections.abc import Callable, Iterator, Sequence
from contextlib import contextmanager
from typing import Any, TypeVar

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
    ``ray.init`` itself can wait forever holding the interpreter, so no thread of this process could say so."""
    command = [sys.executable, "-m", "drivenav.eval.ray_executor", address or ""]
    probe = subprocess.Popen(command, stdout=subprocess.DEVNULL, stderr=subprocess.PIPE, start_new_session=True)
    try:
        _, err = probe.communicate(timeout=WORKER_START_S)
    except subprocess.TimeoutExpired:
        os.killpg(probe.pid, signal.SIGKILL)
        probe.wait()
        raise RunStoppedError(
            f"no Ray worker ran a task within {WORKER_START_S:.0f} s: Ray's workers die as they start (see the "
            "raylet logs, /tmp/ray/session_latest/logs on each node), or the cluster has no free CPU"
        ) from None
    lines = err.decode(errors="replace").strip().splitlines()
    if probe.returncode == 2:
        raise InputError("command line", "--ray-address", "a reachable Ray cluster", lines[-1] if lines else address)
    if probe.returncode != 0:
        raise RunStoppedError(f"a Ray worker could not run a task: {lines[-1] if lines else probe.returncode}")


def _probe(address: str | None) -> int:
    """``python -m drivenav.eval.ray_executor [ADDRESS]``: one task on Ray (exit 2: no cluster there)."""
    ray = import_ray()
    try:
        _init(ray, 1, address)
    except InputError as error:
        print(error, file=sys.stderr)
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
    except (ConnectionError, RuntimeError, ValueError) as exc:
        raise InputError("command line", "--ray-address", "a reachable Ray cluster", f"{address} ({exc})") from None


if __name__ == "__main__":
    sys.exit(_probe(sys.argv[1] if len(sys.argv) > 1 and sys.argv[1] else None))
