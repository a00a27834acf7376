"""The import layers of docs/architecture.md, checked over src/ with the ast module.

A package may import only from its own layer or below. Every import counts: module
level, inside functions (lazy) and under ``TYPE_CHECKING``. The root utility modules
are free to use from anywhere, and import nothing of visnav but each other.
:mod:`visnav.node_registry` names node classes as ``module:Class`` strings, which are
not imports and so are not checked (it starts the nodes, it does not depend on them).
"""

from __future__ import annotations

import ast
from pathlib import Path

import pytest

SRC = Path(__file__).resolve().parents[1] / "src" / "visnav"

LAYERS: tuple[tuple[str, ...], ...] = (
    ("msgs",),
    ("description",),
    ("graph",),
    ("tf", "message_filters"),
    ("perception", "bag", "teleop"),
    ("sim", "mapping", "slam", "viz"),
    ("planning", "doctor", "launch", "bridge"),
    ("scenarios",),
    ("cli",),
)
"""Bottom to top, as in docs/architecture.md."""

ROOT_UTILITIES = frozenset(
    {"errors", "node_registry", "textfile", "safe_yaml", "outpaths", "plugin_registry", "logsetup"}
)
"""Root modules (``src/visnav/<name>.py``) every layer may import."""

PACKAGE_ATTRIBUTES = frozenset({"__version__"})
"""Names of ``visnav/__init__.py`` itself (not modules), free to import."""

LEVEL = {package: level for level, packages in enumerate(LAYERS) for package in packages}


def _module_name(path: Path) -> str:
    parts = list(path.relative_to(SRC.parent).with_suffix("").parts)
    if parts[-1] == "__init__":
        parts.pop()
    return ".".join(parts)


def _imports(path: Path) -> list[tuple[int, str]]:
    """Every visnav module ``path`` imports (line, dotted name), relative ones resolved."""
    source = path.read_text(encoding="utf-8")
    return _imports_in(source, _module_name(path), is_package=path.name == "__init__.py")


def _imports_in(source: str, module_name: str, *, is_package: bool) -> list[tuple[int, str]]:
    tree = ast.parse(source)
    package = module_name.split(".")
    if not is_package:
        package = package[:-1]
    found: list[tuple[int, str]] = []
    for node in ast.walk(tree):
        if isinstance(node, ast.Import):
            found.extend((node.lineno, alias.name) for alias in node.names)
        elif isinstance(node, ast.ImportFrom):
            if node.level:
                base = package[: len(package) - node.level + 1]
                module = ".".join([*base, *([node.module] if node.module else [])])
            else:
                module = node.module or ""
            if node.module is None or module == "visnav":
                found.extend((node.lineno, f"{module}.{alias.name}") for alias in node.names)
            else:
                found.append((node.lineno, module))
    return [(line, name) for line, name in found if name.split(".")[0] == "visnav"]


def _top(name: str) -> str | None:
    parts = name.split(".")
    return parts[1] if len(parts) > 1 else None


def _files() -> list[Path]:
    return sorted(SRC.rglob("*.py"))


def layering_violations() -> list[str]:
    """One line per import that points up the layer table."""
    problems: list[str] = []
    for path in _files():
        own = _top(_module_name(path))
        for line, name in _imports(path):
            target = _top(name)
            if target is None or target == own or target in PACKAGE_ATTRIBUTES:
                continue
            where = f"{path.relative_to(SRC.parent)}:{line}: imports {name}"
            if own is None or own == "__init__":
                continue  # visnav/__init__.py: test_package_init_imports_only_root_utilities
            if own in ROOT_UTILITIES:
                if target not in ROOT_UTILITIES:
                    problems.append(f"{where} (a root utility may import only root utilities)")
                continue
            if target in ROOT_UTILITIES:
                continue
            if target not in LEVEL:
                problems.append(f"{where} ({target!r} is in no layer: add it to LAYERS)")
            elif own not in LEVEL:
                problems.append(f"{where} ({own!r} is in no layer: add it to LAYERS)")
            elif LEVEL[target] > LEVEL[own]:
                problems.append(
                    f"{where} ({own} is layer {LEVEL[own]}, {target} is layer {LEVEL[target]})"
                )
    return problems


def test_every_package_has_a_layer() -> None:
    packages = {p.parent.name for p in SRC.glob("*/__init__.py")}
    modules = {p.stem for p in SRC.glob("*.py")} - {"__init__"}
    assert packages - set(LEVEL) == set()
    assert modules - ROOT_UTILITIES == set()


def test_imports_point_down() -> None:
    problems = layering_violations()
    assert problems == [], "\n".join(problems)


def test_package_init_imports_only_root_utilities() -> None:
    """``import visnav`` stays light: its ``__init__`` imports no subpackage."""
    targets = {_top(name) for _, name in _imports(SRC / "__init__.py")}
    assert targets <= ROOT_UTILITIES


def test_checker_sees_lazy_relative_and_type_checking_imports() -> None:
    """Imports inside functions, relative ones and TYPE_CHECKING ones are all found."""
    code = (
        "from typing import TYPE_CHECKING\n"
        "if TYPE_CHECKING:\n    from visnav.planning import nodes\n"
        "def f():\n    from visnav.cli import main\n    from ..sim import world_spec\n"
        "    from . import clock\n"
    )
    found = [name for _, name in _imports_in(code, "visnav.graph.probe", is_package=False)]
    assert found == ["visnav.planning", "visnav.cli", "visnav.sim", "visnav.graph.clock"]
    assert all(LEVEL[_top(n) or ""] > LEVEL["graph"] for n in found[:3])


@pytest.mark.parametrize("utility", sorted(ROOT_UTILITIES))
def test_root_utilities_exist(utility: str) -> None:
    assert (SRC / f"{utility}.py").is_file()


MAX_LINES = 700
"""House style: a module holds one concept, a few hundred lines, never above this."""


def test_no_module_is_above_the_line_limit() -> None:
    long = {
        str(path.relative_to(SRC.parent)): n
        for path in _files()
        if (n := len(path.read_text(encoding="utf-8").splitlines())) > MAX_LINES
    }
    assert long == {}, f"split these by concept (limit {MAX_LINES} lines): {long}"
