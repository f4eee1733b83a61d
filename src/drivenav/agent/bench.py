"""``drivenav bench agent``: the agent's own compute per step, in the format of the paper's Table VII.

Compute per step = mapping + directions + inspection + policy (planning and decisions); model calls (grounding,
reasoning) are reported separately and excluded, as the issue asks.
"""

from __future__ import annotations

import statistics
from typing import Any

import numba

from drivenav.agent.drivenav import DriveNavAgent
from drivenav.agent.registry import make_agent
from drivenav.envs.base import SimConfig
from drivenav.envs.embedded import EmbeddedEnv
from drivenav.envs.library import SceneLibrary
from drivenav.eval.episodes import generate_episodes
from drivenav.eval.runner import run_episode

COMPUTE_KEYS = ("mapping", "directions.total", "inspection", "policy")
MODULES = {
    "mapping (depth -> maps, frontiers)": "mapping",
    "directions: distance transforms": "directions.distance_transforms",
    "directions: skeleton": "directions.skeleton",
    "directions: weighted FMM": "directions.fmm",
    "directions: backtracking + bearings": "directions.backtracking",
    "directions: clustering": "directions.clustering",
    "directions: tracking": "directions.tracking",
    "inspection (representative views)": "inspection",
    "policy (planner, inspection events, decisions)": "policy",
    "grounding (detector, model)": "grounding",
}


def _summary(values: list[float]) -> dict[str, float]:
    ordered = sorted(values)
    return {
        "median_ms": round(statistics.median(ordered), 3),
        "p90_ms": round(ordered[int(0.9 * (len(ordered) - 1))], 3),
        "mean_ms": round(statistics.fmean(ordered), 3),
    }


def bench_agent(
    episodes: int = 4, max_steps: int = 150, seed: int = 0, agent_name: str = "drive-nav"
) -> dict[str, Any]:
    """Run a few embedded episodes and report per-step compute and the per-module breakdown."""
    numba.set_num_threads(1)
    sim = SimConfig()
    library = SceneLibrary(f"procedural:{episodes}", seed)
    env = EmbeddedEnv(library.load, sim)
    agent = make_agent(agent_name, sim)
    assert isinstance(agent, DriveNavAgent)
    warm = generate_episodes(library, 1, seed + 1)
    run_episode(env, agent, warm[0], seed, 20)  # compile numba kernels outside the measurement
    steps: list[dict[str, float]] = []
    reasoner_calls = 0
    for episode in generate_episodes(library, episodes, seed):
        run_episode(env, agent, episode, seed, max_steps)
        steps.extend(agent.timings)
        reasoner_calls += len(agent.trace.of_kind("direction_selected"))
    compute = [sum(step.get(key, 0.0) for key in COMPUTE_KEYS) for step in steps]
    modules = {
        name: {**_summary([s.get(key, 0.0) for s in steps]), "invocation": "every step"}
        for name, key in MODULES.items()
    }
    modules["direction selection (reasoner)"] = {"invocations": reasoner_calls, "invocation": "decision points"}
    return {
        "agent": agent_name,
        "width": sim.width,
        "height": sim.height,
        "episodes": episodes,
        "steps": len(steps),
        **_summary(compute),
        "modules": modules,
    }
