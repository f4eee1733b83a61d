"""Agents by ``--agent`` name, built from the configuration tree (:mod:`drivenav.settings`).

This sits on the floor above the settings: the agent package below knows no settings, only the typed parts it is
given (the simulator's sensor set-up, the paper's constants of Sec. IV, the body's switches, the explorer's
section, the mapper tuning).
"""

from __future__ import annotations

import importlib
import logging
from collections.abc import Callable
from functools import cache, partial

from drivenav.agent.base import Agent
from drivenav.agent.body import ExplorerAgent, explorer_class
from drivenav.agent.explorers import EXPLORERS, explorer_entry
from drivenav.errors import InputError
from drivenav.methods import METHOD_NAMES, REFERENCE_AGENTS, agent_names, method_named
from drivenav.semantics.registry import (
    GROUNDER_BACKENDS,
    REASONER_BACKENDS,
    SCORER_BACKENDS,
    SEGMENTER_BACKENDS,
    make_grounder,
    make_reasoner,
    make_scorer,
    model_requirements,
    scorer_requirements,
)
from drivenav.settings import Settings, explorer_section
from drivenav.types import SimConfig

log = logging.getLogger(__name__)


def make_agent(settings: Settings) -> Agent:
    """A fresh agent ``settings.run.agent``: the body with the explorer ``settings.explorer.name`` and its section,
    the paper's constants, the body's switches, the mapper tuning and the models of ``settings`` (an explorer that
    scores frames also the image-text scorer). An unknown name is an :class:`InputError` on ``--agent``."""
    name = settings.run.agent
    warn_shadowed_explorers()
    if name in REFERENCE_AGENTS:
        return reference_agent(name)(settings.sim)
    if method_named(name) is None:
        raise InputError("command line", "--agent", f"one of {', '.join(agent_names())}", name)
    entry = explorer_entry(settings.explorer.name)
    models = settings.models
    requires = model_requirements(models)
    explorer_config = explorer_section(settings, entry.name)
    if explorer_class(entry).needs_scorer(explorer_config):
        requires |= scorer_requirements(models)
    return ExplorerAgent(
        settings.sim,
        settings.agent,
        settings.paper,
        settings.mapping,
        name=name,
        explorer=entry,
        explorer_config=explorer_config,
        reasoner_factory=partial(make_reasoner, models),
        grounder_factory=partial(make_grounder, models),
        requires=requires,
        scorer_factory=partial(make_scorer, models),
    )


def reference_agent(name: str) -> Callable[[SimConfig], Agent]:
    """The class of the reference agent ``name`` (:data:`drivenav.methods.REFERENCE_AGENTS`), imported now."""
    module, _, cls = REFERENCE_AGENTS[name].partition(":")
    factory: Callable[[SimConfig], Agent] = getattr(importlib.import_module(module), cls)
    return factory


@cache
def warn_shadowed_explorers() -> None:
    """One warning line (once per process) for each plug-in explorer whose name is a reference agent's or a
    method's: ``--agent NAME`` runs drivenav's, as a plug-in that takes a built-in name is ignored
    (:attr:`~drivenav.plugins.Registry.declared`); the plug-in runs with ``--set explorer.name=NAME``."""
    for name in sorted({*REFERENCE_AGENTS, *METHOD_NAMES}):
        if EXPLORERS.is_plugin(name):
            log.warning(
                "drivenav: explorer plug-in %s: --agent %s is drivenav's own agent, not this explorer "
                "(it runs with --set explorer.name=%s)",
                EXPLORERS.declared[name].entry_point,
                name,
                name,
            )


def check_parts(settings: Settings) -> None:
    """Import every part ``settings`` name, as a run does before its first episode: the chosen explorer's class
    and the reasoner, detector, scorer and segmenter backends. A part that cannot be imported (a broken plug-in, a
    missing extra) is its one :class:`~drivenav.errors.InputError` line, so that ``config show`` refuses what a
    run refuses; the models' files and servers are a run's checks (:func:`~drivenav.semantics.registry.check_models`),
    not those of a tree printed for later."""
    name = settings.explorer.name
    with EXPLORERS.guard(name, "import"):
        explorer_class(explorer_entry(name))
    models = settings.models
    for registry, backend in (
        (REASONER_BACKENDS, models.reasoner),
        (GROUNDER_BACKENDS, models.detector),
        (SCORER_BACKENDS, models.scorer),
        (SEGMENTER_BACKENDS, models.segmenter),
    ):
        registry.get(backend)
