"""Parity: the same episodes run directly in the embedded world and through habitat-lab's ``habitat.Env`` (its
ObjectNav task, sensors, measures and dataset readers) on ``DriveNavSim-v0`` give the same action at every step
and the same success, SPL and distance to goal, in both Habitat layouts (ObjectNav v1 read by habitat-lab's own
reader, HM3D-OVON by drivenav's OVON-v1 dataset). A frame, sign, unit or normalisation error anywhere in the
adapter changes what the agent sees, and so its actions.

The oracle runs at the paper's 640x480; DRIVE-Nav (with the embedded stand-in models, which read the ground-truth
semantic sensor) at 320x240 and 150 steps to keep the suite's time, on the 12 shortest of 40 generated episodes.
"""

from __future__ import annotations

from pathlib import Path

import pytest
from worlds import BothWorlds, export, settings_for

from drivenav.envs.episode import Episode
from drivenav.envs.library import SceneLibrary
from drivenav.eval.episodes import generate_episodes, load_episodes, save_episodes

EPISODES = 12
TOLERANCE = 1e-6
CASES = {
    "oracle": (),
    "drive-nav": ("sim.width=320", "sim.height=240", "sim.max_steps=150"),
}


@pytest.fixture(scope="module")
def episodes(tmp_path_factory: pytest.TempPathFactory) -> list[Episode]:
    """12 short episodes, read back from drivenav's own file (the embedded run reads what a user's would)."""
    pool = generate_episodes(SceneLibrary("procedural", 0), 40, 7)
    chosen = [e for e in pool if e.geodesic_distance <= 8.0][:EPISODES]
    path = tmp_path_factory.mktemp("episodes") / "episodes.json.gz"
    save_episodes(chosen, path)
    return load_episodes(path)


def test_the_episodes_cover_synonyms_and_several_goals(episodes: list[Episode]) -> None:
    assert len(episodes) == EPISODES
    assert sum(bool(e.info.get("synonym")) for e in episodes) >= 3
    assert sum(len(e.goals) > 1 for e in episodes) >= 3


@pytest.mark.parametrize("benchmark", ["hm3d-v1", "hm3d-ovon"])
@pytest.mark.parametrize("agent", sorted(CASES))
def test_same_actions_and_metrics_in_both_worlds(
    agent: str, benchmark: str, episodes: list[Episode], tmp_path: Path
) -> None:
    spec = export(episodes, tmp_path / "data", benchmark)
    worlds = BothWorlds(spec, settings_for(agent, benchmark, *CASES[agent]))
    read_back = {e.episode_id: e for e in spec.episodes()}
    successes = 0
    try:
        for episode in episodes:
            (direct, direct_trace), (through, through_trace) = worlds.run(read_back[episode.episode_id])
            assert through.error == "" and direct.error == "", (through.error, direct.error)
            assert through_trace["actions"] == direct_trace["actions"], f"episode {episode.episode_id}"
            assert through.success == direct.success
            for key in ("spl", "distance_to_goal", "geodesic_distance", "path_length"):
                assert getattr(through, key) == pytest.approx(getattr(direct, key), abs=TOLERANCE), key
            assert (through.collisions, through.stop_reason) == (direct.collisions, direct.stop_reason)
            assert (through.failure_cause, through.revisits) == (direct.failure_cause, direct.revisits)
            successes += int(direct.success or 0)
    finally:
        worlds.close()
    assert successes >= 2  # the metrics compared include successes, not only failures
