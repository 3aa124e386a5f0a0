"""How the packages import one another (read from the source, nothing imported): every import
counts, at module level, under ``TYPE_CHECKING`` and inside functions."""

import ast
from functools import cache
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
LAYERS = ("networks", "sensors", "gtgen", "cosim")  # a package imports only packages to its left
SUMO_MODULES = ("libsumo", "traci")


@cache
def _modules() -> dict[str, Path]:
    out = {}
    for package in LAYERS:
        for path in sorted((ROOT / package).rglob("*.py")):
            parts = path.relative_to(ROOT).with_suffix("").parts
            out[".".join(parts[:-1] if parts[-1] == "__init__" else parts)] = path
    return out


@cache
def _imported(path: Path) -> list[str]:
    """Every module name an import statement of the file names (``from a import b``: a and a.b)."""
    names = []
    for node in ast.walk(ast.parse(path.read_text(), str(path))):
        if isinstance(node, ast.Import):
            names += [alias.name for alias in node.names]
        elif isinstance(node, ast.ImportFrom) and node.module and node.level == 0:
            names += [node.module, *(f"{node.module}.{alias.name}" for alias in node.names)]
    return names


@cache
def _graph() -> dict[str, set[str]]:
    """Module -> the project's modules it imports (not its own parent packages)."""
    modules = _modules()
    graph: dict[str, set[str]] = {name: set() for name in modules}
    for name, path in modules.items():
        for imported in _imported(path):
            while imported and imported not in modules:
                imported = imported.rpartition(".")[0]
            if imported and imported != name and not name.startswith(f"{imported}."):
                graph[name].add(imported)
    return graph


def _cycle(graph: dict[str, set[str]]) -> list[str]:
    """One import circle (empty: none), by depth-first search."""
    state: dict[str, int] = {}  # 1: on the path, 2: done
    path: list[str] = []

    def visit(node: str) -> list[str]:
        state[node] = 1
        path.append(node)
        for nxt in sorted(graph[node]):
            if state.get(nxt) == 1:
                return [*path[path.index(nxt) :], nxt]
            if nxt not in state and (found := visit(nxt)):
                return found
        state[node] = 2
        path.pop()
        return []

    for node in sorted(graph):
        if node not in state and (found := visit(node)):
            return found
    return []


def test_only_the_sumo_boundary_imports_libsumo():
    importers = sorted(
        name for name, path in _modules().items() if any(m.split(".")[0] in SUMO_MODULES for m in _imported(path))
    )
    assert importers and all(name.startswith("cosim.sumo.") for name in importers), importers


def test_no_import_circles():
    assert _cycle(_graph()) == []


def test_the_circle_finder_finds_a_circle():
    assert _cycle({"a": {"b"}, "b": {"c"}, "c": {"a"}, "d": {"a"}}) == ["a", "b", "c", "a"]


def test_a_package_imports_only_the_packages_below_it():
    wrong = [(name, other) for name, imports in _graph().items() for other in imports
             if LAYERS.index(other.split(".")[0]) > LAYERS.index(name.split(".")[0])]  # fmt: skip
    assert wrong == []
