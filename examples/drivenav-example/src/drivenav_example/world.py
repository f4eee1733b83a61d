"""The ``embedded-noisy`` world as drivenav's command line and runs see it: its
:class:`~drivenav.worlds.entry.WorldEntry` (its ``--depth-noise`` option, how the spec is built from the
command line, where its episodes come from, how a run on it is titled, its scenes for ``drivenav viz``). The entry
point ``embedded-noisy = "drivenav_example.world:NOISY"`` (group ``drivenav.worlds``) names it. This module is
imported whenever drivenav's command line is built, so it stays light: the env (:mod:`.noisy_depth`) is imported
when a run uses it."""

from __future__ import annotations

import argparse
from typing import TYPE_CHECKING

from drivenav.worlds.embedded import load_or_generate, scene_library
from drivenav.worlds.entry import WorldEntry

if TYPE_CHECKING:
    from drivenav.envs.base import EnvSpec
    from drivenav.settings import Settings


def _spec_class() -> type[EnvSpec]:
    from drivenav_example.noisy_depth import NoisyDepthSpec

    return NoisyDepthSpec


def _add_options(group: argparse._ArgumentGroup) -> None:
    group.add_argument("--depth-noise", type=float, default=None, help="embedded-noisy: depth noise (m)")


def _build(args: argparse.Namespace, settings: Settings) -> EnvSpec:
    from drivenav_example.noisy_depth import NoisyDepthSpec

    noise = 0.05 if args.depth_noise is None else args.depth_noise
    return NoisyDepthSpec(args.scenes, settings.run.seed, noise)


NOISY = WorldEntry(
    name="embedded-noisy",
    summary="the embedded simulator with a noisy depth camera",
    spec_class=_spec_class,
    build=_build,
    episodes=load_or_generate,
    label=lambda args: f"{args.scenes} (noisy depth)",
    add_options=_add_options,
    own_options=("--depth-noise",),
    scenes=scene_library,
)
