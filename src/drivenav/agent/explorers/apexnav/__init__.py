"""ApexNav's explorer (Zhang et al., RA-L 2025): :mod:`~drivenav.agent.explorers.apexnav.explorer`."""
