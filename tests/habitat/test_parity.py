"""Parity: the same episodes run directly in the embedded world and through habitat-lab's ``habitat.Env`` (its
ObjectNav task, sensors, measures and dataset readers) on ``DriveNavSim-v0`` give the same action at every step
and the same success, SPL and distance to goal, in both Habitat layouts (ObjectNav v1 read by habitat-lab's own
reader, HM3D-OVON by drivenav's own dataset type). A frame, sign, unit or normalisation error anywhere in the
adapter changes what the agent sees, and so its actions.

The oracle runs at the paper's 640x480; DRIVE-Nav, VLFM and ApexNav (with the embedded stand-in models, which read
the ground-truth semantic sensor) at 320x240 and 150 steps to keep the suite's time, on the 12 shortest of 40
generated episodes.
"""

from __future__ import annotations

from pathlib import Path

import pytest
from worlds import BothWorlds, assert_same, export, settings_for

from drivenav.benchmarks.generate import generate_episodes
from drivenav.envs.embedded.library import SceneLibrary
from drivenav.episode import Episode
from drivenav.eval.episodes import load_episodes, save_episodes
from drivenav.eval.records import EpisodeRecord
from drivenav.eval.trace import EpisodeTrace

EPISODES = 12
CASES = {
    "oracle": (),
    "drive-nav": ("sim.width=320", "sim.height=240", "sim.max_steps=150"),
    "vlfm": ("sim.width=320", "sim.height=240", "sim.max_steps=150"),
    "apexnav": ("sim.width=320", "sim.height=240", "sim.max_steps=150"),
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


@pytest.mark.parametrize("half", [0, 1])  # two test items per agent, for the test workers
@pytest.mark.parametrize("agent", sorted(CASES))
def test_same_actions_and_metrics_in_both_worlds(
    agent: str, half: int, episodes: list[Episode], tmp_path: Path
) -> None:
    """Each episode runs once directly, then through habitat.Env in each layout (hm3d-v1: ObjectNav v1 read by
    habitat-lab; hm3d-ovon: HM3D-OVON read by drivenav's own dataset type). One success distance (0.25 m) for
    both, so that one direct run is the reference of both."""
    direct: dict[str, tuple[EpisodeRecord, EpisodeTrace]] = {}
    for benchmark in ("hm3d-v1", "hm3d-ovon"):
        spec = export(episodes[half * EPISODES // 2 : (half + 1) * EPISODES // 2], tmp_path / benchmark, benchmark)
        worlds = BothWorlds(spec, settings_for(agent, benchmark, "sim.success_distance=0.25", *CASES[agent]))
        try:
            for episode in spec.episodes():
                if episode.episode_id not in direct:
                    direct[episode.episode_id] = worlds.direct(episode)
                through = worlds.through(episode)
                reference = direct[episode.episode_id]
                assert_same(reference, through, f"{benchmark} episode {episode.episode_id}")
        finally:
            worlds.close()
    assert len(direct) == EPISODES // 2
    assert sum(int(record.success or 0) for record, _ in direct.values()) >= 1  # successes compared too
