"""Hostile input on the command line: each answer is one line naming what and where, exit 2, no traceback, and
no unbounded work (huge counts, gzip bombs, deep nesting, empty or impossible output paths)."""

from __future__ import annotations

import gzip
import json
import os
import signal
import subprocess
import sys
from collections.abc import Iterator
from pathlib import Path

import pytest

from drivenav import jsonstream
from drivenav.benchmarks import world_stats
from drivenav.cli import main
from drivenav.errors import InputError
from drivenav.eval import episodes as eval_episodes
from drivenav.eval.episodes import load_episodes


def _one_line_exit_2(capsys: pytest.CaptureFixture[str], args: list[str], *words: str) -> str:
    try:
        status = main(args)
    except SystemExit as exit_:  # argparse's own refusals exit from inside main
        status = int(exit_.code or 0)
    assert status == 2
    err = capsys.readouterr().err.strip()
    assert "Traceback" not in err, err
    message = err.splitlines()[-1]  # argparse's refusals come after its usage lines
    assert message.startswith("drivenav") and "error:" in message, err
    for word in words:
        assert word in message, err
    return message


def test_a_gzip_bomb_is_refused_before_it_is_unpacked(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.setattr(jsonstream, "MAX_DOCUMENT_BYTES", 1 << 20)
    bomb = tmp_path / "bomb.json.gz"
    bomb.write_bytes(gzip.compress(b'{"episodes": [' + b" " * (4 << 20) + b"]}"))
    with pytest.raises(InputError, match="at most 1 MiB of JSON"):
        load_episodes(bomb)


def test_an_episodes_file_nested_30000_deep_is_one_line(tmp_path: Path) -> None:
    deep = tmp_path / "deep.json"
    deep.write_text('{"episodes": ' + "[" * 30_000 + "]" * 30_000 + "}")
    with pytest.raises(InputError, match="nested"):
        load_episodes(deep)


def test_a_config_that_is_not_utf8_is_one_line(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    config = tmp_path / "bad.yaml"
    config.write_bytes(b"\xff\xfe run:\n")
    _one_line_exit_2(capsys, ["config", "show", "--config", str(config)], "UTF-8")


@pytest.mark.parametrize(
    ("args", "word"),
    [
        (["--num", "1000000000000"], "--num"),
        (["--num", "1", "--seed", "-1"], "--seed"),
    ],
)
def test_episode_generation_refuses_unbounded_or_negative_values_at_once(
    tmp_path: Path, capsys: pytest.CaptureFixture[str], args: list[str], word: str
) -> None:
    _one_line_exit_2(capsys, ["episodes", "generate", *args, "--out", str(tmp_path / "e.json.gz")], word)


def test_an_empty_output_path_is_refused(capsys: pytest.CaptureFixture[str], tmp_path: Path) -> None:
    _one_line_exit_2(capsys, ["episodes", "generate", "--num", "1", "--out", ""], "empty")
    _one_line_exit_2(capsys, ["robot", "keys", ""], "empty")


def _paths(tmp_path: Path) -> dict[str, str]:
    folder = tmp_path / "a-folder"
    folder.mkdir()
    file = tmp_path / "a-file"
    file.write_text("x")
    return {
        "a folder": str(folder),
        "under a file": str(file / "inside.json.gz"),
        "too long": str(tmp_path / ("n" * 300)),
        "under /proc": "/proc/drivenav-cannot/e.json.gz",
    }


@pytest.mark.parametrize("kind", ["a folder", "under a file", "too long", "under /proc"])
def test_an_episodes_file_that_cannot_be_written_is_one_line(
    tmp_path: Path, capsys: pytest.CaptureFixture[str], kind: str
) -> None:
    out = _paths(tmp_path)[kind]
    for args in (["episodes", "generate", "--num", "1"], ["benchmark", "generate", "--episodes", "1"]):
        message = _one_line_exit_2(capsys, [*args, "--out", out])
        named = [str(path)[:100] for path in (Path(out), *Path(out).parents)]  # the path asked for, or its folder
        assert any(name in message for name in named) and ".partial" not in message
    assert not list(tmp_path.rglob("*.partial"))


@pytest.mark.parametrize("kind", ["under a file", "too long", "under /proc"])
def test_an_output_folder_that_cannot_be_made_is_one_line(
    tmp_path: Path, capsys: pytest.CaptureFixture[str], kind: str
) -> None:
    out = _paths(tmp_path)[kind]
    _one_line_exit_2(capsys, ["robot", "keys", out])
    episodes = tmp_path / "e.json.gz"
    assert main(["episodes", "generate", "--num", "1", "--out", str(episodes)]) == 0
    _one_line_exit_2(capsys, ["episodes", "export", "--episodes", str(episodes), "--format", "ovon", "--out", out])


@pytest.mark.parametrize(
    ("setting", "word"),
    [
        ("mapping.max_size=10", "mapping.max_size"),
        ("paper.directions.cluster_span_deg=1000", "cluster_span_deg"),
        ("paper.directions.association_gate_deg=270", "association_gate_deg"),
    ],
)
def test_settings_that_contradict_each_other_are_refused(
    capsys: pytest.CaptureFixture[str], setting: str, word: str
) -> None:
    _one_line_exit_2(capsys, ["config", "show", "--set", setting], word)


def test_compare_refuses_nan_distances_and_runs_sharing_no_episode(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    for name, seed in (("a", "1"), ("b", "2")):
        args = ["eval", "--agent", "random", "--scenes", "procedural:1", "--episodes", "1", "--seed", seed]
        assert main([*args, "--max-steps", "5", "--out", str(tmp_path / name)]) == 0
    runs = [str(tmp_path / "a"), str(tmp_path / "b")]
    _one_line_exit_2(capsys, ["compare", *runs[:1], "--min-distance", "nan"], "--min-distance")
    assert main(["compare", runs[0], runs[0]]) == 0
    capsys.readouterr()
    _one_line_exit_2(capsys, ["compare", *runs], "share none")  # both have an episode "0", in other scenes


@pytest.mark.parametrize(
    ("change", "field"),
    [
        ({"start_rotation": [0.0, 0.0, 0.0, 0.0]}, "start_rotation"),
        ({"start_position": "lift"}, "start_position"),
    ],
)
def test_an_episode_with_an_impossible_start_is_refused(
    tmp_path: Path, capsys: pytest.CaptureFixture[str], change: dict[str, object], field: str
) -> None:
    source = tmp_path / "e.json.gz"
    assert main(["episodes", "generate", "--scenes", "procedural:1", "--num", "1", "--out", str(source)]) == 0
    data = json.loads(gzip.decompress(source.read_bytes()))
    episode = data["episodes"][0]
    if change.get("start_position") == "lift":
        episode["start_position"][1] = 1000.0  # 1000 m above the floor
    else:
        episode.update(change)
    edited = tmp_path / "edited.json"
    edited.write_text(json.dumps(data))
    args = ["eval", "--agent", "random", "--scenes", "procedural:1", "--episodes", str(edited)]
    _one_line_exit_2(capsys, [*args, "--out", str(tmp_path / "run")], f"episodes[0].{field}")


def test_a_negative_size_names_the_bound_that_holds(capsys: pytest.CaptureFixture[str]) -> None:
    message = _one_line_exit_2(capsys, ["config", "show", "--set", "sim.width=-5"], "sim.width")
    assert "an integer in [1, 8192]" in message  # 0 is refused too


@pytest.mark.parametrize("kind", ["garbage metadata", "no metadata", "a file"])
def test_a_bag_rosbags_cannot_read_is_one_line(tmp_path: Path, capsys: pytest.CaptureFixture[str], kind: str) -> None:
    bag = tmp_path / "bag"
    if kind == "a file":
        bag.write_text("not a bag")
    else:
        bag.mkdir()
        if kind == "garbage metadata":
            (bag / "metadata.yaml").write_text("x\n")
    args = ["robot", "serve", "--source", "bag", "--bag", str(bag), "--bind", "tcp://127.0.0.1:*"]
    _one_line_exit_2(capsys, args, "--bag")


def test_a_gzip_stream_with_a_broken_header_names_gzip(tmp_path: Path) -> None:
    broken = tmp_path / "broken.json.gz"
    broken.write_bytes(b"\x1f\x8b\x09\x00" + b"not deflate at all")  # gzip magic, an unknown method
    with pytest.raises(InputError, match="gzip-compressed JSON"):
        load_episodes(broken)


def test_output_into_a_closed_pipe_ends_quietly(tmp_path: Path) -> None:
    """``drivenav episodes stats ... --json | head`` ended in a BrokenPipeError's traceback: the reader's leaving
    now ends the command with a shell's SIGPIPE status and nothing on stderr."""
    episodes = tmp_path / "eps.json.gz"
    assert main(["episodes", "generate", "--scenes", "procedural:1", "--num", "1", "--out", str(episodes)]) == 0
    reader, writer = os.pipe()
    os.close(reader)  # the reader has gone before the first byte: every write meets a closed pipe
    try:
        args = ["episodes", "stats", str(episodes), "--scenes", "procedural", "--json"]
        result = subprocess.run(
            [sys.executable, "-m", "drivenav.cli", *args], stdout=writer, stderr=subprocess.PIPE, text=True, check=False
        )
    finally:
        os.close(writer)
    assert result.returncode == 128 + signal.SIGPIPE and result.stderr == "", result.stderr


def test_an_interrupt_promises_a_resume_only_where_one_exists(
    tmp_path: Path, capsys: pytest.CaptureFixture[str], monkeypatch: pytest.MonkeyPatch
) -> None:
    """Ctrl-C of ``episodes generate`` or ``episodes stats`` said "finished episodes are saved; rerun to resume";
    they save nothing (a generated file is written whole or not at all)."""
    episodes = tmp_path / "eps.json.gz"
    assert main(["episodes", "generate", "--scenes", "procedural:1", "--num", "1", "--out", str(episodes)]) == 0
    capsys.readouterr()

    def written_then_interrupted(*args: object, **kwargs: object) -> Iterator[str]:
        yield '{"episode_id": "0"}'
        raise KeyboardInterrupt

    def interrupted(*args: object, **kwargs: object) -> None:
        raise KeyboardInterrupt

    monkeypatch.setattr(eval_episodes, "episode_texts", written_then_interrupted)  # while the file is written
    out = tmp_path / "again" / "eps.json.gz"
    assert main(["episodes", "generate", "--scenes", "procedural:1", "--num", "1", "--out", str(out)]) == 130
    assert capsys.readouterr().err.strip() == "drivenav: interrupted"
    assert list(out.parent.iterdir()) == []  # neither the file nor its partial copy
    monkeypatch.setattr(world_stats, "measure", interrupted)
    assert main(["episodes", "stats", str(episodes), "--scenes", "procedural"]) == 130
    assert capsys.readouterr().err.strip() == "drivenav: interrupted"
