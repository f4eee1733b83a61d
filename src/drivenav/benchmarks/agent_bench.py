"""``drivenav bench agent``: the agent's own compute per step, in the format of the paper's Table VII.

A quick stand-alone measurement; ``bench ablations`` builds the same table from every step of its runs (see
:mod:`drivenav.eval.timings`).
"""

from __future__ import annotations

from drivenav.agent.trace import DirectionSelected
from drivenav.agents import make_agent
from drivenav.benchmarks.generate import generate_episodes
from drivenav.envs.embedded.env import EmbeddedEnv
from drivenav.envs.embedded.library import SceneLibrary
from drivenav.eval.runner import run_episode
from drivenav.eval.timings import runtime_table
from drivenav.jsonstream import JsonObject
from drivenav.settings import load_settings


def bench_agent(episodes: int = 4, max_steps: int = 150, seed: int = 0, agent_name: str = "drive-nav") -> JsonObject:
    """Run a few embedded episodes and report per-step compute and the per-module breakdown."""
    settings = load_settings(agent_name)
    sim = settings.sim
    library = SceneLibrary(f"procedural:{episodes}", seed)
    env = EmbeddedEnv(library.load, sim)
    agent = make_agent(settings)
    warm = generate_episodes(library, 1, seed + 1)
    run_episode(env, agent, warm[0], seed, 20)  # compile numba kernels outside the measurement
    steps: list[dict[str, float]] = []
    reasoner_calls = 0
    for episode in generate_episodes(library, episodes, seed):
        run_episode(env, agent, episode, seed, max_steps)
        steps.extend(agent.step_timings)
        reasoner_calls += len(agent.trace.of_type(DirectionSelected))
    return runtime_table(steps, reasoner_calls, episodes, agent_name, sim.width, sim.height)
