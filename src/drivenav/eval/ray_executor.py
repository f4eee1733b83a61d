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
from collections.abc import Callable, Iterator, Sequence
from contextlib import contextmanager
from typing import Any, TypeVar

from drivenav.errors import InputError
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


def run_on_ray(
    items: Sequence[Item],
    function: Callable[[Item], Result],
    workers: int | None,
    address: str | None,
) -> Iterator[Result]:
    """``function(item)`` for every item as Ray tasks (one CPU each); yields results as they finish.

    At most ``workers`` tasks (default: every CPU of the cluster) are in flight; a new one is submitted as each
    finishes. ``function`` should keep its expensive state per worker process (Ray reuses the processes).
    """
    if not items:
        return
    with ray_session(workers, address) as ray:
        limit = workers or max(1, int(ray.cluster_resources().get("CPU", 1)))
        task = ray.remote(num_cpus=1, max_retries=0)(function)
        queue = iter(items)
        pending = [task.remote(item) for item in itertools.islice(queue, limit)]
        while pending:
            (ready,), pending = ray.wait(pending, num_returns=1)
            result: Result = ray.get(ready)
            pending.extend(task.remote(item) for item in itertools.islice(queue, 1))
            yield result


@contextmanager
def ray_session(workers: int | None, address: str | None) -> Iterator[Any]:
    """The ``ray`` module, connected: Ray is started (or joined at ``address``) unless it already is, and then
    stopped on leaving; an enclosing session makes the runs inside it share one connection."""
    ray = import_ray()
    started_here = not ray.is_initialized()
    if started_here:
        _init(ray, workers, address)
    try:
        yield ray
    finally:
        if started_here:
            ray.shutdown()


def _init(ray: Any, workers: int | None, address: str | None) -> None:
    options: dict[str, Any] = {
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
