"""One world as a run and the command line see it: a :class:`WorldEntry`.

An entry names everything that differs between worlds outside the world's own simulator code: its ``--env``
options, how its :class:`~drivenav.envs.base.EnvSpec` is built from the parsed command line and the settings,
where its episodes come from, how a run on it is titled, and how its spec is rebuilt from the world record that
``run.json`` keeps under ``config.env``. Everything here is light (the world's modules are imported when a run
uses them), so that the command line lists the worlds without loading numpy.
"""

from __future__ import annotations

import argparse
from collections.abc import Callable
from dataclasses import dataclass, fields
from pathlib import Path
from typing import TYPE_CHECKING

from drivenav.errors import InputError
from drivenav.jsonstream import JsonObject
from drivenav.plugins import OptionAdder, no_options, refuse_options

if TYPE_CHECKING:
    from drivenav.envs.base import EnvSpec
    from drivenav.envs.embedded.building import Building
    from drivenav.envs.embedded.scene import Scene
    from drivenav.episode import Episode
    from drivenav.eval.runner import RunSpec
    from drivenav.settings import Settings

SpecBuilder = Callable[[argparse.Namespace, "Settings"], "EnvSpec"]
EpisodeSource = Callable[[argparse.Namespace, "RunSpec"], "list[Episode]"]
SceneLoader = Callable[[str], "Scene | Building"]


def no_presets(args: argparse.Namespace) -> list[str]:
    """A world that adds no configuration preset."""
    return []


@dataclass(frozen=True)
class WorldEntry:
    """A world by its ``--env`` name.

    ``summary`` names it in ``--env``'s help; ``docs`` points to its documentation in the world options' title.
    ``spec_class`` returns the spec's class (imported on first use). ``add_options`` adds the world's own options
    to the command line's world group; ``own_options`` are those refused with any other world; ``set_prefix``
    marks the ``--set PREFIX.KEY=VALUE`` overrides passed to the world itself (refused with any other world and kept
    out of drivenav's settings). ``presets`` are configuration presets the world's options imply, layered first.
    ``build`` makes the spec from the command line and the resolved settings, ``episodes`` the run's episodes,
    ``label`` the title of a run's table. ``scenes``, where drivenav can draw the world's scenes, loads one by
    id from a spec (``drivenav viz``); other worlds are drawn as a trace on a blank floor.
    ``embedded_episodes``: the world runs the embedded world's episodes (``bench ablations`` then defaults to
    benchmark v1's frozen ones); ``needs_benchmark``: it runs a Habitat ``--config`` benchmark (``doctor``).
    """

    name: str
    summary: str
    spec_class: Callable[[], type[EnvSpec]]
    build: SpecBuilder
    episodes: EpisodeSource
    label: Callable[[argparse.Namespace], str]
    add_options: OptionAdder = no_options
    own_options: tuple[str, ...] = ()
    docs: str = ""
    set_prefix: str = ""
    presets: Callable[[argparse.Namespace], list[str]] = no_presets
    scenes: Callable[[EnvSpec], SceneLoader] | None = None
    embedded_episodes: bool = False
    needs_benchmark: bool = False

    def rebuild(self, record: JsonObject, source: str | Path) -> EnvSpec:
        """The spec a run recorded (``run.json``'s ``config.env``): the spec class's fields read back, JSON lists
        as the tuples they were; a record that does not fit is an :class:`InputError` naming ``source``."""
        cls = self.spec_class()
        names = [f.name for f in fields(cls)]
        values = {key: tuple(v) if isinstance(v, list) else v for key, v in record.items() if key in names}
        try:
            return cls(**values)
        except TypeError as error:
            expected = f"a {self.name} world's fields ({', '.join(names)})"
            raise InputError(source, "config.env", expected, str(error)) from None

    def scene(self, spec: EnvSpec, scene_id: str, source: str | Path) -> Scene | Building | None:
        """The scene ``scene_id`` of the world ``spec`` describes (None where drivenav cannot draw this world's
        scenes); an :class:`InputError` naming ``source``'s ``scene_id`` when the world has no such scene (an
        episodes copy naming another world's scene)."""
        if self.scenes is None:
            return None
        try:
            return self.scenes(spec)(scene_id)
        except KeyError:
            raise InputError(source, "scene_id", f"a scene of the run's {self.name} world", scene_id) from None

    def refuse_options(self, args: argparse.Namespace) -> None:
        """Refuse this world's own options and ``--set`` overrides in ``args`` (a run on another world)."""
        refuse_options(args, self.own_options, f"only with --env {self.name}")
        found = [o for o in getattr(args, "overrides", []) if self.set_prefix and o.startswith(self.set_prefix)]
        if found:
            expected = f"{self.set_prefix}KEY=VALUE only with --env {self.name}"
            raise InputError("command line", "--set", expected, found[0])
