"""Large episode files are read as a stream: the same episodes as reading the whole document, a goals text that
episodes repeat read once, a few KB per episode, and syntax errors placed at the file's own line and column."""

from __future__ import annotations

import gzip
import hashlib
import json
from pathlib import Path
from typing import Any

import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from drivenav import jsonstream
from drivenav.benchmarks.episodes_bench import traced_read, write_repeated
from drivenav.benchmarks.generate import generate_episodes
from drivenav.envs.embedded.library import SceneLibrary
from drivenav.episode import parse_episode
from drivenav.errors import InputError
from drivenav.eval.episodes import episode_to_dict, load_episodes, save_episodes
from drivenav.eval.rundir import episodes_sha256
from drivenav.validation import Fields

EPISODES = [episode_to_dict(e) for e in generate_episodes(SceneLibrary("procedural:2", 0), 12, 3)]


def _write(path: Path, text: str, compress: bool = True) -> Path:
    path.write_bytes(gzip.compress(text.encode()) if compress else text.encode())
    return path


def _whole_document_reading(text: str, path: Path) -> list[Any]:
    """The oracle: every episode parsed from ``json.loads`` of the whole text."""
    items = json.loads(text)["episodes"]
    return [parse_episode(Fields(path), f"episodes[{i}]", item) for i, item in enumerate(items)]


@settings(max_examples=25, deadline=None, suppress_health_check=[HealthCheck.function_scoped_fixture])
@given(
    indent=st.sampled_from([None, 0, 2]),
    sort_keys=st.booleans(),
    chunk=st.sampled_from([7, 64, 1000, 1 << 20]),
    extra_first=st.booleans(),
    order=st.permutations(range(len(EPISODES))),
)
def test_a_streamed_file_reads_as_the_whole_document_does(
    tmp_path: Path,
    monkeypatch: pytest.MonkeyPatch,
    indent: int | None,
    sort_keys: bool,
    chunk: int,
    extra_first: bool,
    order: list[int],
) -> None:
    monkeypatch.setattr(jsonstream, "CHUNK_BYTES", chunk)  # windows far smaller than one episode, and whole files
    episodes = [EPISODES[i] for i in order]
    document = {"note": {"made by": "a test"}, "episodes": episodes} if extra_first else {"episodes": episodes}
    text = json.dumps(document, indent=indent, sort_keys=sort_keys)
    path = _write(tmp_path / "eps.json.gz", text)
    assert load_episodes(path) == _whole_document_reading(text, path)


def test_a_repeated_goals_text_is_read_once_and_shared(tmp_path: Path) -> None:
    repeats = [{**EPISODES[0], "episode_id": f"copy-{k}"} for k in range(50)]
    path = _write(tmp_path / "eps.json.gz", json.dumps({"episodes": repeats}))
    loaded = load_episodes(path)
    assert all(episode.goals is loaded[0].goals for episode in loaded)
    assert loaded[7] == _whole_document_reading(json.dumps({"episodes": repeats}), path)[7]


def test_a_large_file_holds_a_few_kilobytes_per_episode(tmp_path: Path) -> None:
    count = 4000  # read whole, such a file held about 80 KB per episode (5.5 GB for 100,000)
    path = tmp_path / "large.json.gz"
    write_repeated(path, count, distinct=12)
    held, peak = traced_read(path)
    assert held <= peak < 5_000 * count, f"{peak / count:.0f} bytes per episode at the peak"


@pytest.mark.parametrize("chunk", [16, 1 << 20])
@pytest.mark.parametrize(
    "damage",
    [
        lambda text: text.replace('"scene_id":', '"scene_id"', 7),  # a missing colon, late in the file
        lambda text: text[: len(text) // 2],  # cut short
        lambda text: text.replace("]", "],", 1),  # a trailing comma inside the goals
        lambda text: text + " {}",  # extra data after the document
    ],
)
def test_a_syntax_error_names_the_files_own_line_and_column(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch, chunk: int, damage: Any
) -> None:
    monkeypatch.setattr(jsonstream, "CHUNK_BYTES", chunk)
    text = damage(json.dumps({"episodes": EPISODES}, indent=1))
    with pytest.raises(json.JSONDecodeError) as expected:
        json.loads(text)
    path = _write(tmp_path / "bad.json", text, compress=False)
    with pytest.raises(InputError, match="valid JSON") as error:
        load_episodes(path)
    assert f"at line {expected.value.lineno}, column {expected.value.colno}" in str(error.value)


def _largest_window(monkeypatch: pytest.MonkeyPatch) -> list[int]:
    """The longest text the reader's window held, after each read (a spy on :meth:`jsonstream._Window.more`)."""
    sizes = [0]
    more = jsonstream._Window.more

    def spied(window: jsonstream._Window) -> bool:
        found = more(window)
        sizes[0] = max(sizes[0], len(window.text))
        return found

    monkeypatch.setattr(jsonstream._Window, "more", spied)
    return sizes


@pytest.mark.parametrize("where", ["between episodes", "before the array", "after the document"])
def test_whitespace_is_read_through_a_window_of_a_chunk_or_two(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch, where: str
) -> None:
    """Reading time grew with the square of the whitespace between episodes (256 MiB: 22 s) because the window
    kept every space read; it now holds about one chunk, so time grows with the text (no clock in the test)."""
    monkeypatch.setattr(jsonstream, "CHUNK_BYTES", 1024)
    largest = _largest_window(monkeypatch)
    spaces = " \n\t\r" * (1 << 18)  # 1 MiB: a thousand chunks
    first, second = (json.dumps(e) for e in EPISODES[:2])
    text = {
        "between episodes": f'{{"episodes": [{first},{spaces}{second}]}}',
        "before the array": f'{{"episodes":{spaces}[{first}, {second}]}}',
        "after the document": f'{{"episodes": [{first}, {second}]}}{spaces}',
    }[where]
    path = _write(tmp_path / "eps.json.gz", text)
    assert load_episodes(path) == _whole_document_reading(text, path)
    assert largest[0] < 4 * (1024 + max(len(first), len(second))), largest[0]  # an episode read twice over


def test_a_syntax_error_after_long_whitespace_names_its_line_and_column(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    monkeypatch.setattr(jsonstream, "CHUNK_BYTES", 16)
    text = '{"episodes": [' + json.dumps(EPISODES[0]) + ",  \n " * 500 + "  \n   x]}"
    with pytest.raises(json.JSONDecodeError) as expected:
        json.loads(text)
    with pytest.raises(InputError, match="valid JSON") as error:
        load_episodes(_write(tmp_path / "bad.json", text, compress=False))
    assert f"at line {expected.value.lineno}, column {expected.value.colno}" in str(error.value)


def test_a_whitespace_bomb_is_refused_at_the_limit_holding_a_chunk(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    """A 10 MB gzip of 10 GiB of spaces took 541 s to refuse; the refusal now comes at the limit having held about
    one chunk of text."""
    monkeypatch.setattr(jsonstream, "MAX_DOCUMENT_BYTES", 1 << 20)
    monkeypatch.setattr(jsonstream, "CHUNK_BYTES", 1024)
    largest = _largest_window(monkeypatch)
    path = _write(tmp_path / "bomb.json.gz", '{"episodes": [' + json.dumps(EPISODES[0]) + "," + " " * (4 << 20) + "]}")
    with pytest.raises(InputError, match="at most 1 MiB of JSON"):
        load_episodes(path)
    assert largest[0] < 4 * (1024 + len(json.dumps(EPISODES[0]))), largest[0]


def test_a_habitat_content_file_is_named_whatever_its_key_order(tmp_path: Path) -> None:
    episode = {k: v for k, v in EPISODES[0].items() if k != "goals"}
    text = json.dumps({"episodes": [episode], "goals_by_category": {"scene.basis.glb_chair": []}})
    with pytest.raises(InputError, match="goals_by_category"):
        load_episodes(_write(tmp_path / "content.json.gz", text))


def test_two_episode_lists_in_one_file_are_refused(tmp_path: Path) -> None:
    text = '{"episodes": ' + json.dumps(EPISODES[:1]) + ', "episodes": ' + json.dumps(EPISODES[1:2]) + "}"
    with pytest.raises(InputError, match="one 'episodes' key"):
        load_episodes(_write(tmp_path / "twice.json.gz", text))


def test_a_document_that_is_no_object_is_named(tmp_path: Path) -> None:
    with pytest.raises(InputError, match="a JSON object"):
        load_episodes(_write(tmp_path / "list.json.gz", json.dumps(EPISODES)))


def test_the_written_file_and_digest_are_those_of_the_plain_json_form(tmp_path: Path) -> None:
    """The goals' text made once per goal changes neither the bytes of a saved file nor a run's episodes digest
    (run.json of earlier runs still resumes)."""
    episodes = load_episodes(_write(tmp_path / "eps.json.gz", json.dumps({"episodes": EPISODES})))
    save_episodes(episodes, tmp_path / "saved.json.gz")
    plain = json.dumps({"episodes": [episode_to_dict(e) for e in episodes]}, separators=(",", ":")).encode()
    with (
        (tmp_path / "plain.json.gz").open("wb") as raw,
        gzip.GzipFile(filename="", mode="wb", fileobj=raw, mtime=0) as gz,
    ):
        gz.write(plain)
    assert (tmp_path / "saved.json.gz").read_bytes() == (tmp_path / "plain.json.gz").read_bytes()
    sorted_text = json.dumps([episode_to_dict(e) for e in episodes], sort_keys=True, separators=(",", ":"))
    assert episodes_sha256(episodes) == hashlib.sha256(sorted_text.encode()).hexdigest()


def test_bench_episodes_reports_the_costs_before_the_first_episode(capsys: pytest.CaptureFixture[str]) -> None:
    from drivenav.cli import main

    assert main(["bench", "episodes", "--num", "250", "--json"]) == 0
    result = json.loads(capsys.readouterr().out)
    assert result["episodes"] == 250
    keys = ("read_s", "check_s", "digest_s", "copy_s", "held_bytes_per_episode", "peak_bytes_per_episode")
    assert all(result[key] >= 0 for key in keys)
