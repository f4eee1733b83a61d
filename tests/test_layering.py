"""The floor contract: which part of drivenav may import which, checked over every module (imports inside functions
and behind ``TYPE_CHECKING`` included).

drivenav is built in floors. A module imports only from floors below its own, so there is no import loop between
folders and a lower floor never sees a higher one:

1. the neutral base: errors, the settings' ranges, grid, types, the JSON and YAML readers, the kernels' ``jit``,
   the entry-point registries (``plugins``), the paper's constants, metrics, the episode format, the method names;
2. ``wire``, the message framing and sockets below every end that speaks it: the brain-robot protocol's two ends
   (``envs.robot``, ``robot``) and the served grounder's (``semantics.served``, ``semantics.grounder_server``);
3. the algorithmic core, numpy in and dataclasses out: ``mapping``, ``semantics`` (protocols and the embedded
   models), ``directions``, ``inspection``, ``agent``;
4. ``settings`` (the typed configuration tree) and the agents built from it;
5. ``envs``, the worlds: the shared protocol (``envs.base``, ``envs.vocabulary``) and one folder or module per world
   (``embedded``, ``habitat``, ``robot``), which never import one another;
6. ``eval`` (the run machinery: runs any world), then ``benchmarks`` (episode generation, the benchmarks, world
   statistics), then ``analysis`` (the paper's tables, comparisons of runs), then ``worlds`` (the registry of
   worlds by ``--env``), then ``robot`` (the robot side's servers), then ``viz`` (draws what it is given) and
   ``report``;
7. the applications: ``brain`` (a live episode), ``doctor``, ``cli``.
"""

from __future__ import annotations

import ast
import subprocess
import sys
from pathlib import Path

import pytest

PACKAGE = Path(__file__).parents[1] / "src" / "drivenav"

FLOORS: tuple[str, ...] = (
    "errors", "ranges", "grid", "types", "jsonstream", "validation", "jit", "instances", "metrics", "packing",
    "threads", "plugins", "paper", "methods", "episode",
    "wire",
    "mapping", "semantics", "directions", "inspection", "agent",
    "settings", "agents",
    "envs",
    "eval", "benchmarks", "analysis", "worlds", "robot", "viz", "report",
    "brain", "doctor", "demo", "cli",
)  # fmt: skip
"""Every part of the package, lowest first: a part imports only parts listed before it."""

WORLDS = ("envs.embedded", "envs.habitat", "envs.robot")
"""The worlds inside ``envs``: none imports another, and the shared world modules import none of them."""
SHARED_WORLD_MODULES = ("envs.base", "envs.vocabulary")


def imported_modules(path: Path) -> set[str]:
    tree = ast.parse(path.read_text(encoding="utf-8"))
    names: set[str] = set()
    for node in ast.walk(tree):
        if isinstance(node, ast.Import):
            names.update(alias.name for alias in node.names)
        elif isinstance(node, ast.ImportFrom) and node.module and node.level == 0:
            names.add(node.module)
            names.update(f"{node.module}.{alias.name}" for alias in node.names)
    return {name for name in names if _is_module(name)}


def _is_module(name: str) -> bool:
    parts = name.split(".")
    if parts[0] != "drivenav" or len(parts) < 2:
        return False
    path = PACKAGE.joinpath(*parts[1:])
    return path.with_suffix(".py").is_file() or path.is_dir()


def module_name(path: Path) -> str:
    parts = path.relative_to(PACKAGE).with_suffix("").parts
    return ".".join(("drivenav", *(p for p in parts if p != "__init__")))


def part_of(module: str) -> str:
    """The floor's part a module belongs to: its top-level module or folder under ``drivenav``."""
    return module.split(".")[1]


def world_of(module: str) -> str | None:
    inner = ".".join(module.split(".")[1:3])
    return inner if inner in (*WORLDS, *SHARED_WORLD_MODULES) else None


def every_import() -> list[tuple[str, str]]:
    """(importer, imported) for every import of a drivenav module by another, over the whole package."""
    pairs = []
    for path in sorted(PACKAGE.rglob("*.py")):
        importer = module_name(path)
        pairs.extend((importer, imported) for imported in sorted(imported_modules(path)))
    return pairs


def floor_violations(pairs: list[tuple[str, str]]) -> list[str]:
    found = []
    for importer, imported in pairs:
        low, high = part_of(imported), part_of(importer)
        if low != high and FLOORS.index(low) > FLOORS.index(high):
            found.append(f"{importer} imports {imported}, a higher floor")
    return found


def world_violations(pairs: list[tuple[str, str]]) -> list[str]:
    found = []
    for importer, imported in pairs:
        mine, theirs = world_of(importer), world_of(imported)
        if mine is not None and theirs in WORLDS and mine != theirs:
            found.append(f"{importer} imports {imported}, another world")
    return found


def test_every_part_has_a_floor() -> None:
    parts = {part_of(module_name(path)) for path in PACKAGE.rglob("*.py") if path.name != "__init__.py"}
    parts.discard("__main__")
    assert parts <= set(FLOORS), sorted(parts - set(FLOORS))


def test_the_run_machinery_imports_no_episode_generation() -> None:
    """``eval`` runs episodes it is given; generating them is ``benchmarks``' (the embedded world's ``--episodes N``
    is the world registry's, above both)."""
    found = [(a, b) for a, b in every_import() if part_of(a) == "eval" and part_of(b) == "benchmarks"]
    assert found == []


def test_no_part_imports_a_higher_floor() -> None:
    assert floor_violations(every_import()) == []


def test_worlds_do_not_import_one_another() -> None:
    assert world_violations(every_import()) == []


def test_the_checks_see_violations(tmp_path: Path) -> None:
    module = tmp_path / "bad.py"
    module.write_text("def f():\n    from drivenav.viz import topdown\n", encoding="utf-8")
    assert imported_modules(module) == {"drivenav.viz", "drivenav.viz.topdown"}
    assert floor_violations([("drivenav.eval.pictures", "drivenav.viz.topdown")]) != []
    assert floor_violations([("drivenav.viz.topdown", "drivenav.eval.runner")]) == []
    assert world_violations([("drivenav.envs.habitat.env", "drivenav.envs.embedded.measures")]) != []
    assert world_violations([("drivenav.envs.base", "drivenav.envs.robot")]) != []
    assert world_violations([("drivenav.envs.habitat.env", "drivenav.envs.base")]) == []


def test_the_settings_read_the_agents_config_without_importing_the_agent() -> None:
    """``drivenav config show`` and every settings check read ``AgentConfig`` from ``agent/config.py`` and each
    explorer's section from its entry's ``config`` module: the settings floor loads no agent behaviour."""
    agent_imports = {m for m in imported_modules(PACKAGE / "settings.py") if m.startswith("drivenav.agent")}
    assert agent_imports <= {"drivenav.agent.config", "drivenav.agent.explorers"}
    code = (
        "import sys, drivenav.settings as s; s.load_settings('vlfm')\n"
        "print(sorted(m for m in sys.modules if m.startswith('drivenav.agent.')))"
    )
    loaded = eval(subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True).stdout)
    assert "drivenav.agent.config" in loaded and "drivenav.agent.explorers.vlfm.config" in loaded
    packages = {"drivenav.agent.explorers", *(m.rpartition(".")[0] for m in loaded if m.endswith(".config"))}
    assert [m for m in loaded if not m.endswith(".config") and m not in packages] == []


@pytest.mark.parametrize("floor", ["mapping", "directions", "inspection", "semantics", "agent"])
def test_the_core_loads_no_world(floor: str) -> None:
    """Importing a core package (all of its modules) loads no world, evaluator, picture or command-line code (the
    wire sits below the core: the served grounder speaks it)."""
    modules = sorted(module_name(p) for p in (PACKAGE / floor).rglob("*.py"))
    code = f"import sys\nfor m in {modules!r}: __import__(m)\n" + (
        "print(sorted({m.split('.')[1] for m in sys.modules if m.startswith('drivenav.')}))"
    )
    loaded = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True).stdout
    higher = {"envs", "eval", "benchmarks", "analysis", "worlds", "viz", "report", "cli", "robot", "brain", "settings"}
    assert not set(eval(loaded)) & higher
