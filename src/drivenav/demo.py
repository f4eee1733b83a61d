"""``make demo``: a short embedded benchmark with results and pictures, in a few minutes on a laptop."""

from __future__ import annotations

import json
from pathlib import Path

from drivenav.benchmarks.generate import generate_episodes
from drivenav.envs.embedded.env import EmbeddedSpec
from drivenav.envs.embedded.library import SceneLibrary
from drivenav.eval.report import format_table, shown
from drivenav.eval.rundir import read_run
from drivenav.eval.runner import RunSpec, evaluate
from drivenav.settings import load_settings
from drivenav.types import SimConfig
from drivenav.viz.episode import episode_material, render_episode_pictures

DEMO_SCENES = "procedural:2"
DEMO_AGENTS = (("drive-nav", 500), ("oracle", 500))
VIDEO_AGENT = "drive-nav"  # only its first episode gets an MP4, to keep the demo short


def _markdown_link(path: Path, out: Path) -> str:
    """An image for pictures, a plain link for videos (Markdown viewers do not play ``![...](x.mp4)``)."""
    target = path.relative_to(out)
    return f"  [video: {path.name}]({target})" if path.suffix == ".mp4" else f"  ![{path.name}]({target})"


def run_demo(out: Path, num_episodes: int, seed: int) -> Path:
    """Evaluate the demo agents on a few procedural episodes, draw every episode, write ``index.md``."""
    out.mkdir(parents=True, exist_ok=True)
    library = SceneLibrary(DEMO_SCENES, seed)
    episodes = generate_episodes(library, num_episodes, seed, SimConfig())
    lines = ["# drivenav demo", "", f"{len(episodes)} episodes on `{DEMO_SCENES}` (seed {seed}).", ""]
    for agent, max_steps in DEMO_AGENTS:
        run_dir = out / agent
        settings = load_settings(agent, options={"run.seed": seed, "sim.max_steps": max_steps})
        spec = RunSpec(EmbeddedSpec(DEMO_SCENES, seed), settings)
        summary = evaluate(episodes, spec, run_dir)
        table = format_table(summary, f"{agent} (max {max_steps} steps)")
        print(table)
        lines += [f"## {agent}", "", "```", table, "```", ""]
        run = read_run(run_dir)
        for number, record in enumerate(sorted(run.records, key=lambda r: int(r.episode_id))):
            video = agent == VIDEO_AGENT and number == 0
            material = episode_material(run_dir, run, record.episode_id)
            pictures = render_episode_pictures(material, run_dir / "viz", video=video)
            lines.append(
                f"- episode {record.episode_id} ({record.object_category}): success {record.success}, "
                f"SPL {shown(record.spl, '{:.2f}')}, {record.steps} steps"
            )
            lines += [_markdown_link(p, out) for p in pictures]
        lines.append("")
    index = out / "index.md"
    index.write_text("\n".join(lines) + "\n", encoding="utf-8")
    (out / "demo.json").write_text(json.dumps({"scenes": DEMO_SCENES, "seed": seed}) + "\n", encoding="utf-8")
    return index
