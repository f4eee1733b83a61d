"""The example package's rows: the farthest-frontier explorer's method and one variant of it, which ``--agent`` and
``bench ablations --methods`` offer beside drivenav's own (entry point group ``drivenav.methods``)."""

from __future__ import annotations

from drivenav.methods import Method

ROWS = (
    Method("farthest", (), "the farthest frontier point within 12 s of travel", explorer="farthest"),
    Method(
        "farthest-near",
        (),
        "farthest, with goals within 6 s of travel only",
        ("explorer.farthest.max_travel_time=6.0",),
        explorer="farthest",
        base="farthest",
    ),
)
"""The entry point ``farthest = "drivenav_example.methods:ROWS"`` (group ``drivenav.methods``) names these."""
