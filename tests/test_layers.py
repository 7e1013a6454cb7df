"""The package's layers hold: imports flow one way and nothing imports in a circle.

``core`` (pure stages) <- ``io`` (files) <- ``draw`` (figures, sheets) <- ``run``
(pipeline, triage) <- ``cli``: a module may import its own layer and the layers
before it, never one after. The rules are read from the source with ``ast``, so
an import inside a function counts as much as one at the top; imports under
``if TYPE_CHECKING:`` are annotations only and are left out.
"""

from __future__ import annotations

import ast
from pathlib import Path

import pytest

PACKAGE = Path(__file__).resolve().parents[1] / "rockscan"
LAYERS = ("core", "io", "draw", "run", "cli")
#: Root modules any layer may import (the version; the lazy API is imported by none).
SHARED_ROOT = {"rockscan._version"}
MAX_FUNCTION_LINES = 100


def _module_name(path: Path) -> str:
    parts = path.relative_to(PACKAGE.parent).with_suffix("").parts
    return ".".join(parts[:-1] if parts[-1] == "__init__" else parts)


MODULES = {_module_name(p): p for p in sorted(PACKAGE.rglob("*.py"))}


def _is_type_checking(node: ast.If) -> bool:
    test = node.test
    return (isinstance(test, ast.Name) and test.id == "TYPE_CHECKING") or (
        isinstance(test, ast.Attribute) and test.attr == "TYPE_CHECKING"
    )


def _imports(tree: ast.AST) -> list[tuple[str, int]]:
    """(imported module, line) for every runtime import in a module, nested ones too."""
    found: list[tuple[str, int]] = []

    def visit(node: ast.AST) -> None:
        if isinstance(node, ast.If) and _is_type_checking(node):
            for child in node.orelse:
                visit(child)
            return
        if isinstance(node, ast.Import):
            found.extend((alias.name, node.lineno) for alias in node.names)
        elif isinstance(node, ast.ImportFrom) and node.module and node.level == 0:
            for alias in node.names:
                sub = f"{node.module}.{alias.name}"
                found.append((sub if sub in MODULES else node.module, node.lineno))
        for child in ast.iter_child_nodes(node):
            visit(child)

    visit(tree)
    return found


TREES = {name: ast.parse(path.read_text(encoding="utf-8")) for name, path in MODULES.items()}
IMPORTS = {name: _imports(tree) for name, tree in TREES.items()}


def _layer(module: str) -> str | None:
    parts = module.split(".")
    return parts[1] if len(parts) > 1 and parts[0] == "rockscan" and parts[1] in LAYERS else None


def test_every_module_lives_in_a_layer():
    outside = [m for m in MODULES if _layer(m) is None and m not in {"rockscan", "rockscan.__main__"}]
    assert sorted(outside) == sorted(SHARED_ROOT)


@pytest.mark.parametrize("module", sorted(m for m in MODULES if _layer(m)))
def test_a_layer_imports_only_itself_and_the_layers_before_it(module):
    allowed = set(LAYERS[: LAYERS.index(_layer(module)) + 1])
    wrong = [
        f"line {line}: {target}"
        for target, line in IMPORTS[module]
        if target.split(".")[0] == "rockscan"
        and target not in SHARED_ROOT
        and (_layer(target) not in allowed)
    ]
    assert not wrong, f"{module} imports across layers: {wrong}"


def test_core_imports_nothing_of_files_drawing_running_or_the_command_line():
    core = [m for m in MODULES if _layer(m) == "core"]
    assert len(core) >= 15
    for module in core:
        outside = {t for t, _ in IMPORTS[module] if t.startswith("rockscan.") and _layer(t) != "core"}
        assert not outside, (module, outside)


def _cycle() -> list[str] | None:
    graph = {
        m: sorted({t for t, _ in IMPORTS[m] if t in MODULES and t != m and t != "rockscan"}) for m in MODULES
    }
    state: dict[str, int] = {}
    stack: list[str] = []

    def walk(node: str) -> list[str] | None:
        state[node] = 1
        stack.append(node)
        for nxt in graph[node]:
            if state.get(nxt) == 1:
                return [*stack[stack.index(nxt) :], nxt]
            if nxt not in state and (found := walk(nxt)):
                return found
        stack.pop()
        state[node] = 2
        return None

    for module in graph:
        if module not in state and (found := walk(module)):
            return found
    return None


def test_no_import_cycle_at_module_or_function_level():
    assert _cycle() is None, " -> ".join(_cycle() or [])


def test_the_cycle_finder_finds_a_planted_cycle():
    a, b = "rockscan.core.superformula", "rockscan.core.polar"
    saved = IMPORTS[a], IMPORTS[b]
    try:
        IMPORTS[a] = [*saved[0], (b, 1)]
        IMPORTS[b] = [*saved[1], (a, 1)]
        found = _cycle()
        assert found is not None and found[0] == found[-1] and {a, b} <= set(found)
    finally:
        IMPORTS[a], IMPORTS[b] = saved


@pytest.mark.parametrize(("library", "home"), [("click", "cli"), ("matplotlib", "draw")])
def test_heavy_libraries_are_imported_only_in_their_layer(library, home):
    users = {m for m, imports in IMPORTS.items() for t, _ in imports if t.split(".")[0] == library}
    assert users, f"nothing imports {library}"
    assert {m for m in users if _layer(m) != home} == set()


def test_no_function_is_longer_than_a_screenful_or_two():
    long = [
        f"{name}.{node.name}: {node.end_lineno - node.lineno + 1} lines"
        for name, tree in TREES.items()
        for node in ast.walk(tree)
        if isinstance(node, ast.FunctionDef | ast.AsyncFunctionDef)
        and node.end_lineno - node.lineno + 1 > MAX_FUNCTION_LINES
    ]
    assert not long
