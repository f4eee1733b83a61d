"""Agents by ``--agent`` name, built from the configuration tree (:mod:`drivenav.settings`)."""

from __future__ import annotations

from collections.abc import Callable
from functools import partial

from drivenav.agent.base import Agent
from drivenav.agent.drivenav import DriveNavAgent
from drivenav.agent.oracle import OracleAgent
from drivenav.agent.random_agent import RandomAgent
from drivenav.errors import InputError
from drivenav.methods import agent_names, method_named
from drivenav.semantics.registry import make_grounder, make_reasoner, model_requirements
from drivenav.settings import Settings
from drivenav.types import SimConfig

REFERENCE: dict[str, Callable[[SimConfig], Agent]] = {
    OracleAgent.name: OracleAgent,
    RandomAgent.name: RandomAgent,
}


def make_agent(settings: Settings) -> Agent:
    """A fresh agent ``settings.run.agent``; DRIVE-Nav variants take the paper's constants, the agent switches,
    the mapper tuning and the models of ``settings``. An unknown name is an :class:`InputError` on ``--agent``."""
    name = settings.run.agent
    if name in REFERENCE:
        return REFERENCE[name](settings.sim)
    if method_named(name) is None:
        raise InputError("command line", "--agent", f"one of {', '.join(agent_names())}", name)
    models = settings.models
    return DriveNavAgent(
        settings.sim,
        settings.agent,
        settings.paper,
        settings.mapping,
        name=name,
        reasoner_factory=partial(make_reasoner, models),
        grounder_factory=partial(make_grounder, models),
        requires=model_requirements(models),
    )
