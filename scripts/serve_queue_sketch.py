"""A sketch of the served grounder's batching (issue 61; docs/benchmarks.md, "A batch stays open until the model
takes it"). Not a measurement: a discrete-event model of W workers and one model copy.

Each worker maps for a time drawn uniformly from ``map_ms``, sends one frame and waits for its reply; a forward of b
frames takes ``fixed_ms + per_frame_ms * b`` (32 + 26 b: SAM3 bf16 on the H100, 58 ms at batch 1 and 30 ms a frame
at batch 8). A batch is due when it holds ``cap`` frames, when its oldest has waited ``batch_ms``, or when every
worker waits. Policies:

- ``closed``: the next batch is handed over while the model runs, closed when handed over (before 13b1d5e);
- ``open``: as ``closed``, but frames that come before the model takes it join it (13b1d5e).

    python3 scripts/serve_queue_sketch.py
"""

from __future__ import annotations

import heapq
import random
from dataclasses import dataclass, field

ARRIVE, DONE, TIMER = 0, 1, 2


@dataclass
class Queue:
    """The server's state: frames queued (arrival ms, worker), the batch handed over, the batch running."""

    policy: str
    workers: int
    cap: int
    batch_ms: float
    pending: list[tuple[float, int]] = field(default_factory=list)
    staged: list[tuple[float, int]] | None = None
    running: list[tuple[float, int]] | None = None
    sizes: list[int] = field(default_factory=list)

    def due(self, now: float) -> bool:
        if not self.pending:
            return False
        waiting = len(self.pending) + len(self.staged or []) + len(self.running or [])
        return len(self.pending) >= self.cap or now - self.pending[0][0] >= self.batch_ms or waiting >= self.workers

    def take(self, count: int) -> list[tuple[float, int]]:
        taken, self.pending = self.pending[:count], self.pending[count:]
        return taken


def run(
    policy: str,
    workers: int,
    map_ms: tuple[float, float] = (40.0, 120.0),
    fixed_ms: float = 32.0,
    per_frame_ms: float = 26.0,
    cap: int = 16,
    batch_ms: float = 5.0,
    horizon_ms: float = 60_000.0,
    seed: int = 0,
) -> tuple[float, float]:
    """Frames a second and the mean batch over ``horizon_ms``."""
    rng = random.Random(seed)
    events: list[tuple[float, int, int]] = [(rng.uniform(*map_ms), ARRIVE, w) for w in range(workers)]
    heapq.heapify(events)
    queue, done, busy_until = Queue(policy, workers, cap, batch_ms), 0, -1.0
    while events:
        now, kind, worker = heapq.heappop(events)
        if now > horizon_ms:
            break
        if kind == ARRIVE:
            queue.pending.append((now, worker))
        elif kind == DONE and queue.running is not None and now == busy_until:
            for _, finished in queue.running:
                heapq.heappush(events, (now + rng.uniform(*map_ms), ARRIVE, finished))
            done += len(queue.running)
            queue.running = None
        if queue.running is None and (queue.staged or queue.due(now)):
            queue.running = queue.staged or queue.take(cap)
            queue.staged = None
            busy_until = now + fixed_ms + per_frame_ms * len(queue.running)
            heapq.heappush(events, (busy_until, DONE, -1))
            queue.sizes.append(len(queue.running))
        if queue.running is not None and queue.staged is None and queue.due(now):
            queue.staged = queue.take(cap)
        if policy == "open" and queue.staged is not None:
            queue.staged += queue.take(cap - len(queue.staged))
        if queue.pending and queue.pending[0][0] + batch_ms > now:
            heapq.heappush(events, (queue.pending[0][0] + batch_ms, TIMER, -1))
    return done / (horizon_ms / 1000.0), sum(queue.sizes) / max(1, len(queue.sizes))


def main() -> None:
    print("workers | closed: frames/s (mean batch) | open: frames/s (mean batch)")
    for workers in (2, 8, 16, 32):
        closed, opened = run("closed", workers), run("open", workers)
        print(f"{workers:7d} | {closed[0]:6.1f} ({closed[1]:.2f}) | {opened[0]:6.1f} ({opened[1]:.2f})")
    print("open, frames/s by --batch-ms 0 / 2 / 5 / 10")
    for workers in (1, 2, 4, 8, 16, 32):
        rates = [run("open", workers, batch_ms=ms)[0] for ms in (0.0, 2.0, 5.0, 10.0)]
        print(f"{workers:7d} | " + " / ".join(f"{rate:.1f}" for rate in rates))


if __name__ == "__main__":
    main()
