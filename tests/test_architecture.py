"""The package's shape: one concept per module, no module over 600 lines, no import cycles,
imports that run one way down its floors.

The import graph is read from the source with :mod:`ast` (module-level and function-level
imports, ``TYPE_CHECKING`` blocks included), so a cycle hidden behind a lazy import counts.
"""

import ast
import graphlib
from pathlib import Path

import pytest

PACKAGE = Path(__file__).resolve().parents[1] / "pbvs_pin"
MAX_LINES = 600


def _module_names() -> dict[str, Path]:
    names = {}
    for path in sorted(PACKAGE.rglob("*.py")):
        parts = path.relative_to(PACKAGE.parent).with_suffix("").parts
        names[".".join(parts[:-1] if parts[-1] == "__init__" else parts)] = path
    return names


MODULES = _module_names()


def _resolve(name: str) -> str | None:
    """The longest known module that ``name`` lies in (an attribute import names its module)."""
    while name and name not in MODULES:
        name = name.rpartition(".")[0]
    return name or None


def _imports(module: str, path: Path) -> set[str]:
    """The package's modules that ``module`` imports anywhere in its source."""
    found = set()
    package = module if path.name == "__init__.py" else module.rpartition(".")[0]
    for node in ast.walk(ast.parse(path.read_text())):
        if isinstance(node, ast.Import):
            targets = [alias.name for alias in node.names]
        elif isinstance(node, ast.ImportFrom):
            base = node.module or ""
            if node.level:
                parent = package.split(".")[: len(package.split(".")) - node.level + 1]
                base = ".".join([*parent, *([node.module] if node.module else [])])
            targets = [f"{base}.{alias.name}" for alias in node.names]
        else:
            continue
        for target in targets:
            resolved = _resolve(target) if target.startswith("pbvs_pin") else None
            if resolved and resolved != module:
                found.add(resolved)
    return found


def test_the_import_graph_has_no_cycle():
    graph = {module: _imports(module, path) for module, path in MODULES.items()}
    # the package's __init__ files re-export their submodules; an edge into an __init__ from
    # inside its own package is the usual ``from pbvs_pin import x`` and is followed as such
    try:
        tuple(graphlib.TopologicalSorter(graph).static_order())
    except graphlib.CycleError as cycle:
        pytest.fail(f"import cycle: {' -> '.join(cycle.args[1])}")


def test_the_cycle_check_finds_a_cycle(tmp_path):
    """The check itself can fail: two modules importing each other form a cycle."""
    graph = {"a": {"b"}, "b": {"a"}}
    with pytest.raises(graphlib.CycleError):
        tuple(graphlib.TopologicalSorter(graph).static_order())


@pytest.mark.parametrize("module", sorted(MODULES))
def test_no_module_is_over_600_lines(module):
    lines = len(MODULES[module].read_text().splitlines())
    assert lines <= MAX_LINES, f"{module}: {lines} lines"


LAYERS = (
    ("exceptions",),
    ("validation", "linalg", "toml_keys", "compile_cache", "interrupts", "outputs"),
    ("model",),
    ("perception",),
    ("control",),
    ("controller",),
    ("plant",),
    ("bringup",),
    ("sim",),
    ("viz",),
    ("ros",),
    ("study",),
    ("cli",),
)
"""The package's parts from the ground up, as the paper's Fig. 3 reads: the model, perception,
control and the controller, the plants, a robot brought up at its home, the simulation, then
the views, the ROS 2 bridge, the study and the command line. A part imports only parts on its
own floor or below."""


def _part(module: str) -> str:
    """The part of ``pbvs_pin`` a module belongs to: its sub-package or its top-level module."""
    parts = module.split(".")
    return parts[1] if len(parts) > 1 else "pbvs_pin"


def _upward_imports(graph: dict[str, set[str]]) -> list[str]:
    """Every import from a part to a part on a higher floor, as ``module -> module``."""
    floor = {part: level for level, parts in enumerate(LAYERS) for part in parts}
    # the package's __init__ imports only compile_cache and interrupts; its public names load
    # lazily, by name, when first used
    floor["pbvs_pin"] = 1
    return [
        f"{module} -> {target}"
        for module, targets in sorted(graph.items())
        for target in sorted(targets)
        if floor[_part(target)] > floor[_part(module)]
    ]


def test_every_part_has_a_floor():
    parts = {_part(module) for module in MODULES} - {"pbvs_pin"}
    placed = {part for floor in LAYERS for part in floor}
    assert parts <= placed, f"parts with no floor in LAYERS: {sorted(parts - placed)}"


def test_imports_run_one_way_down():
    graph = {module: _imports(module, path) for module, path in MODULES.items()}
    upward = _upward_imports(graph)
    assert not upward, "imports that run up a floor:\n" + "\n".join(upward)


def test_the_floor_check_finds_an_upward_import():
    """The check itself can fail: the model importing the simulator runs up."""
    graph = {"pbvs_pin.model.robot": {"pbvs_pin.sim.loop"}, "pbvs_pin.sim.loop": set()}
    assert _upward_imports(graph) == ["pbvs_pin.model.robot -> pbvs_pin.sim.loop"]
