"""The robot commands end to end: ``robot keys``, ``robot serve-sim`` with ``eval --env robot`` (the same records
as a direct ``eval``), ``run --env robot`` (one live episode with its trace and picture), and the refusals."""

from __future__ import annotations

import json
import socket
import stat
import subprocess
import sys
from collections.abc import Iterator
from pathlib import Path

import pytest

from conftest import REPO, run_cli
from drivenav.benchmarks.generate import generate_episodes
from drivenav.envs.embedded.library import SceneLibrary
from drivenav.eval.episodes import save_episodes
from drivenav.settings import load_settings

SCENES = "procedural:2"
SAME = ("episode_id", "success", "spl", "steps", "path_length", "distance_to_goal", "collisions", "stop_reason")


def free_endpoint() -> str:
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return f"tcp://127.0.0.1:{s.getsockname()[1]}"


@pytest.fixture(scope="module")
def episodes_file(tmp_path_factory: pytest.TempPathFactory) -> Path:
    file = tmp_path_factory.mktemp("robot") / "episodes.json.gz"
    save_episodes(generate_episodes(SceneLibrary(SCENES, 5), 2, 5, load_settings().sim), file)
    return file


@pytest.fixture
def serve_sim(episodes_file: Path) -> Iterator[tuple[str, Path]]:
    keys = episodes_file.parent / "keys"
    if not keys.exists():
        assert run_cli("robot", "keys", str(keys)).returncode == 0
    endpoint = free_endpoint()
    command = [sys.executable, "-m", "drivenav.cli", "robot", "serve-sim", "--scenes", SCENES, "--seed", "5"]
    command += ["--episodes", str(episodes_file), "--bind", endpoint, "--keys", str(keys)]
    server = subprocess.Popen(command, cwd=REPO, stdout=subprocess.PIPE, text=True)
    assert server.stdout is not None
    assert server.stdout.readline().startswith(f"serving on {endpoint} with CURVE")
    yield endpoint, keys
    server.terminate()
    server.wait(timeout=30)


def records(run: Path) -> list[dict[str, object]]:
    lines = (run / "episodes.jsonl").read_text().splitlines()
    return sorted((json.loads(line) for line in lines), key=lambda r: str(r["episode_id"]))


def test_keys_are_written_with_private_secrets(tmp_path: Path) -> None:
    result = run_cli("robot", "keys", str(tmp_path / "k"))
    assert result.returncode == 0, result.stderr
    names = {p.relative_to(tmp_path / "k").as_posix() for p in (tmp_path / "k").rglob("*") if p.is_file()}
    assert names == {"server.key", "server.key_secret", "client.key", "client.key_secret", "authorized/client.key"}
    for secret in ("server.key_secret", "client.key_secret"):
        assert stat.S_IMODE((tmp_path / "k" / secret).stat().st_mode) == 0o600
    again = run_cli("robot", "keys", str(tmp_path / "k"))
    assert again.returncode == 2 and "remove old keys on purpose" in again.stderr


def test_eval_through_serve_sim_with_curve_matches_the_embedded_world(
    tmp_path: Path, episodes_file: Path, serve_sim: tuple[str, Path]
) -> None:
    endpoint, keys = serve_sim
    common = ["--agent", "drive-nav", "--episodes", str(episodes_file), "--max-steps", "60"]
    direct = run_cli("eval", *common, "--scenes", SCENES, "--seed", "5", "--out", str(tmp_path / "direct"))
    assert direct.returncode == 0, direct.stderr
    robot = ["--env", "robot", "--robot", endpoint, "--robot-keys", str(keys), "--seed", "5"]
    through = run_cli("eval", *common, *robot, "--out", str(tmp_path / "robot"))
    assert through.returncode == 0, through.stderr
    want, got = records(tmp_path / "direct"), records(tmp_path / "robot")
    assert [{k: r[k] for k in SAME} for r in got] == [{k: r[k] for k in SAME} for r in want]
    run = json.loads((tmp_path / "robot" / "run.json").read_text())
    assert run["config"]["env"] == {
        "name": "robot",
        "address": endpoint,
        "keys": str(keys.resolve()),
        "ground_truth": ["semantic"],
        "timeout_s": 10.0,
        "retries": 3,
    }


def test_a_live_run_prints_progress_and_writes_its_trace_and_picture(
    tmp_path: Path, serve_sim: tuple[str, Path]
) -> None:
    endpoint, keys = serve_sim
    out = tmp_path / "live"
    robot = ["--robot", endpoint, "--robot-keys", str(keys), "--episode-id", "0", "--max-steps", "30"]
    result = run_cli("run", *robot, "--target", "side table", "--out", str(out))
    assert result.returncode == 0, result.stderr
    progress = [line for line in result.stderr.splitlines() if line.startswith("step ")]
    assert progress and progress[0].startswith("step    1 | TURN_")
    (record,) = records(out)
    assert record["episode_id"] == "0" and record["steps"] == len(progress) and record["error"] == ""
    assert record["success"] in (0, 1)  # serve-sim knows the episode and measures it
    assert (out / "viz" / "0_topdown.png").is_file()
    drawn = run_cli("viz", str(out), "0", "--out", str(tmp_path / "drawn"))  # the live run's own directory
    assert drawn.returncode == 0 and (tmp_path / "drawn" / "0_topdown.png").is_file(), drawn.stderr
    (out / "episodes.json.gz").unlink()
    gone = run_cli("viz", str(out), "0")
    assert gone.returncode == 2 and "RUN_DIR" in gone.stderr and "--episodes" not in gone.stderr


def test_robot_options_are_checked_before_any_work(tmp_path: Path, episodes_file: Path) -> None:
    base = ["eval", "--agent", "drive-nav", "--episodes", str(episodes_file), "--out", str(tmp_path / "r")]
    missing = run_cli(*base, "--env", "robot")
    assert missing.returncode == 2 and "--robot" in missing.stderr
    workers = run_cli(*base, "--env", "robot", "--robot", free_endpoint(), "--workers", "2")
    assert workers.returncode == 2 and "--workers" in workers.stderr
    keys = run_cli(*base, "--env", "robot", "--robot", free_endpoint(), "--robot-keys", str(tmp_path / "none"))
    assert keys.returncode == 2 and "client.key_secret" in keys.stderr


def test_a_live_run_the_robot_refuses_is_recorded_and_said_in_one_line(
    tmp_path: Path, serve_sim: tuple[str, Path]
) -> None:
    endpoint, keys = serve_sim
    robot = ["--robot", endpoint, "--robot-keys", str(keys), "--max-steps", "5", "--out", str(tmp_path / "live")]
    result = run_cli("run", *robot, "--episode-id", "nope", "--target", "chair")
    assert result.returncode == 1 and "Traceback" not in result.stderr, result.stderr
    assert "an episode this robot knows" in result.stdout and "picture: none" in result.stdout
    (record,) = records(tmp_path / "live")
    assert record["stop_reason"] == "error"
    empty = run_cli("run", *robot, "--target", " ")
    assert empty.returncode == 2 and "--target" in empty.stderr


def test_habitat_options_on_another_world_are_refused(tmp_path: Path, episodes_file: Path) -> None:
    base = ["eval", "--agent", "random", "--episodes", "1", "--out", str(tmp_path / "r")]
    for extra, option in ((["--split", "val"], "--split"), (["--data-dir", str(tmp_path)], "--data-dir")):
        result = run_cli(*base, *extra)
        assert result.returncode == 2 and option in result.stderr and "--env habitat" in result.stderr
    named = run_cli(*base, "--env", "habitat", "--config", "hm3d-v9")
    assert named.returncode == 2 and "got 'hm3d-v9'" in named.stderr


def test_serve_sim_stopped_by_sigterm_says_it_stopped_serving(episodes_file: Path) -> None:
    command = [sys.executable, "-m", "drivenav.cli", "robot", "serve-sim", "--scenes", SCENES, "--seed", "5"]
    command += ["--episodes", str(episodes_file), "--bind", free_endpoint()]
    server = subprocess.Popen(command, cwd=REPO, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
    assert server.stdout is not None and server.stdout.readline().startswith("serving on")
    server.terminate()
    _, err = server.communicate(timeout=30)
    assert err.strip().splitlines()[-1] == "drivenav: interrupted (stopped serving (the robot is halted))"
