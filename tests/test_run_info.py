"""``run.json`` as a typed :class:`RunInfo`: the file keeps its format, reading it rebuilds the settings, and a
hand-edited value is one :class:`InputError` naming ``config.KEY``.

``tests/data/run.json`` is the ``run.json`` of a ``bench ablations`` run (drive-nav, seed 3, geometric reasoner), in
today's tree (rewritten when the body's ``agent.fusion`` and ``agent.stop_in_view``, ApexNav's section, the body's
``agent.floors`` and ``models.detector_regime`` came, and when ``explorer`` came to hold the chosen explorer's section
only; ``tests/data/run-all-explorers.json`` is the same run's from before, with every installed explorer's section,
a plug-in's ``pocket`` among them); ``tests/data/run-before-explorers.json`` is the same run's as
written before explorers had settings sections of their own (and before ``RunInfo.config`` was typed).
"""

from __future__ import annotations

import json
from collections.abc import Callable
from pathlib import Path

import pytest

from drivenav.envs.embedded.env import EmbeddedSpec
from drivenav.errors import InputError
from drivenav.eval.run_info import RunInfo, world_json
from drivenav.jsonstream import JsonObject
from drivenav.settings import load_settings

RUN_JSON = Path(__file__).parent / "data" / "run.json"
BEFORE_EXPLORERS = Path(__file__).parent / "data" / "run-before-explorers.json"


def _written() -> JsonObject:
    data: JsonObject = json.loads(RUN_JSON.read_text(encoding="utf-8"))
    return data


def test_a_run_json_written_before_reads_back_to_the_same_file() -> None:
    info = RunInfo.from_json(_written(), RUN_JSON)
    assert info.config.run.agent == "drive-nav" and info.config.run.seed == 3
    assert info.config.models.reasoner == "geometric" and info.config.sim.max_steps == 400
    assert info.world == {"name": "embedded", "scenes": "procedural:3", "seed": 3}
    # written as rundir writes it (sorted keys, two-space indent)
    assert json.dumps(info.to_json(), indent=2, sort_keys=True) + "\n" == RUN_JSON.read_text(encoding="utf-8")


def test_a_run_json_from_before_explorers_reads_as_the_same_settings() -> None:
    """An older drivenav's run directory still reads (report, viz); a resume into it is refused, since its tree
    is written otherwise."""
    older = json.loads(BEFORE_EXPLORERS.read_text(encoding="utf-8"))
    info = RunInfo.from_json(older, BEFORE_EXPLORERS)
    assert info.config == RunInfo.from_json(_written(), RUN_JSON).config
    assert "use_reasoner" in older["config"]["agent"] and info.config.explorer.name == "directions"
    with pytest.raises(InputError, match=r"config\.agent"):
        info.check_resume(older, BEFORE_EXPLORERS)


def test_the_settings_read_back_are_those_the_run_was_started_with() -> None:
    options = {"run.seed": 3, "sim.max_steps": 400, "models.reasoner": "geometric", "models.detector": "ground-truth"}
    settings = load_settings("drive-nav", options=options)
    assert RunInfo.from_json(_written(), RUN_JSON).config == settings
    info = RunInfo(settings, world_json(EmbeddedSpec("procedural:3", 3)), "x", "v", None, None)
    assert info.config_json() == _written()["config"]


@pytest.mark.parametrize(
    ("edit", "field"),
    [
        (lambda d: d["config"]["paper"]["speed"].update(lam="abc"), "config.paper.speed.lam"),
        (lambda d: d["config"]["sim"].update(max_steps=-1), "config.sim.max_steps"),
        (lambda d: d["config"]["sim"].update(nope=1), "config.sim.nope"),
        (lambda d: d["config"].pop("env"), "config.env"),
        (lambda d: d.pop("episodes_sha256"), "episodes_sha256"),
        (lambda d: d.update(git_dirty="yes"), "git_dirty"),
    ],
)
def test_a_hand_edited_run_json_is_one_input_error_naming_the_key(
    edit: Callable[[JsonObject], object], field: str
) -> None:
    data = _written()
    edit(data)
    with pytest.raises(InputError) as caught:
        RunInfo.from_json(data, RUN_JSON)
    assert caught.value.field == field and len(str(caught.value).splitlines()) == 1


def test_resume_compares_the_trees_as_written() -> None:
    """A key the previous run.json lacks (another drivenav version) refuses the resume unless it holds its default
    now: a setting added since, at its default, keeps the behaviour its absence had, and a long run resumes."""
    info = RunInfo.from_json(_written(), RUN_JSON)
    info.check_resume(_written(), RUN_JSON)
    older = _written()
    del older["config"]["models"]["max_detections"]
    info.check_resume(older, RUN_JSON)  # added since, at its default
    changed = _written()
    changed["config"]["agent"]["enrich"] = False
    del older["config"]["agent"]["enrich"]
    with pytest.raises(InputError, match=r"config\.agent\.enrich"):
        RunInfo.from_json(changed, RUN_JSON).check_resume(older, RUN_JSON)
    older["config"]["models"]["unknown_since"] = 1
    with pytest.raises(InputError, match=r"config\.models\.unknown_since|config\.models"):
        info.check_resume(older, RUN_JSON)
