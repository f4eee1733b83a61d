"""Where a run's episodes execute (``--executor``, ``--workers``, ``--ray-address``): a light module, so that the
command line builds its options without importing the agent."""

from __future__ import annotations

from contextlib import AbstractContextManager, nullcontext
from dataclasses import dataclass

from drivenav.errors import InputError


@dataclass(frozen=True)
class Executor:
    """Where episodes run; records do not depend on it.

    ``local``: in this process for one worker, else a pool of ``workers`` processes. ``ray``: up to ``workers``
    Ray tasks at a time (default: the cluster's CPUs) on a private local instance, or on the cluster at
    ``ray_address``.
    """

    kind: str = "local"
    workers: int | None = None
    ray_address: str | None = None

    def __post_init__(self) -> None:
        if self.kind not in EXECUTORS:
            raise InputError("command line", "--executor", " or ".join(EXECUTORS), self.kind)
        if self.workers is not None and self.workers < 1:
            raise InputError("command line", "--workers", "a positive integer", self.workers)
        if self.ray_address is not None and self.kind != "ray":
            raise InputError("command line", "--ray-address", "only with --executor ray", self.ray_address)

    def session(self) -> AbstractContextManager[object]:
        """Around several runs: one Ray connection for all of them (nothing to hold for local runs)."""
        if self.kind != "ray":
            return nullcontext()
        from drivenav.eval.ray_executor import ray_session

        return ray_session(self.workers, self.ray_address)


EXECUTORS = ("local", "ray")
