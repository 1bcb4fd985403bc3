"""The package's floors: an import only goes down (``cli`` → ``eval`` → ``envs`` → ``task`` → ``perception`` →
``grasping`` → ``motion`` → ``robot`` → ``world`` → ``errors``), so that each floor can be read, tested and
replaced without the ones above. ``envs`` holds the Gymnasium environments, built on the tasks and skills."""

from __future__ import annotations

import ast
from pathlib import Path

import pytest

SRC = Path(__file__).resolve().parents[1] / "src" / "pickplace"
FLOORS = ["errors", "world", "robot", "motion", "grasping", "perception", "task", "envs", "eval", "cli"]


def _floor(module: str) -> int:
    """The floor of ``pickplace.<first>...`` (``__init__`` and ``__main__`` of the package are outside)."""
    return FLOORS.index(module.split(".")[1])


def _modules() -> list[tuple[str, Path]]:
    out = []
    for path in sorted(SRC.rglob("*.py")):
        parts = path.relative_to(SRC.parent).with_suffix("").parts
        if parts[-1] == "__init__":
            parts = parts[:-1]
        if len(parts) > 1 and parts[1] != "__main__":
            out.append((".".join(parts), path))
    return out


def _imports(path: Path) -> list[tuple[int, str]]:
    """(line, module) of every ``pickplace.*`` import in the file, at any depth (lazy imports too)."""
    found = []
    for node in ast.walk(ast.parse(path.read_text(encoding="utf-8"))):
        if isinstance(node, ast.ImportFrom) and node.module and node.module.startswith("pickplace."):
            found.append((node.lineno, node.module))
        elif isinstance(node, ast.ImportFrom) and node.module == "pickplace":
            found += [(node.lineno, f"pickplace.{a.name}") for a in node.names if a.name in FLOORS]
        elif isinstance(node, ast.Import):
            found += [(node.lineno, a.name) for a in node.names if a.name.startswith("pickplace.")]
    return found


def test_every_module_is_on_a_floor() -> None:
    modules = _modules()
    assert len(modules) > 20
    for name, _ in modules:
        assert name.split(".")[1] in FLOORS, f"{name} is on no floor: put it in one of {FLOORS}"


@pytest.mark.parametrize(("name", "path"), _modules(), ids=[m[0] for m in _modules()])
def test_imports_only_go_down(name: str, path: Path) -> None:
    up = [(line, mod) for line, mod in _imports(path) if _floor(mod) > _floor(name)]
    assert not up, f"{name} imports from a higher floor: " + ", ".join(f"{m} (line {ln})" for ln, m in up)
