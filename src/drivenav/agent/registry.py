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

_DIRECTIONAL = AgentConfig(enrich=False, verify=False)  # "Full Directional Reasoning Pipeline" (Tables V, VI)

DRIVE_NAV_VARIANTS: dict[str, AgentConfig] = {
    # Table VI: module ablation.
    "frontier": replace(
        _DIRECTIONAL, paper=replace(_PAPER, directions=replace(_PAPER.directions, cluster_span=0.0)), decision_scan=True
    ),
    "directional": _DIRECTIONAL,
    "directional-enrich": replace(_DIRECTIONAL, enrich=True),
    "directional-verify": replace(_DIRECTIONAL, verify=True),
    "drive-nav": AgentConfig(),
    # Table V: directional-reasoning components (on the directional pipeline).
    "no-weighted-fmm": replace(_DIRECTIONAL, paper=replace(_PAPER, speed=replace(_PAPER.speed, weighted=False))),
    "no-240": replace(
        _DIRECTIONAL, paper=replace(_PAPER, inspection=replace(_PAPER.inspection, restrict_forward=False))
    ),
    # Table II: analytical comparison with the full system.
    "direction-360": AgentConfig(decision_scan=True),
    "nearest-frontier": AgentConfig(use_reasoner=False, enrich=False, verify=False),
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
