"""Bad input on the command line: one line naming the file and field, exit status 2, no traceback."""

from __future__ import annotations

import gzip
import json
from pathlib import Path

from conftest import run_cli
from drivenav.benchmarks.generate import generate_episodes
from drivenav.envs.embedded.library import SceneLibrary
from drivenav.eval.episodes import episode_to_dict


def _assert_clean_error(result, *needles: str) -> None:  # type: ignore[no-untyped-def]
    assert result.returncode == 2, result.stderr
    assert "Traceback" not in result.stderr
    lines = [line for line in result.stderr.splitlines() if line.strip()]
    assert len(lines) == 1, result.stderr
    for needle in needles:
        assert needle in lines[0]


def test_unknown_agent(tmp_path: Path) -> None:
    result = run_cli("eval", "--agent", "teleport", "--episodes", "1", "--out", str(tmp_path / "run"))
    _assert_clean_error(result, "--agent", "teleport", "oracle")


def test_malformed_episode_file(tmp_path: Path) -> None:
    bad = tmp_path / "eps.json.gz"
    bad.write_bytes(b"not gzip, not json")
    result = run_cli("eval", "--agent", "oracle", "--episodes", str(bad), "--out", str(tmp_path / "run"))
    _assert_clean_error(result, str(bad), "JSON")


def test_episode_starting_off_the_navigable_area(tmp_path: Path) -> None:
    [episode] = generate_episodes(SceneLibrary("procedural:1", 0), 1, 0)
    data = episode_to_dict(episode)
    data["start_position"] = [-50.0, 0.0, 50.0]
    path = tmp_path / "eps.json.gz"
    path.write_bytes(gzip.compress(json.dumps({"episodes": [data]}).encode()))
    result = run_cli("eval", "--agent", "oracle", "--episodes", str(path), "--out", str(tmp_path / "run"))
    _assert_clean_error(result, str(path), "episodes[0].start_position", "navigable")


def test_episode_in_unknown_scene(tmp_path: Path) -> None:
    [episode] = generate_episodes(SceneLibrary("procedural:1", 0), 1, 0)
    data = episode_to_dict(episode)
    data["scene_id"] = "hm3d/val/00800-TEEsavR23oF"
    path = tmp_path / "eps.json.gz"
    path.write_bytes(gzip.compress(json.dumps({"episodes": [data]}).encode()))
    result = run_cli("eval", "--agent", "oracle", "--episodes", str(path), "--out", str(tmp_path / "run"))
    _assert_clean_error(result, "episodes[0].scene_id")


def test_malformed_map_yaml(tmp_path: Path) -> None:
    scene = tmp_path / "scene"
    scene.mkdir()
    (scene / "map.yaml").write_text("image: map.pgm\nresolution: [oops\n")
    result = run_cli("episodes", "generate", "--scenes", str(scene), "--num", "1", "--out", str(tmp_path / "e.json.gz"))
    _assert_clean_error(result, "map.yaml")


def test_missing_scene_path(tmp_path: Path) -> None:
    result = run_cli("episodes", "generate", "--scenes", str(tmp_path / "nowhere"), "--num", "1", "--out", "x.json.gz")
    _assert_clean_error(result, "--scenes")


def test_bad_worker_count(tmp_path: Path) -> None:
    result = run_cli("eval", "--agent", "oracle", "--episodes", "1", "--workers", "0", "--out", str(tmp_path))
    _assert_clean_error(result, "--workers")


def test_unknown_scorer(tmp_path: Path) -> None:
    result = run_cli("eval", "--agent", "oracle", "--episodes", "1", "--scorer", "clip", "--out", str(tmp_path / "run"))
    _assert_clean_error(result, "models.scorer", "--scorer", "blip2-itm", "'clip'")


def test_scorer_replay_without_a_recording(tmp_path: Path) -> None:
    missing = str(tmp_path / "calls.jsonl")
    args = ("--scorer", "replay", "--vlm-replay", missing, "--out", str(tmp_path / "run"))
    result = run_cli("eval", "--agent", "oracle", "--episodes", "1", *args)
    _assert_clean_error(result, "--vlm-replay", missing)
