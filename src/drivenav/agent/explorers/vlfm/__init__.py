"""VLFM's explorer (Yokoyama et al., ICRA 2024): :mod:`~drivenav.agent.explorers.vlfm.explorer`."""
