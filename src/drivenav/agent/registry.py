"""Agents by ``--agent`` name."""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import replace
from functools import partial

from drivenav.agent.base import Agent
from drivenav.agent.drivenav import AgentConfig, DriveNavAgent
from drivenav.agent.oracle import OracleAgent
from drivenav.agent.random_agent import RandomAgent
from drivenav.config import DriveNavConfig
from drivenav.envs.base import SimConfig
from drivenav.errors import InputError

_PAPER = DriveNavConfig()

DRIVE_NAV_VARIANTS: dict[str, AgentConfig] = {
    "drive-nav": AgentConfig(),
    "nearest-frontier": AgentConfig(use_reasoner=False),
    "frontier": AgentConfig(
        paper=replace(_PAPER, directions=replace(_PAPER.directions, cluster_span=0.0)), decision_scan=True
    ),
    "direction-360": AgentConfig(decision_scan=True),
    "no-weighted-fmm": AgentConfig(paper=replace(_PAPER, speed=replace(_PAPER.speed, weighted=False))),
    "no-240": AgentConfig(paper=replace(_PAPER, inspection=replace(_PAPER.inspection, restrict_forward=False))),
}
"""DRIVE-Nav and its baselines / ablations, composed from config switches (paper Tables II, V, VI)."""

AGENTS: dict[str, Callable[[SimConfig], Agent]] = {
    OracleAgent.name: OracleAgent,
    RandomAgent.name: RandomAgent,
    **{name: partial(DriveNavAgent, config=config, name=name) for name, config in DRIVE_NAV_VARIANTS.items()},
}


def agent_names() -> list[str]:
    return sorted(AGENTS)


def make_agent(name: str, sim: SimConfig) -> Agent:
    """A fresh agent; an unknown name is an :class:`InputError` on ``--agent``."""
    factory = AGENTS.get(name)
    if factory is None:
        raise InputError("command line", "--agent", f"one of {', '.join(agent_names())}", name)
    return factory(sim)
