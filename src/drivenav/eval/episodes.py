"""HM3D-OVON-style episode files: validated reading and writing, and the check of a file against the embedded world's
scenes (generation: :mod:`drivenav.benchmarks.generate`).

A file is gzip-compressed JSON ``{"episodes": [...]}``; each episode carries ``episode_id``, ``scene_id``,
``start_position`` and ``start_rotation`` (Habitat's y-up frame, see :mod:`drivenav.episode`),
``object_category`` (the text given to the agent, a synonym in some episodes as in HM3D-OVON's
val_seen_synonyms), ``goals`` (every instance of the category with ``position`` and ``view_points``) and
``info`` (``geodesic_distance``, ``canonical_category``, ``synonym``); episodes read from a Habitat dataset keep
its ``scene_dataset_config`` and ``children_object_categories`` where it has them.
"""

from __future__ import annotations

import errno
import gc
import gzip
import json
import os
import secrets
from collections.abc import Callable, Iterable, Iterator
from contextlib import contextmanager, suppress
from pathlib import Path
from typing import Any

from drivenav.envs.embedded.building import Building
from drivenav.envs.embedded.library import SceneLibrary
from drivenav.envs.embedded.terrain import (
    START_TOLERANCE,
    DistanceField,
    FlatTerrain,
    LevelTerrain,
    Terrain,
    terrain_of,
)
from drivenav.episode import (
    Episode,
    ObjectGoal,
    coordinates,
    episode_extras,
    goal_to_dict,
    parse_episode_with,
    parse_goals,
)
from drivenav.errors import InputError
from drivenav.jsonstream import DOCUMENT, ArrayStream, Convert, JsonObject
from drivenav.types import SimConfig
from drivenav.validation import Fields


def episode_to_dict(episode: Episode) -> JsonObject:
    """The HM3D-OVON JSON form of an episode (goals inside it)."""
    return _episode_dict(episode, [goal_to_dict(goal) for goal in episode.goals])


def _episode_dict(episode: Episode, goals: Any) -> JsonObject:
    return {
        "episode_id": episode.episode_id,
        "scene_id": episode.scene_id,
        "start_position": coordinates(episode.start_position),
        "start_rotation": coordinates(episode.start_rotation),
        "object_category": episode.object_category,
        "goals": goals,
        "info": dict(episode.info),
        **episode_extras(episode),
    }


_COMPACT = (",", ":")


def episode_texts(episodes: Iterable[Episode], sort_keys: bool = False) -> Iterator[str]:
    """Each episode's compact JSON text, as ``json.dumps(episode_to_dict(episode))`` with ``separators=(",", ":")``
    writes it, with each goal's text made once however many episodes share the goal: 100,000 episodes of a few
    hundred goals are written in seconds, not minutes."""
    placeholder = json.dumps(secrets.token_hex(16))  # stands for the goals in the episode's own text
    goal_texts: dict[int, str] = {}  # by the goal object's id: every goal stays alive in ``episodes`` meanwhile
    for episode in episodes:
        text = json.dumps(_episode_dict(episode, placeholder[1:-1]), separators=_COMPACT, sort_keys=sort_keys)
        head, _, tail = text.partition(placeholder)
        if not tail or placeholder in tail:  # the placeholder is also an id or a category: no shortcut
            yield json.dumps(episode_to_dict(episode), separators=_COMPACT, sort_keys=sort_keys)
            continue
        goals = [_goal_text(goal, goal_texts, sort_keys) for goal in episode.goals]
        yield f"{head}[{','.join(goals)}]{tail}"


def _goal_text(goal: ObjectGoal, texts: dict[int, str], sort_keys: bool) -> str:
    text = texts.get(id(goal))
    if text is None:
        text = texts[id(goal)] = json.dumps(goal_to_dict(goal), separators=_COMPACT, sort_keys=sort_keys)
    return text


WRITE_CHUNK = 1 << 20  # characters of episode text gathered per write


def save_episodes(episodes: Iterable[Episode], path: str | Path) -> None:
    """Write a json.gz episode file, byte-identical for identical episodes; written to a temporary file and moved
    into place, so a reader sees the old file or the whole new one. A temporary file left behind (a link, in a run
    directory someone sent) is removed first, never written through."""
    target = Path(path)
    if target.is_dir():
        raise IsADirectoryError(errno.EISDIR, "is a directory (an episodes file is expected)", str(target))
    target.parent.mkdir(parents=True, exist_ok=True)
    partial = target.with_name(target.name + ".partial")
    try:
        partial.unlink(missing_ok=True)
        _write_gzip(partial, episodes)
        os.replace(partial, target)
    except BaseException as error:  # an interrupt too: no partial file is left behind
        with suppress(OSError):
            partial.unlink(missing_ok=True)
        if isinstance(error, OSError):  # named by the path asked for, not the temporary one
            raise OSError(error.errno, error.strerror, str(target)) from None
        raise


def _write_gzip(path: Path, episodes: Iterable[Episode]) -> None:
    with path.open("wb") as raw, gzip.GzipFile(filename="", mode="wb", fileobj=raw, mtime=0) as gz:
        pending = ['{"episodes":[']
        size = 0
        for i, text in enumerate(episode_texts(episodes)):
            pending.append(f",{text}" if i else text)
            size += len(text)
            if size > WRITE_CHUNK:
                gz.write("".join(pending).encode())
                pending, size = [], 0
        pending.append("]}")
        gz.write("".join(pending).encode())


def load_episodes(
    path: str | Path, require_goals: bool = True, read_one: Callable[[], object] = lambda: None
) -> list[Episode]:
    """Read and validate an episode file (json.gz, or plain .json), streamed: the episodes are read one at a time
    and a goals text that episodes repeat is read once (one shared tuple), so a file of 100,000 episodes is read in
    seconds and held in about 1 KB per episode. ``require_goals`` False also reads a live run's copy of its
    episode (``drivenav run``: a target, no goals); ``read_one`` is called after each episode read (a progress
    bar's step)."""
    source = Path(path)
    if not source.is_file():
        raise InputError(source, "--episodes", "an episode count or an existing .json.gz file")
    fields = Fields(source)

    def goals(value: Any, index: int) -> tuple[ObjectGoal, ...]:
        return parse_goals(fields, f"episodes[{index}].goals", value, require_goals)

    stream = ArrayStream(source, "episodes", member="goals", convert=goals)
    try:
        with _no_cycle_collection():
            episodes = []
            for i, item in enumerate(stream.items()):
                episodes.append(_parse_streamed(fields, f"episodes[{i}]", item, goals, i))
                read_one()
    except InputError as error:
        if error.field != DOCUMENT:  # a Habitat file fails on its first episode's goals: say what it is
            _refuse_habitat_layout(fields, _top_level(source))
        raise
    data = fields.mapping(stream.document if stream.document is not None else stream.members, "")
    if not stream.found:
        fields.mapping(data, "", required=("episodes",))
        fields.sequence(data["episodes"], "episodes", 1, "a non-empty list of episodes")
    _refuse_habitat_layout(fields, {**data, "episodes": episodes})
    fields.sequence(episodes, "episodes", 1, "a non-empty list of episodes")
    _refuse_duplicates(fields, episodes)
    return episodes


@contextmanager
def _no_cycle_collection() -> Iterator[None]:
    """Python's cycle collector paused while episodes are read: they hold no cycles, and its passes over a growing
    heap of 100,000 episodes' tuples would cost a third of the reading time."""
    enabled = gc.isenabled()
    gc.disable()
    try:
        yield
    finally:
        if enabled:
            gc.enable()


def _parse_streamed(fields: Fields, name: str, item: Any, goals: Convert, index: int) -> Episode:
    """An episode of a streamed file: its ``goals`` came converted (see :class:`ArrayStream`) unless absent."""
    item = fields.mapping(item, name)
    return parse_episode_with(fields, name, item, item["goals"] if "goals" in item else goals(None, index))


def _top_level(source: Path) -> JsonObject:
    """The top-level members of an episode file (its episodes read but not kept), for :func:`_refuse_habitat_layout`."""
    stream = ArrayStream(source, "episodes")
    count = sum(1 for _ in stream.items())
    return {**stream.members, "episodes": [None] * min(count, 1)} if stream.document is None else {"episodes": [None]}


HABITAT_SPLIT_KEYS = ("category_to_task_category_id", "category_to_mp3d_category_id", "goals_by_category")
"""Keys of a Habitat ObjectNav v1 / HM3D-OVON split file (its episodes live in ``content/<scene>.json.gz``;
HM3D-OVON's holds only ``goals_by_category``, empty, and ``episodes``)."""


def _refuse_habitat_layout(fields: Fields, data: JsonObject) -> None:
    """Habitat's ObjectNav v1 layout (HM3D-OVON's too) keeps goals per category (``goals_by_category``) and, in a
    split file, the episodes in ``content/<scene>.json.gz`` beside it: the embedded world reads neither."""
    source = Path(fields.source)
    expected = "goals inside each episode (the embedded world's layout); a Habitat file runs with --env habitat"
    if data["episodes"] == [] and ((source.parent / "content").is_dir() or any(k in data for k in HABITAT_SPLIT_KEYS)):
        got = "[] in a Habitat ObjectNav v1 / HM3D-OVON split file: episodes in content/<scene>.json.gz"
        raise fields.error("episodes", expected, got)
    if "goals_by_category" in data:
        got = "Habitat ObjectNav v1 / HM3D-OVON content file: goals by category, episodes without goals"
        raise fields.error("goals_by_category", expected, got)


def _refuse_duplicates(fields: Fields, episodes: list[Episode]) -> None:
    first: dict[str, int] = {}
    for i, episode in enumerate(episodes):
        j = first.setdefault(episode.episode_id, i)
        if j != i:
            expected = f"an id no other episode has (episodes[{j}] has it)"
            raise fields.error(f"episodes[{i}].episode_id", expected, episode.episode_id)


GEODESIC_TOLERANCE = 0.10  # an episode's info.geodesic_distance may differ this much from the world's own


FLOOR_TOLERANCE = START_TOLERANCE  # metres: a start stands on a floor (Habitat's one-floor step limit)


def validate_for_scenes(
    episodes: list[Episode],
    library: SceneLibrary,
    source: str | Path,
    sim: SimConfig,
    checked_one: Callable[[], object] = lambda: None,
) -> None:
    """Every episode fits the world: its scene is in ``library``; its start and view points lie on the scene's one
    connected navigable area (:mod:`drivenav.envs.embedded.terrain`; in a building, on a floor within 0.25 m of
    their heights), so a goal is reachable from the start; in a building, every goal has a view point on its own
    floor and a start off the navigable area over a stairwell is named as such; and ``info.geodesic_distance`` (if
    given) is the world's start-to-goal distance (what SPL divides by) within 10 %. Goals that episodes share (one
    tuple, as a file's repeated goals text reads) are checked once. ``checked_one`` is called after each episode
    checked (a progress bar's step)."""
    fields = Fields(source)
    terrains: dict[str, Terrain] = {}
    distances: dict[tuple[str, tuple[int, ...]], DistanceField] = {}  # by the goals' ids: all alive in ``episodes``
    for i, episode in enumerate(episodes):
        if episode.scene_id not in library:
            raise fields.error(f"episodes[{i}].scene_id", f"a scene of --scenes {library.spec}", episode.scene_id)
        if episode.scene_id not in terrains:
            terrains[episode.scene_id] = terrain_of(library.load(episode.scene_id), sim)
        terrain = terrains[episode.scene_id]
        key = (episode.scene_id, tuple(map(id, episode.goals)))
        if key not in distances:
            _check_view_points(episode, f"episodes[{i}]", terrain, fields)
            distances[key] = terrain.field(episode.view_points_xyz())
        _check_start(episode, f"episodes[{i}]", terrain, fields)
        _check_geodesic(episode, f"episodes[{i}]", distances[key], fields)
        checked_one()


def _where(episode: Episode) -> str:
    return f"a navigable position the agent can reach in {episode.scene_id}"


def _check_view_points(episode: Episode, name: str, terrain: Terrain, fields: Fields) -> None:
    for k, goal in enumerate(episode.goals):
        for m, point in enumerate(goal.view_points):
            if not terrain.on_reachable(*point.xy, point.height):
                field = f"{name}.goals[{k}].view_points[{m}].agent_state.position"
                raise fields.error(field, _where(episode), list(point.position))
        if isinstance(terrain, LevelTerrain):
            _check_goal_floor(goal, f"{name}.goals[{k}]", terrain.building, fields)


def _check_goal_floor(goal: ObjectGoal, name: str, building: Building, fields: Fields) -> None:
    """A goal of a building has a view point on its own floor (where :mod:`drivenav.envs.embedded.goals` puts them):
    the storey under the goal's ``position``, an object's centre, which lies between its floor and the slab above."""
    storey = building.storey_at(goal.position[1])
    floor = building.elevations[storey]
    if not any(abs(point.height - floor) <= FLOOR_TOLERANCE for point in goal.view_points):
        expected = f"a view point on the goal's floor (storey {storey}, height {floor:g} m, under its position)"
        heights = sorted({round(point.height, 3) for point in goal.view_points})
        raise fields.error(f"{name}.view_points", expected, f"view points at heights {heights}")


def _check_start(episode: Episode, name: str, terrain: Terrain, fields: Fields) -> None:
    height = episode.start_height
    flat = isinstance(terrain, FlatTerrain)
    if not terrain.on_reachable(*episode.start_xy, height) or (flat and abs(height) > FLOOR_TOLERANCE):
        expected = f"{_where(episode)}, on its floor (height 0)" if flat else f"{_where(episode)}, on a floor"
        if isinstance(terrain, LevelTerrain) and _in_stairwell(terrain.building, episode):
            storey = terrain.building.storey_at(height)
            expected = f"{expected}, not in the void of a stairwell (storey {storey}'s floor is open there)"
        raise fields.error(f"{name}.start_position", expected, list(episode.start_position))


def _in_stairwell(building: Building, episode: Episode) -> bool:
    """Whether the start lies over a stairwell of the storey at its height (where that storey has no floor)."""
    row, col = building.grid.cell_at(*episode.start_xy)
    rows, cols = building.grid.shape
    holes = building.holes[building.storey_at(episode.start_height)]
    return 0 <= row < rows and 0 <= col < cols and bool(holes[row, col])


def _check_geodesic(episode: Episode, name: str, goals: DistanceField, fields: Fields) -> None:
    distance = goals.at(*episode.start_xy, episode.start_height)  # finite: start and view points share one area
    given = episode.info.get("geodesic_distance")
    if given is not None and abs(given - distance) > GEODESIC_TOLERANCE * distance:
        expected = f"the world's start-to-goal distance {distance:.2f} m within {GEODESIC_TOLERANCE:.0%}"
        raise fields.error(f"{name}.info.geodesic_distance", expected, given)
