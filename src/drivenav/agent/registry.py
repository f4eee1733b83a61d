"""Agents by ``--agent`` name."""

from __future__ import annotations

from collections.abc import Callable

from drivenav.agent.base import Agent
from drivenav.agent.oracle import OracleAgent
from drivenav.agent.random_agent import RandomAgent
from drivenav.envs.base import SimConfig
from drivenav.errors import InputError

AGENTS: dict[str, Callable[[SimConfig], Agent]] = {
    OracleAgent.name: OracleAgent,
    RandomAgent.name: RandomAgent,
}


def agent_names() -> list[str]:
    return sorted(AGENTS)


def make_agent(name: str, sim: SimConfig) -> Agent:
    """A fresh agent; an unknown name is an :class:`InputError` on ``--agent``."""
    factory = AGENTS.get(name)
    if factory is None:
        raise InputError("command line", "--agent", f"one of {', '.join(agent_names())}", name)
    return factory(sim)
