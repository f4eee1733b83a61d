"""The Habitat adapter's tests run in ``.venv-habitat`` (habitat-lab 0.3.320260507, numpy 1.26): ``make test-habitat``.

habitat-sim cannot be installed on our machines, so its compiled modules get import stand-ins (a no-op where the
real ones are installed) and drivenav's embedded world is registered as a habitat-lab simulator,
``DriveNavSim-v0`` (:mod:`drivenav_sim`); everything else is habitat-lab's own code.
"""

from __future__ import annotations

import standins

standins.install()

import drivenav_sim  # noqa: E402,F401  (registers DriveNavSim-v0)
