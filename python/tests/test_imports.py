# SPDX-License-Identifier: MIT
"""The package's modules import each other without a circle (docs/architecture.md: layers).

Every import counts, also those inside functions and under TYPE_CHECKING: a lazy import hides a
circle from the interpreter, not from the next maintainer (issue 15: link <-> faults was one).
"""

from __future__ import annotations

import ast
from pathlib import Path

SRC = Path(__file__).resolve().parent.parent / "src"
PACKAGE = "ctrlbus"


def module_name(path: Path) -> str:
    parts = list(path.relative_to(SRC).with_suffix("").parts)
    if parts[-1] == "__init__":
        parts.pop()
    return ".".join(parts)


def all_modules() -> dict[str, Path]:
    return {module_name(path): path for path in sorted((SRC / PACKAGE).rglob("*.py"))}


def imports_of(name: str, path: Path, modules: dict[str, Path]) -> set[str]:
    """The package's modules that `name` imports (`from a import b` counts as a.b when a.b is a
    module, else as a)."""
    is_package = path.name == "__init__.py"
    found: set[str] = set()
    for node in ast.walk(ast.parse(path.read_text(encoding="utf-8"), filename=str(path))):
        if isinstance(node, ast.Import):
            targets = [alias.name for alias in node.names]
        elif isinstance(node, ast.ImportFrom):
            if node.level:
                anchor = name if is_package else name.rpartition(".")[0]
                for _ in range(node.level - 1):
                    anchor = anchor.rpartition(".")[0]
                base = f"{anchor}.{node.module}" if node.module else anchor
            else:
                base = node.module or ""
            targets = [
                f"{base}.{alias.name}" if f"{base}.{alias.name}" in modules else base for alias in node.names
            ]
        else:
            continue
        found.update(target for target in targets if target in modules and target != name)
    return found


def find_cycle(graph: dict[str, set[str]]) -> list[str] | None:
    """One import circle as [a, b, ..., a], or None."""
    state: dict[str, int] = {}  # 1 = on the current path, 2 = done
    path: list[str] = []

    def visit(node: str) -> list[str] | None:
        state[node] = 1
        path.append(node)
        for target in sorted(graph[node]):
            if state.get(target) == 1:
                return [*path[path.index(target) :], target]
            if target not in state and (cycle := visit(target)) is not None:
                return cycle
        path.pop()
        state[node] = 2
        return None

    for node in sorted(graph):
        if node not in state and (cycle := visit(node)) is not None:
            return cycle
    return None


def import_graph() -> dict[str, set[str]]:
    modules = all_modules()
    return {name: imports_of(name, path, modules) for name, path in modules.items()}


def test_the_walk_sees_the_package() -> None:
    graph = import_graph()
    assert {"ctrlbus.ports", "ctrlbus.link", "ctrlbus.faults", "ctrlbus.cli.common"} <= graph.keys()
    assert {"ctrlbus.faults", "ctrlbus.link"} <= graph["ctrlbus.ports"]
    assert "ctrlbus.ports" in graph["ctrlbus.cli.common"]


def test_the_walk_finds_a_circle_when_there_is_one() -> None:
    assert find_cycle({"a": {"b"}, "b": {"c"}, "c": {"a"}}) == ["a", "b", "c", "a"]
    assert find_cycle({"a": {"b"}, "b": set(), "c": {"a", "b"}}) is None


def test_no_import_circle_in_the_package() -> None:
    cycle = find_cycle(import_graph())
    assert cycle is None, "import circle: " + " -> ".join(cycle or [])


def test_links_do_not_know_the_fault_injector() -> None:
    graph = import_graph()
    assert "ctrlbus.faults" not in graph["ctrlbus.link"]
    assert "ctrlbus.ports" not in graph["ctrlbus.faults"]


# docs/architecture.md, "The Python layers": top-level module or package -> layer, bottom up.
LAYERS = {
    "errors": 1,
    "compat": 1,
    "protocol_tables": 1,
    "frame": 2,
    "messages": 2,
    "constants": 2,
    "kinematics": 2,
    "binconf": 2,
    "link": 3,
    "faults": 3,
    "ports": 3,
    "quirks": 3,
    "base": 4,
    "checker": 5,
    "core": 5,
    "sim": 5,
    "annotate": 5,
    "capture": 5,
    "vtime": 5,
    "tap": 5,
    "cli": 6,
    "demo": 6,
    "web": 6,
    "ros2": 6,
    "__main__": 6,
}


def layer_of(module: str) -> int:
    parts = module.split(".")
    if len(parts) == 1:  # the package itself: its face re-exports from every layer
        return len(LAYERS)
    assert parts[1] in LAYERS, f"{module}: add it to LAYERS and to the picture in docs/architecture.md"
    return LAYERS[parts[1]]


def test_no_layer_imports_a_layer_above_it() -> None:
    upwards = [
        f"{module} -> {target}"
        for module, targets in import_graph().items()
        for target in sorted(targets)
        if target != PACKAGE and layer_of(target) > layer_of(module)  # `from ctrlbus import __version__`
    ]
    assert upwards == []


# Inside the Core (issue 15): the sans-IO session and every part of it (its protocol steps, the
# request in flight, the schedule, telemetry, event log, ...) hold no lock, start no thread and read
# no clock; the runner, which owns the thread and the clock, is the one exception.
CORE_RUNNER = "ctrlbus.core.runner"


def stdlib_imports_of(path: Path) -> set[str]:
    found: set[str] = set()
    for node in ast.walk(ast.parse(path.read_text(encoding="utf-8"), filename=str(path))):
        if isinstance(node, ast.Import):
            found.update(alias.name.split(".")[0] for alias in node.names)
        elif isinstance(node, ast.ImportFrom) and not node.level and node.module:
            found.add(node.module.split(".")[0])
    return found


def test_the_sans_io_core_takes_no_lock_and_the_runner_does() -> None:
    modules = all_modules()
    core = [name for name in modules if name.startswith("ctrlbus.core.") and name != CORE_RUNNER]
    assert "ctrlbus.core.session" in core and "ctrlbus.core.exchange" in core  # the scan works
    for name in core:
        imported = stdlib_imports_of(modules[name])
        assert "threading" not in imported, f"{name} imports threading"
        assert "time" not in imported, f"{name} imports time: the Core's time is passed in"
    assert "threading" in stdlib_imports_of(modules[CORE_RUNNER])


def test_the_dashboard_json_is_made_in_the_web_layer_only() -> None:
    graph = import_graph()
    assert "ctrlbus.core.session" in graph["ctrlbus.web.snapshot"]
    assert not any(
        target.startswith("ctrlbus.web")
        for name in graph
        if name.startswith("ctrlbus.core")
        for target in graph[name]
    )
