"""The algorithmic core imports no world: ``mapping``, ``directions``, ``inspection``, ``semantics`` and ``agent``
use only the neutral modules (types, config, grid, errors, metrics) and each other; ``agent`` does not import
``eval``. A small AST check over every module, imports inside functions included."""

from __future__ import annotations

import ast
import subprocess
import sys
from pathlib import Path

import pytest

PACKAGE = Path(__file__).parents[1] / "src" / "drivenav"
CORE = ("mapping", "directions", "inspection", "semantics", "agent")
WORLDS_AND_EDGES = ("drivenav.envs", "drivenav.eval", "drivenav.viz", "drivenav.cli")


def imported_modules(path: Path) -> set[str]:
    tree = ast.parse(path.read_text(encoding="utf-8"))
    names: set[str] = set()
    for node in ast.walk(tree):
        if isinstance(node, ast.Import):
            names.update(alias.name for alias in node.names)
        elif isinstance(node, ast.ImportFrom) and node.module and node.level == 0:
            names.add(node.module)
    return names


def violations(package: str) -> list[str]:
    found = []
    for path in sorted((PACKAGE / package).rglob("*.py")):
        for module in imported_modules(path):
            if any(module == edge or module.startswith(edge + ".") for edge in WORLDS_AND_EDGES):
                found.append(f"{path.relative_to(PACKAGE)} imports {module}")
    return found


@pytest.mark.parametrize("package", CORE)
def test_core_package_imports_no_world(package: str) -> None:
    assert violations(package) == []


def test_the_check_sees_a_violation(tmp_path: Path) -> None:
    module = tmp_path / "bad.py"
    module.write_text("def f():\n    from drivenav.envs.embedded.env import EmbeddedEnv\n", encoding="utf-8")
    assert imported_modules(module) == {"drivenav.envs.embedded.env"}


def test_the_settings_read_the_agents_config_without_importing_the_agent() -> None:
    """``drivenav config show`` and every settings check read ``AgentConfig`` from ``agent/config.py``: the
    settings floor imports no agent behaviour (it used to import the 658-line agent module)."""
    agent_imports = {m for m in imported_modules(PACKAGE / "settings.py") if m.startswith("drivenav.agent")}
    assert agent_imports == {"drivenav.agent.config"}
    code = "import sys, drivenav.settings; print(sorted(m for m in sys.modules if m.startswith('drivenav.agent.')))"
    loaded = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True).stdout
    assert loaded.strip() == "['drivenav.agent.config']"
