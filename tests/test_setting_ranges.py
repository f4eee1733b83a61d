"""Settings checked where they are declared: every numeric setting has a finite range that its dataclass checks, so
``config show``, a run and a config built in Python refuse the same values with one line naming the dotted key and
the range -- never a ValueError's traceback, never a value that passes and then makes every episode an error."""

from __future__ import annotations

import dataclasses
import math
from collections.abc import Iterator
from pathlib import Path
from typing import Any

import pytest

from drivenav.agent.explorers import EXPLORERS
from drivenav.cli import main
from drivenav.errors import InputError
from drivenav.mapping.value_map import ValueMapConfig
from drivenav.ranges import MAX_FRAME_SIDE, Range, SettingError
from drivenav.settings import load_settings, settings_from_dict, settings_to_dict
from drivenav.types import SimConfig


def _numeric_leaves(value: object, prefix: str = "") -> Iterator[tuple[str, float]]:
    for item in dataclasses.fields(value):  # type: ignore[arg-type]
        child = getattr(value, item.name)
        if dataclasses.is_dataclass(child):
            yield from _numeric_leaves(child, f"{prefix}{item.name}.")
        elif isinstance(child, int | float) and not isinstance(child, bool):
            yield f"{prefix}{item.name}", child


def _chosen(key: str) -> list[str]:
    """The override that chooses the explorer whose section holds ``key`` (none for the other sections): a section
    is in the tree only while its explorer is chosen."""
    section, _, rest = key.partition(".")
    return [f"explorer.name={rest.partition('.')[0]}"] if section == "explorer" else []


NUMERIC = {
    key: value
    for name in EXPLORERS.built_ins
    for key, value in _numeric_leaves(load_settings(overrides=[f"explorer.name={name}"]))
}
UNBOUNDED = {"run.seed": "any integer >= 0 seeds numpy's generators"}


def test_the_tree_has_the_numbers_this_file_walks() -> None:
    assert len(NUMERIC) > 50 and {"sim.width", "explorer.vlfm.min_confidence", "mapping.pixel_stride"} <= set(NUMERIC)


@pytest.mark.parametrize("key", sorted(NUMERIC))
def test_every_numeric_setting_refuses_nan_and_a_value_past_its_range(key: str) -> None:
    """Past the range: 1e308 for a float (1e308 passed as a decision threshold), 10^23 for an integer (a frame
    width of 10^23 passed and made every episode an error)."""
    huge = "100000000000000000000000" if isinstance(NUMERIC[key], int) else "1e308"
    for value in ("nan", "-1", huge) if key not in UNBOUNDED else ("nan", "-1"):
        with pytest.raises(InputError) as caught:
            load_settings(overrides=[*_chosen(key), f"{key}={value}"])
        message = str(caught.value)
        assert "\n" not in message and f"field '{key}'" in message, message


@pytest.mark.parametrize("key", sorted(NUMERIC))
def test_every_default_lies_within_its_range(key: str) -> None:
    """Setting each default again is accepted: the ranges hold the paper's and the project's values."""
    value = NUMERIC[key]
    assert load_settings(overrides=[*_chosen(key), f"{key}={value!r}"]) == load_settings(overrides=_chosen(key))


@pytest.mark.parametrize(
    ("setting", "words"),
    [
        ("explorer.vlfm.min_confidence=1.5", ("[0, 1)", "1.5")),
        ("explorer.vlfm.frontier_radius=-1", ("[0, 1000]", "-1.0")),
        ("explorer.vlfm.frontier_radius=nan", ("[0, 1000]", "nan")),
        ("explorer.vlfm.frontier_radius=1e9", ("[0, 1000]", "1000000000.0")),
        ("explorer.vlfm.decision_threshold=1e308", ("[0, 1]", "1e+308")),
        ("sim.width=100000000000000000000000", ("an integer in [1, 8192]",)),
        ("mapping.pixel_stride=100000000000000000000000", ("an integer in [1, 8192]",)),
        ("agent.planner.lookahead=0", ("(0, 1000]",)),
    ],
)
def test_config_show_and_a_run_refuse_the_same_values(
    tmp_path: Path, capsys: pytest.CaptureFixture[str], setting: str, words: tuple[str, ...]
) -> None:
    """Each was a ValueError's traceback (even from ``config show``), or passed and made every episode an error
    with exit 0."""
    key = setting.partition("=")[0]
    out = tmp_path / "run"
    lines = []
    for args in (
        ["config", "show", "--agent", "vlfm", "--set", setting],
        ["eval", "--agent", "vlfm", "--scenes", "procedural:1", "--episodes", "1", "--set", setting, "--out", str(out)],
    ):
        assert main(args) == 2
        err = capsys.readouterr().err.strip()
        assert len(err.splitlines()) == 1 and "Traceback" not in err, err
        assert f"field '{key}'" in err and all(word in err for word in words), err
        lines.append(err)
    assert lines[0] == lines[1]
    assert not (out / "episodes.jsonl").exists()


@pytest.mark.parametrize(
    ("overrides", "key", "words"),
    [
        (
            ["explorer.name=vlfm", "explorer.vlfm.frontier_radius=6"],
            "explorer.vlfm.frontier_radius",
            "at most sim.max_depth (5 m)",
        ),
        (["sim.max_depth=150"], "sim.max_depth", "at most half of mapping.max_size (100 m)"),
        (["sim.grid_resolution=0.001"], "mapping.max_size", "at most 16384 cells of sim.grid_resolution"),
        (["mapping.initial_size=300"], "mapping.max_size", "at least initial_size"),
        (["sim.min_depth=5"], "sim.min_depth", "less than max_depth (5 m)"),
    ],
)
def test_rules_between_settings_name_the_key_they_refuse(overrides: list[str], key: str, words: str) -> None:
    with pytest.raises(InputError) as caught:
        load_settings(overrides=overrides)
    assert caught.value.field == key and words in caught.value.expected, caught.value


def test_a_config_built_in_python_is_checked_as_the_command_line_checks_it() -> None:
    with pytest.raises(SettingError, match=r"ValueMapConfig\.min_confidence: expected a finite number in \[0, 1\)"):
        ValueMapConfig(min_confidence=1.5)
    with pytest.raises(SettingError, match=rf"SimConfig\.width: expected an integer in \[1, {MAX_FRAME_SIDE}\]"):
        SimConfig(width=0)
    with pytest.raises(ValueError):  # a SettingError is a ValueError, as the configs raised before
        SimConfig(hfov_deg=math.nan)


def test_a_run_json_with_a_value_out_of_range_is_refused_on_resume() -> None:
    tree: dict[str, Any] = settings_to_dict(load_settings("vlfm"))
    tree["explorer"]["vlfm"]["decision_threshold"] = 2.0
    with pytest.raises(InputError, match=r"'explorer\.vlfm\.decision_threshold'"):
        settings_from_dict(tree)


@pytest.mark.parametrize(
    ("bounds", "inside", "outside", "text"),
    [
        (Range(0.0, 1.0, high_open=True), [0.0, 0.5], [1.0, -0.1, math.nan, math.inf, True, "1"], "in [0, 1)"),
        (Range(1, 8192, integer=True), [1, 8192], [0, 8193, 2.0, 10**400], "an integer in [1, 8192]"),
        (Range(0.0, low_open=True), [1e-300, 1e308], [0.0, math.inf, -math.inf], "a finite number > 0"),
    ],
)
def test_a_range_holds_its_numbers_and_says_which(
    bounds: Range, inside: list[object], outside: list[object], text: str
) -> None:
    assert all(bounds.holds(value) for value in inside)
    assert not any(bounds.holds(value) for value in outside)
    assert text in bounds.text


# ------------------------------------------------------------------------------------------------ config files


def _config(tmp_path: Path, text: str) -> str:
    path = tmp_path / "settings.yaml"
    path.write_text(text)
    return str(path)


def test_a_dotted_key_in_a_config_file_is_named_with_the_nesting_it_needs(tmp_path: Path) -> None:
    """``sim.width: 320`` at the top of a file was reported as "expected an int like 640, got 'null'"."""
    with pytest.raises(InputError) as caught:
        load_settings(configs=[_config(tmp_path, "sim.width: 320\n")])
    assert caught.value.field == "sim.width"
    assert "'sim:' and under it '  width: ...'" in caught.value.expected and "null" not in str(caught.value)


@pytest.mark.parametrize(
    ("text", "key", "line"),
    [
        ("sim:\n  width: 320\n  width: 640\n", "sim.width", 3),
        ("sim:\n  width: 320\nsim:\n  height: 240\n", "sim", 3),
        ("explorer:\n  vlfm:\n    keep_radius: 0.4\n    keep_radius: 0.6\n", "explorer.vlfm.keep_radius", 4),
    ],
)
def test_a_key_given_twice_in_a_config_file_is_refused_naming_it(
    tmp_path: Path, text: str, key: str, line: int
) -> None:
    with pytest.raises(InputError) as caught:
        load_settings(configs=[_config(tmp_path, text)])
    assert caught.value.field == key and caught.value.got == f"the key again at line {line}", caught.value
