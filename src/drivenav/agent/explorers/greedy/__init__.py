"""The greedy nearest-frontier explorer (paper Table II): :mod:`~drivenav.agent.explorers.greedy.explorer`."""
