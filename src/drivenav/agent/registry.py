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
from drivenav.errors import InputError
from drivenav.semantics.registry import ModelSpec, make_grounder, make_reasoner, model_requirements
from drivenav.types import SimConfig

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

SIMPLE_AGENTS: dict[str, Callable[[SimConfig], Agent]] = {
    OracleAgent.name: OracleAgent,
    RandomAgent.name: RandomAgent,
}


def agent_names() -> list[str]:
    return sorted([*SIMPLE_AGENTS, *DRIVE_NAV_VARIANTS])


def make_agent(name: str, sim: SimConfig, models: ModelSpec | None = None) -> Agent:
    """A fresh agent; DRIVE-Nav variants use the reasoner and grounder of ``models`` (embedded by default).

    An unknown name is an :class:`InputError` on ``--agent``.
    """
    if name in SIMPLE_AGENTS:
        return SIMPLE_AGENTS[name](sim)
    if name not in DRIVE_NAV_VARIANTS:
        raise InputError("command line", "--agent", f"one of {', '.join(agent_names())}", name)
    spec = models or ModelSpec()
    return DriveNavAgent(
        sim,
        DRIVE_NAV_VARIANTS[name],
        name=name,
        reasoner_factory=partial(make_reasoner, spec),
        grounder_factory=partial(make_grounder, spec),
        requires=model_requirements(spec),
    )
