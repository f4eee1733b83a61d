"""``drivenav bench agent``: the agent's own compute per step, in the format of the paper's Table VII.

A quick stand-alone measurement on a few procedural houses, or on the first episodes of a benchmark version
(``--benchmark v2``); ``bench ablations`` builds the same table from every step of its runs (see
:mod:`drivenav.eval.timings`).
"""

from __future__ import annotations

from drivenav.agent.trace import DirectionSelected
from drivenav.agents import make_agent
from drivenav.benchmarks.benchmark import BENCHMARKS, generate_benchmark
from drivenav.benchmarks.generate import generate_episodes
from drivenav.envs.embedded.env import EmbeddedEnv
from drivenav.envs.embedded.library import SceneLibrary
from drivenav.eval.runner import run_episode
from drivenav.eval.timings import runtime_table
from drivenav.jsonstream import JsonObject
from drivenav.settings import load_settings


def bench_agent(
    episodes: int = 4, max_steps: int = 150, seed: int = 0, agent_name: str = "drive-nav", benchmark: str | None = None
) -> JsonObject:
    """Run a few embedded episodes (procedural houses, or the first of ``benchmark``'s) and report per-step compute
    and the per-module breakdown."""
    settings = load_settings(agent_name)
    sim = settings.sim
    if benchmark is None:
        library = SceneLibrary(f"procedural:{episodes}", seed)
        chosen, warm = generate_episodes(library, episodes, seed), generate_episodes(library, 1, seed + 1)[0]
    else:
        definition = BENCHMARKS[benchmark]
        library = SceneLibrary(definition.scenes, definition.seed)
        chosen = generate_benchmark(definition, episodes)
        warm = chosen[0]
    env = EmbeddedEnv(library.load, sim)
    agent = make_agent(settings)
    run_episode(env, agent, warm, seed, 20)  # compile numba kernels outside the measurement
    steps: list[dict[str, float]] = []
    reasoner_calls = 0
    for episode in chosen:
        run_episode(env, agent, episode, seed, max_steps)
        steps.extend(agent.step_timings)
        reasoner_calls += len(agent.trace.of_type(DirectionSelected))
    table = runtime_table(steps, reasoner_calls, len(chosen), agent_name, sim.width, sim.height)
    return {**table, "benchmark": benchmark} if benchmark is not None else table
