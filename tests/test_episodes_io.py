"""Episode files: round trip, determinism of bytes, and one clear error per kind of bad input."""

from __future__ import annotations

import gzip
import json
from dataclasses import replace
from pathlib import Path

import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from drivenav.benchmarks.benchmark import BenchmarkDefinition, generate_benchmark
from drivenav.episode import Episode, ObjectGoal, ViewPoint, world_to_habitat, yaw_to_quaternion
from drivenav.errors import InputError
from drivenav.eval.episodes import episode_to_dict, load_episodes, save_episodes


def _episode(episode_id: str = "0") -> Episode:
    view = ViewPoint(world_to_habitat(2.0, 1.0), yaw_to_quaternion(0.0))
    goal = ObjectGoal(7, "sofa", world_to_habitat(3.0, 1.0, 0.4), (view,))
    return Episode(
        episode_id=episode_id,
        scene_id="procedural/house_00001",
        start_position=world_to_habitat(0.5, 0.5),
        start_rotation=yaw_to_quaternion(1.0),
        object_category="couch",
        goals=(goal,),
        info={"geodesic_distance": 1.58, "canonical_category": "sofa", "synonym": True},
    )


def test_round_trip(tmp_path: Path) -> None:
    path = tmp_path / "eps.json.gz"
    save_episodes([_episode("0"), _episode("1")], path)
    loaded = load_episodes(path)
    assert [e.episode_id for e in loaded] == ["0", "1"]
    assert episode_to_dict(loaded[0]) == episode_to_dict(_episode("0"))
    assert loaded[0].start_xy == pytest.approx((0.5, 0.5))
    assert loaded[0].start_yaw == pytest.approx(1.0, abs=1e-4)
    assert loaded[0].view_points_xy() == [pytest.approx((2.0, 1.0))]


_metres = st.floats(-50.0, 50.0, allow_nan=False)


@settings(max_examples=30, deadline=None)
@given(x=_metres, y=_metres, yaw=st.floats(-3.2, 3.2), gx=_metres, gy=_metres, view_yaw=st.floats(-3.2, 3.2))
def test_an_episode_read_from_its_file_is_the_episode_written(
    tmp_path_factory: pytest.TempPathFactory, x: float, y: float, yaw: float, gx: float, gy: float, view_yaw: float
) -> None:
    """Coordinates are stored exactly: a run's copy of its episodes, run again, starts where the run started (a
    start rotation rounded to 0.1 mm of a quaternion turns the first depth rays, and most episodes of a
    generated set then drive elsewhere)."""
    view = ViewPoint(world_to_habitat(gx, gy), yaw_to_quaternion(view_yaw))
    goal = ObjectGoal(7, "sofa", world_to_habitat(gx + 0.3, gy, 0.4), (view,))
    start = replace(_episode(), start_position=world_to_habitat(x, y), start_rotation=yaw_to_quaternion(yaw))
    episode = replace(start, goals=(goal,))
    path = tmp_path_factory.mktemp("exact") / "eps.json.gz"
    save_episodes([episode], path)
    assert load_episodes(path) == [episode]


def test_a_generated_set_reads_back_as_generated(tmp_path: Path) -> None:
    generated = generate_benchmark(BenchmarkDefinition("homes:1", 4, 4949, None, "ovon"))
    save_episodes(generated, tmp_path / "eps.json.gz")
    assert load_episodes(tmp_path / "eps.json.gz") == generated


def test_a_temporary_file_left_as_a_link_is_never_written_through(tmp_path: Path) -> None:
    """A run directory someone sent may hold ``episodes.json.gz.partial`` as a link to a file of yours: a resume
    that writes the episodes copy removes the link and leaves its target alone."""
    kept = tmp_path / "yours.txt"
    kept.write_text("precious", encoding="utf-8")
    target = tmp_path / "run" / "episodes.json.gz"
    target.parent.mkdir()
    target.with_name("episodes.json.gz.partial").symlink_to(kept)
    save_episodes([_episode()], target)
    assert kept.read_text(encoding="utf-8") == "precious"
    assert [e.episode_id for e in load_episodes(target)] == ["0"]


def test_same_episodes_same_bytes(tmp_path: Path) -> None:
    save_episodes([_episode()], tmp_path / "a.json.gz")
    save_episodes([_episode()], tmp_path / "b.json.gz")
    assert (tmp_path / "a.json.gz").read_bytes() == (tmp_path / "b.json.gz").read_bytes()


def _write(tmp_path: Path, payload: object) -> Path:
    path = tmp_path / "bad.json.gz"
    path.write_bytes(gzip.compress(json.dumps(payload).encode()))
    return path


def _valid() -> dict[str, object]:
    return episode_to_dict(_episode())


@pytest.mark.parametrize(
    ("mutate", "field"),
    [
        (lambda e: e.pop("scene_id"), "episodes[0].scene_id"),
        (lambda e: e.update(start_position=[1.0, 2.0]), "episodes[0].start_position"),
        (lambda e: e.update(start_rotation="north"), "episodes[0].start_rotation"),
        (lambda e: e.update(goals=[]), "episodes[0].goals"),
        (
            lambda e: e["goals"][0].update(view_points=[{"agent_state": {"position": [0, 0]}}]),
            "episodes[0].goals[0].view_points[0].agent_state.position",
        ),
        (lambda e: e.update(object_category=""), "episodes[0].object_category"),
        (lambda e: e["info"].update(geodesic_distance="far"), "episodes[0].info.geodesic_distance"),
        (lambda e: e["info"].update(geodesic_distance=-1.0), "episodes[0].info.geodesic_distance"),
        (lambda e: e["info"].update(canonical_category=7), "episodes[0].info.canonical_category"),
        (lambda e: e["info"].update(synonym="yes"), "episodes[0].info.synonym"),
    ],
)
def test_bad_fields_are_named(tmp_path: Path, mutate, field: str) -> None:  # type: ignore[no-untyped-def]
    episode = _valid()
    mutate(episode)
    path = _write(tmp_path, {"episodes": [episode]})
    with pytest.raises(InputError) as info:
        load_episodes(path)
    assert str(path) in str(info.value)
    assert f"'{field}'" in str(info.value)


def test_not_gzip_json(tmp_path: Path) -> None:
    path = tmp_path / "eps.json.gz"
    path.write_bytes(b"\x1f\x8b\x08garbage")
    with pytest.raises(InputError, match="gzip-compressed JSON"):
        load_episodes(path)


def test_missing_episodes_list(tmp_path: Path) -> None:
    with pytest.raises(InputError, match="field 'episodes': expected the keys episodes, got 'missing'"):
        load_episodes(_write(tmp_path, {"eps": []}))


def test_plain_json_is_read_too(tmp_path: Path) -> None:
    path = tmp_path / "eps.json"
    path.write_text(json.dumps({"episodes": [_valid()]}))
    assert [e.episode_id for e in load_episodes(path)] == ["0"]


def test_missing_file(tmp_path: Path) -> None:
    with pytest.raises(InputError, match="--episodes"):
        load_episodes(tmp_path / "nope.json.gz")
