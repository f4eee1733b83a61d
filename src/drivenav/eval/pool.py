"""Episodes in a pool of worker processes, with the failure modes of long runs handled.

- A worker that dies (killed, out of memory) stops the run with :class:`~drivenav.errors.WorkerDiedError` naming the
  episode it was running; nothing it did not finish is reported, so a rerun resumes from there.
- Workers watch their parent: when the driver is killed (even with ``kill -9``) they exit by themselves.
- Interrupting the driver (Ctrl-C, or SIGTERM, which the command line turns into the same) cancels what has not
  started and stops the workers at once.
- Workers ignore SIGINT (the driver decides) and send their log records to the driver, which prints them above
  its progress bar.
"""

from __future__ import annotations

import logging
import logging.handlers
import os
import signal
import threading
import time
from collections.abc import Callable, Iterator, Sequence
from concurrent.futures import Future, ProcessPoolExecutor, as_completed
from concurrent.futures.process import BrokenProcessPool
from multiprocessing import get_context
from multiprocessing.process import BaseProcess
from multiprocessing.queues import Queue
from typing import Any, TypeVar

from drivenav.errors import WorkerDiedError

Item = TypeVar("Item")
Result = TypeVar("Result")

PARENT_POLL_S = 0.5  # how often a worker checks that its driver is alive
_STARTED = "started"
_FINISHED = "finished"


def _watch_parent(parent: int) -> None:
    while os.getppid() == parent:
        time.sleep(PARENT_POLL_S)
    os._exit(1)  # the driver is gone: nobody will read our results


def _init_worker(messages: Queue[Any], parent: int, log_level: int) -> None:
    signal.signal(signal.SIGINT, signal.SIG_IGN)
    threading.Thread(target=_watch_parent, args=(parent,), daemon=True).start()
    root = logging.getLogger()
    root.handlers[:] = [logging.handlers.QueueHandler(messages)]
    root.setLevel(log_level)
    global _MESSAGES
    _MESSAGES = messages


_MESSAGES: Queue[Any] | None = None


def _announce_and_run(function: Callable[[Item], Result], item: Item, key: str) -> Result:
    if _MESSAGES is not None:
        _MESSAGES.put((_STARTED, os.getpid(), key))
    result = function(item)
    if _MESSAGES is not None:
        _MESSAGES.put((_FINISHED, os.getpid(), key))
    return result


class _Listener:
    """The driver's side of the message queue: worker log records, and which worker runs which episode."""

    def __init__(self, messages: Queue[Any]) -> None:
        self.messages = messages
        self.running: dict[int, str] = {}
        self._thread = threading.Thread(target=self._listen, daemon=True)
        self._thread.start()

    def _listen(self) -> None:
        while True:
            message = self.messages.get()
            if message is None:
                return
            if isinstance(message, tuple) and message[0] == _STARTED:
                self.running[message[1]] = message[2]
            elif isinstance(message, tuple) and message[0] == _FINISHED:
                self.running.pop(message[1], None)
            elif isinstance(message, logging.LogRecord):
                logging.getLogger(message.name).handle(message)

    def stop(self) -> None:
        self.messages.put(None)
        self._thread.join(timeout=5)


def run_in_pool(
    items: Sequence[Item], function: Callable[[Item], Result], workers: int, key: Callable[[Item], str]
) -> Iterator[Result]:
    """``function(item)`` for every item in ``workers`` spawned processes; yields results as they finish."""
    context = get_context("spawn")
    messages: Queue[Any] = context.Queue()
    listener = _Listener(messages)
    pool = ProcessPoolExecutor(
        workers,
        mp_context=context,
        initializer=_init_worker,
        initargs=(messages, os.getpid(), logging.getLogger().level),
    )
    processes: dict[int, BaseProcess] = {}
    finished = False
    try:
        futures: dict[Future[Result], str] = {
            pool.submit(_announce_and_run, function, item, key(item)): key(item) for item in items
        }
        processes.update(getattr(pool, "_processes", None) or {})
        for future in as_completed(futures):
            try:
                result = future.result()
            except BrokenProcessPool:
                raise _worker_died(processes, listener, futures) from None
            yield result
        finished = True
    finally:
        pool.shutdown(wait=finished, cancel_futures=True)
        if not finished:
            for process in processes.values():
                process.terminate()
        listener.stop()


def _worker_died(
    processes: dict[int, BaseProcess], listener: _Listener, futures: dict[Future[Any], str]
) -> WorkerDiedError:
    """Name the episode whose worker died (all unfinished ones where it cannot be told which)."""
    time.sleep(PARENT_POLL_S)  # let the listener take the last start messages
    for process in processes.values():
        process.join(timeout=1)
    killed = [pid for pid, p in processes.items() if p.exitcode not in (None, 0, -signal.SIGTERM)]
    named = [listener.running[pid] for pid in killed if pid in listener.running]
    if not named:
        named = [key for future, key in futures.items() if not future.done() or future.exception() is not None]
    codes = sorted({str(processes[pid].exitcode) for pid in killed})
    return WorkerDiedError(named, codes)
