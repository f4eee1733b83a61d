"""Golden records: the same embedded episodes, seeds and agents give the same records as before (captured from
commit 0209848 with ``drivenav eval --max-steps 120``, when the evaluation core became world-agnostic; re-captured
when the agent's fidelity fixes moved drive-nav's episode 0, direction-360's and no-240's episodes 0 and 1: the
other 16 are unchanged)."""

from __future__ import annotations

import json
from pathlib import Path

import pytest

from drivenav.envs.embedded.env import EmbeddedSpec
from drivenav.eval.episodes import load_episodes
from drivenav.eval.records import read_records
from drivenav.eval.rundir import trace_path
from drivenav.eval.runner import RunSpec, evaluate
from drivenav.settings import load_settings

GOLDEN = Path(__file__).parent / "data" / "golden"
RECORDS = json.loads((GOLDEN / "golden_records.json").read_text(encoding="utf-8"))
EXACT = ("success", "steps", "stop_reason", "failure_cause", "collisions", "revisits", "vlm_calls", "actions")


@pytest.mark.parametrize("agent", sorted(RECORDS))
def test_same_records_as_before(agent: str, tmp_path: Path) -> None:
    episodes = load_episodes(GOLDEN / "episodes.json.gz")
    settings = load_settings(agent, options={"run.seed": 7, "sim.max_steps": 120})
    spec = RunSpec(EmbeddedSpec("procedural", 7), settings)
    evaluate(episodes, spec, tmp_path, show_progress=False)
    for record in read_records(tmp_path / "episodes.jsonl"):
        expected = RECORDS[agent][record.episode_id]
        trace = json.loads(trace_path(tmp_path, record.episode_id).read_text(encoding="utf-8"))
        got = {**record.to_json(), "actions": trace["actions"]}
        assert {k: got[k] for k in EXACT} == {k: expected[k] for k in EXACT}
        for key in ("spl", "path_length", "distance_to_goal", "geodesic_distance"):
            assert got[key] == pytest.approx(expected[key], abs=1e-4), key
