"""The house rules of the code base, checked on the source text (issue 14).

A newcomer should be able to read any module in one sitting and trust the layering:
the library never reaches up into the leaves, the algorithms run without py_trees or
ROS installed, and no two modules need each other to load. These tests parse every
module of ``bomc_bt/`` and ``behaviours/`` with :mod:`ast` (nothing is imported), so
they also catch imports hidden inside functions.
"""

from __future__ import annotations

import ast
from dataclasses import dataclass
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]
PACKAGES = ("bomc_bt", "behaviours")
MAX_LINES = 400

# Plain algorithms: testable with numpy alone, reusable outside a behaviour tree or ROS.
ALGORITHM_MODULES = (
    "bomc_bt.anytime",
    "bomc_bt.exploration",
    "bomc_bt.traversal",
    "bomc_bt.refresh",
    "bomc_bt.viewpoints",
    "bomc_bt.perception.projection",
    "bomc_bt.graph",
    "bomc_bt.evaluation",
    "bomc_bt.change_evaluation",
    "bomc_bt.net_changes",
    "bomc_bt.planner",
    "bomc_bt.path_smoothing",
    "bomc_bt.polyline",
    "bomc_bt.costmap",
    "bomc_bt.localization",
    "bomc_bt.scan_likelihood",
    "bomc_bt.world",
    "bomc_bt.worldgen",
    "bomc_bt.worldgen_placer",
    "bomc_bt.officegen",
    "bomc_bt.geometry",
    "bomc_bt.grid",
)
FRAMEWORK_ROOTS = {"py_trees", "rospy", "roslib", "rosgraph", "rosbag", "roslaunch", "actionlib", "tf", "tf2_ros",
                   "genpy", "message_filters", "cv_bridge"}


@dataclass(frozen=True)
class Module:
    """One source file: its dotted name, path relative to the repository, and syntax tree."""

    name: str
    path: str
    tree: ast.Module
    lines: int


def _module_name(path: Path) -> str:
    parts = list(path.relative_to(ROOT).with_suffix("").parts)
    if parts[-1] == "__init__":
        parts.pop()
    return ".".join(parts)


def _load_modules() -> dict[str, Module]:
    out = {}
    for package in PACKAGES:
        for path in sorted((ROOT / package).rglob("*.py")):
            text = path.read_text()
            name = _module_name(path)
            out[name] = Module(name, path.relative_to(ROOT).as_posix(), ast.parse(text, str(path)),
                               len(text.splitlines()))
    return out


MODULES = _load_modules()


def _is_package(module: Module) -> bool:
    return module.path.endswith("__init__.py")


def _is_type_checking_block(node: ast.AST) -> bool:
    test = getattr(node, "test", None) if isinstance(node, ast.If) else None
    return (isinstance(test, ast.Name) and test.id == "TYPE_CHECKING") or (
        isinstance(test, ast.Attribute) and test.attr == "TYPE_CHECKING")


def _runtime_nodes(tree: ast.AST):
    """Every node of ``tree`` except the bodies of ``if TYPE_CHECKING:`` blocks.

    Annotation-only imports are not loaded at run time: a strategy module may name the
    class that calls it in its type hints (the graph's association policies do).
    """
    stack = [tree]
    while stack:
        node = stack.pop()
        yield node
        for child in ast.iter_child_nodes(node):
            if _is_type_checking_block(child):
                stack.extend(child.orelse)
            else:
                stack.append(child)


def imported_names(module: Module) -> set[str]:
    """Every dotted name ``module`` imports, anywhere in its body (functions included).

    ``from a import b`` yields ``a.b`` when ``a.b`` is a module of ours, else ``a``;
    relative imports are resolved against the module's package.
    """
    found: set[str] = set()
    for node in _runtime_nodes(module.tree):
        if isinstance(node, ast.Import):
            found.update(alias.name for alias in node.names)
        elif isinstance(node, ast.ImportFrom):
            base = node.module or ""
            if node.level:
                package = module.name if _is_package(module) else module.name.rpartition(".")[0]
                anchor = package.rsplit(".", node.level - 1)[0] if node.level > 1 else package
                base = f"{anchor}.{base}" if base else anchor
            for alias in node.names:
                candidate = f"{base}.{alias.name}"
                found.add(candidate if candidate in MODULES else base)
    return found


def _own_module(name: str) -> str | None:
    """The module of ours that importing ``name`` loads (longest known prefix), or None."""
    parts = name.split(".")
    for end in range(len(parts), 0, -1):
        prefix = ".".join(parts[:end])
        if prefix in MODULES:
            return prefix
    return None


def import_graph() -> dict[str, set[str]]:
    """Module -> the modules of ours it imports."""
    graph: dict[str, set[str]] = {}
    for name, module in MODULES.items():
        targets = {_own_module(n) for n in imported_names(module)}
        graph[name] = {t for t in targets if t is not None and t != name}
    return graph


def find_cycles(graph: dict[str, set[str]]) -> list[list[str]]:
    """Strongly connected components with more than one module (Tarjan), each sorted."""
    index: dict[str, int] = {}
    low: dict[str, int] = {}
    stack: list[str] = []
    on_stack: set[str] = set()
    cycles: list[list[str]] = []

    def visit(v: str) -> None:
        index[v] = low[v] = len(index)
        stack.append(v)
        on_stack.add(v)
        for w in sorted(graph.get(v, ())):
            if w not in index:
                visit(w)
                low[v] = min(low[v], low[w])
            elif w in on_stack:
                low[v] = min(low[v], index[w])
        if low[v] == index[v]:
            component = []
            while True:
                w = stack.pop()
                on_stack.discard(w)
                component.append(w)
                if w == v:
                    break
            if len(component) > 1:
                cycles.append(sorted(component))

    for v in sorted(graph):
        if v not in index:
            visit(v)
    return cycles


def _is_algorithm(name: str) -> bool:
    return any(name == a or name.startswith(a + ".") for a in ALGORITHM_MODULES)


def _is_framework(name: str) -> bool:
    root = name.split(".")[0]
    return root in FRAMEWORK_ROOTS or root.endswith(("_msgs", "_srvs"))


# -- the checker itself ---------------------------------------------------------------------
def test_the_checker_sees_imports_inside_functions_and_finds_cycles():
    tree = ast.parse("def f():\n    from bomc_bt.grid import OccupancyGrid\n    import py_trees\n")
    names = imported_names(Module("bomc_bt.example", "bomc_bt/example.py", tree, 3))
    assert names == {"bomc_bt.grid", "py_trees"}
    relative = ast.parse("from .frames import Detection\nfrom .. import grid\n")
    names = imported_names(Module("bomc_bt.perception.x", "bomc_bt/perception/x.py", relative, 2))
    assert names == {"bomc_bt.perception.frames", "bomc_bt.grid"}
    assert find_cycles({"a": {"b"}, "b": {"c"}, "c": {"a"}, "d": {"a"}}) == [["a", "b", "c"]]
    assert find_cycles({"a": {"b"}, "b": set()}) == []


def test_every_listed_algorithm_module_exists():
    for name in ALGORITHM_MODULES:
        assert any(m == name or m.startswith(name + ".") for m in MODULES), f"{name}: no such module"


# -- the rules ------------------------------------------------------------------------------
def test_no_import_cycle_among_library_modules():
    graph = import_graph()
    library = {k: {t for t in v if t.startswith("bomc_bt")} for k, v in graph.items() if k.startswith("bomc_bt")}
    assert find_cycles(library) == []


def test_library_never_imports_the_leaf_package():
    offenders = sorted(f"{m.path} imports {n}" for m in MODULES.values() if m.name.startswith("bomc_bt")
                       for n in imported_names(m) if n.split(".")[0] == "behaviours")
    assert offenders == []


def test_algorithms_import_neither_py_trees_nor_ros():
    offenders = sorted(f"{m.path} imports {n}" for m in MODULES.values() if _is_algorithm(m.name)
                       for n in imported_names(m) if _is_framework(n))
    assert offenders == []


@pytest.mark.parametrize("module", sorted(MODULES.values(), key=lambda m: m.path), ids=lambda m: m.path)
def test_module_is_short_enough_to_read_in_one_sitting(module):
    assert module.lines <= MAX_LINES, f"{module.path}: {module.lines} lines (max {MAX_LINES})"
