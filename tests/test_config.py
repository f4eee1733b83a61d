"""The configuration tree: the paper's defaults, presets, YAML files, options and --set overrides in order, one-line
errors for wrong keys, types and values, and the methods of the paper's tables as presets."""

from __future__ import annotations

import math
from dataclasses import asdict
from pathlib import Path

import pytest
import yaml

from drivenav.agent.body import ExplorerAgent
from drivenav.agent.config import FusionConfig
from drivenav.agent.oracle import OracleAgent
from drivenav.agents import make_agent
from drivenav.cli import main
from drivenav.errors import InputError
from drivenav.mapping.config import MappingConfig, MapTuning
from drivenav.methods import ALL_METHODS, BEYOND_PAPER, FLOORS_OFF, METHOD_NAMES, METHODS
from drivenav.settings import (
    Settings,
    agent_names,
    explorer_section,
    first_difference,
    load_settings,
    preset_names,
    settings_to_dict,
    settings_to_yaml,
)
from drivenav.types import SimConfig


def test_defaults_are_the_papers_values() -> None:
    s = load_settings()
    assert (s.sim.width, s.sim.height, s.sim.hfov_deg, s.sim.camera_height) == (640, 480, 79.0, 0.88)
    assert (s.sim.min_depth, s.sim.max_depth, s.sim.forward_step, s.sim.turn_angle_deg) == (0.5, 5.0, 0.25, 30.0)
    assert (s.sim.max_steps, s.sim.success_distance) == (500, 0.25)
    speed = s.paper.speed
    assert (speed.lam, speed.r_obs, speed.beta, speed.r_vor, speed.weighted) == (0.65, 0.8, 3.0, 0.5, True)
    assert s.paper.directions.bearing_radius == 0.8
    assert s.paper.directions.cluster_span == pytest.approx(math.pi / 4)  # tau_theta = 45 deg
    assert s.paper.inspection.forward_range == pytest.approx(4 * math.pi / 3)  # 240 deg
    assert (s.paper.semantics.enrich_rounds, s.paper.semantics.verify_frames) == (5, 3)
    assert s == Settings() and s.run.agent == "drive-nav"


def test_the_paper_preset_spells_out_the_defaults() -> None:
    assert "paper" in preset_names()
    assert load_settings(configs=["paper"]) == load_settings()


def test_layers_apply_in_order(tmp_path: Path) -> None:
    mine = tmp_path / "mine.yaml"
    mine.write_text("paper:\n  speed:\n    lam: 0.4\nsim:\n  max_steps: 300\n")
    s = load_settings(
        "no-240", configs=[str(mine), "quick"], overrides=["paper.speed.lam=0.5"], options={"sim.max_steps": 200}
    )
    assert s.paper.speed.lam == 0.5  # --set wins over the file
    assert s.sim.max_steps == 200  # an option wins over the presets and files
    assert s.paper.inspection.restrict_forward is False and s.run.agent == "no-240"
    assert load_settings(configs=[str(mine), "quick"]).sim.max_steps == 150  # later files win
    assert load_settings(overrides=["paper.speed.lam=0.3", "paper.speed.lam=0.2"]).paper.speed.lam == 0.2


@pytest.mark.parametrize(
    ("overrides", "words"),
    [
        (["paper.speed.lamb=0.5"], ["'paper.speed.lamb'", "lam, r_obs, beta, r_vor, weighted", "'lamb'"]),
        (["paper.speed.lam=abc"], ["'paper.speed.lam'", "a float", "'abc'"]),
        (["agent.enrich=maybe"], ["'agent.enrich'", "a bool", "'maybe'"]),
        (["paper.speed.lam=1.5"], ["'paper.speed.lam'", "lambda < 1", "1.5"]),
        (["sim.width=-3"], ["'sim.width'", "an integer in [1, 8192]", "-3"]),
        (["sim.max_steps=0"], ["'sim.max_steps'", "an integer in [1, 100000]"]),
        (["sim.min_depth=6"], ["'sim.min_depth'", "less than max_depth (5 m)"]),
        (["sim=3"], ["'sim'", "a mapping with keys width", "3"]),
        (["run.seed=1.5"], ["'run.seed'", "an int like 0", "1.5"]),
        (["paper.speed.lam=[1"], ["'paper.speed.lam'", "a YAML value", "'[1'"]),
        (["paper.speed.lam=${nowhere}"], ["'paper.speed.lam'", "an interpolation", "'nowhere' not found"]),
        (["run.agent=no-such"], ["'run.agent'", "one of apexnav, apexnav-floors-off, direction-360", "'no-such'"]),
        (["models.reasoner=gpt"], ["'models.reasoner'", "one of embedded, openai", "'gpt'"]),
        (["models.scorer=clip"], ["'models.scorer'", "one of embedded, blip2-itm, siglip", "--scorer", "'clip'"]),
        (["mapping.min_obstacle_height=1.0"], ["'mapping.min_obstacle_height'", "less than sim.agent_height"]),
        (["paper.speed"], ["--set", "KEY=VALUE"]),
    ],
)
def test_a_wrong_key_or_value_is_one_line(overrides: list[str], words: list[str]) -> None:
    with pytest.raises(InputError) as caught:
        load_settings(overrides=overrides)
    message = str(caught.value)
    assert "\n" not in message
    for word in words:
        assert word in message


def test_bad_config_files_and_names(tmp_path: Path) -> None:
    broken = tmp_path / "broken.yaml"
    broken.write_text("paper: [1, 2\n")
    listed = tmp_path / "list.yaml"
    listed.write_text("- 1\n")
    unknown = tmp_path / "unknown.yaml"
    unknown.write_text("papr:\n  x: 1\n")
    flat = tmp_path / "flat.yaml"
    flat.write_text("paper:\n  speed: 3\n")
    for config, words in (
        (str(broken), ["broken.yaml", "a YAML mapping"]),
        (str(listed), ["list.yaml", "a YAML mapping"]),
        (str(unknown), ["unknown.yaml", "'papr'", "sim, mapping, paper, agent, explorer, models, run"]),
        (str(flat), ["flat.yaml", "'paper.speed'", "a mapping with keys lam, r_obs", "got 3"]),
        ("no-such-preset", ["--config", "paper, quick"]),
    ):
        with pytest.raises(InputError) as caught:
            load_settings(configs=[config])
        assert all(word in str(caught.value) for word in words), caught.value
    with pytest.raises(InputError, match="--agent"):
        load_settings("no-such-agent")


# the switches each method of the paper's tables changes, from the defaults (Tables II, V, VI)
EXPECTED = {
    "frontier": {"enrich": False, "verify": False, "decision_scan": True, "cluster_span_deg": 0.0},
    "directional": {"enrich": False, "verify": False},
    "directional-enrich": {"verify": False},
    "directional-verify": {"enrich": False},
    "drive-nav": {},
    "no-weighted-fmm": {"enrich": False, "verify": False, "weighted": False},
    "no-240": {"enrich": False, "verify": False, "restrict_forward": False},
    "direction-360": {"decision_scan": True},
    "nearest-frontier": {"explorer": "greedy", "enrich": False, "verify": False},
    "vlfm": {"explorer": "vlfm", "enrich": False, "verify": False},
    "apexnav": {
        "explorer": "apexnav",
        "enrich": False,
        "verify": False,
        "fusion": {**asdict(FusionConfig()), "enabled": True},
        "stop_in_view": False,
        "stop_distance": 0.7,
        "weighted": False,
    },
}
PLUS_RULES: dict[str, object] = {"skip_void_events": True, "return_aware": True, "settle_steps": 3, "target_check": 0.5}
# beyond the paper: drive-nav with every rule of drive-nav-plus, and its ablation rows each without one
BEYOND = {
    "drive-nav-plus": PLUS_RULES,
    "drive-nav-plus-no-void": {rule: on for rule, on in PLUS_RULES.items() if rule != "skip_void_events"},
    "drive-nav-plus-no-return": {rule: on for rule, on in PLUS_RULES.items() if rule != "return_aware"},
    "drive-nav-plus-no-check": {rule: on for rule, on in PLUS_RULES.items() if rule != "target_check"},
    "drive-nav-plus-no-settle": {rule: on for rule, on in PLUS_RULES.items() if rule != "settle_steps"},
}
FLOORS_OFF_SWITCH = {"floors": {**settings_to_dict(Settings())["agent"]["floors"], "enabled": False}}
BEYOND.update({f"{name}-floors-off": {**{**EXPECTED, **BEYOND}[name], **FLOORS_OFF_SWITCH} for name in FLOORS_OFF})


def _switches(settings: Settings) -> dict[str, object]:
    """The switches a method may set; the directions explorer's are its defaults where another explorer runs."""
    p = settings.paper
    directions = explorer_section(settings, "directions")
    return {
        **{k: v for k, v in settings_to_dict(settings)["agent"].items()},
        "explorer": settings.explorer.name,
        "decision_scan": directions.decision_scan,  # type: ignore[attr-defined]
        **{rule: getattr(directions, rule) for rule in PLUS_RULES},
        "cluster_span_deg": p.directions.cluster_span_deg,
        "weighted": p.speed.weighted,
        "restrict_forward": p.inspection.restrict_forward,
    }


@pytest.mark.parametrize("name", sorted({**EXPECTED, **BEYOND}))
def test_every_method_is_a_preset_over_the_defaults(name: str) -> None:
    settings = load_settings(name)
    default = _switches(load_settings())
    changed = {k: v for k, v in _switches(settings).items() if default[k] != v}
    assert changed == {**EXPECTED, **BEYOND}[name]
    agent = make_agent(settings)
    assert isinstance(agent, ExplorerAgent) and agent.name == name
    assert agent.config == settings.agent and agent.paper == settings.paper
    assert agent.sim == settings.sim == SimConfig() and agent.mapping == settings.mapping == MapTuning()


def test_one_list_of_methods_for_registry_and_ablations() -> None:
    assert [m.name for m in METHODS] == list(METHOD_NAMES) == [*ALL_METHODS, *BEYOND_PAPER]
    assert set(ALL_METHODS) == set(EXPECTED) and set(BEYOND_PAPER) == set(BEYOND)
    assert agent_names() == sorted([*EXPECTED, *BEYOND, "oracle", "random"])
    assert isinstance(make_agent(load_settings("oracle")), OracleAgent)


def test_config_show_prints_yaml_that_loads_back(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    assert main(["config", "show", "--agent", "no-240", "--set", "paper.speed.lam=0.5"]) == 0
    text = capsys.readouterr().out
    shown = yaml.safe_load(text)
    assert shown["paper"]["speed"]["lam"] == 0.5 and shown["paper"]["inspection"]["restrict_forward"] is False
    saved = tmp_path / "shown.yaml"
    saved.write_text(text)
    assert load_settings(configs=[str(saved)]) == load_settings("no-240", overrides=["paper.speed.lam=0.5"])
    assert settings_to_yaml(load_settings()) == settings_to_yaml(Settings())


def test_config_show_refuses_a_wrong_key_in_one_line(capsys: pytest.CaptureFixture[str]) -> None:
    assert main(["config", "show", "--set", "paper.speed.lamb=0.5"]) == 2
    err = capsys.readouterr().err.strip()
    assert err.startswith("drivenav: error: --set: field 'paper.speed.lamb'") and len(err.splitlines()) == 1


def test_eval_takes_overrides_and_records_them(tmp_path: Path) -> None:
    out = tmp_path / "run"
    args = ["eval", "--agent", "random", "--episodes", "1", "--out", str(out), "--config", "quick"]
    assert main([*args, "--set", "paper.speed.lam=0.5"]) == 0
    run = yaml.safe_load((out / "run.json").read_text())
    assert run["config"]["paper"]["speed"]["lam"] == 0.5 and run["config"]["sim"]["max_steps"] == 150
    assert main([*args, "--set", "paper.speed.lam=0.4"]) == 2  # resuming with another lambda is refused


def test_the_mapper_follows_the_sensor_by_default() -> None:
    sim = SimConfig(min_depth=0.3, max_depth=4.0, camera_height=1.2, agent_radius=0.2, grid_resolution=0.1)
    mapping = MappingConfig.from_sim(sim, load_settings().mapping)
    assert mapping == MappingConfig.from_sim(sim)
    assert (mapping.min_depth, mapping.max_depth, mapping.camera_height) == (0.3, 4.0, 1.2)
    assert (mapping.resolution, mapping.agent_radius, mapping.max_obstacle_height) == (0.1, 0.2, 0.88)
    tuned = load_settings(overrides=["mapping.min_frontier_area=2.5"]).mapping
    assert MappingConfig.from_sim(sim, tuned).min_frontier_area == 2.5


def test_config_show_states_the_units() -> None:
    header = [line for line in settings_to_yaml(load_settings()).splitlines() if line.startswith("#")]
    assert any("metres" in line and "degrees (*_deg)" in line for line in header)


def test_methods_name_the_papers_tables() -> None:
    tables = {m.name: set(m.tables) for m in METHODS}
    assert {name for name, t in tables.items() if "II" in t} == {
        "drive-nav",
        "direction-360",
        "nearest-frontier",
        "vlfm",
    }
    assert {name for name, t in tables.items() if "I" in t} == {"drive-nav", "vlfm", "apexnav"}
    assert {name for name, t in tables.items() if "V" in t} == {"directional", "no-weighted-fmm", "no-240"}
    assert all(m.description and (m.tables or m.base) for m in METHODS)
    bases = {m.name: m.base for m in METHODS if not m.tables}
    rows = {name: "drive-nav-plus" for name in BEYOND if name.startswith("drive-nav-plus-no-")}  # each without a rule
    off = {f"{name}-floors-off": name for name in FLOORS_OFF}  # each with its floors off
    assert bases == {"drive-nav-plus": "drive-nav", **rows, **off}


def test_first_difference_names_the_key() -> None:
    base = settings_to_dict(load_settings())
    assert first_difference(base, settings_to_dict(load_settings())) is None
    changed = settings_to_dict(load_settings(overrides=["paper.speed.lam=0.5", "sim.max_steps=9"]))
    assert first_difference(base, changed) == "paper.speed.lam"  # sorted order: paper before sim
    assert first_difference(base, settings_to_dict(load_settings("no-240"))) == "agent.enrich"
    assert first_difference({"a": {"b": 1}}, {"a": {"b": 1, "c": None}}) == "a.c"  # a key only one side has
    assert first_difference({"a": {"b": 1}}, {"a": 2}) == "a"
