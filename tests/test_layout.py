"""The rooms keep to their rules: core/ imports neither bpy (nor bmesh, gpu) nor anything above it, and nothing
outside ui/ imports ui/ or the package's register() (only that register() imports the interface, to register it):
the commands and blender/ work with the saved settings' schema (blender.schema) alone. In the core only the BVHTree
ray engine (core/engines/bvhtree.py) imports mathutils, and nothing else in the package but the Embree engine
(core/engines/embree.py) imports embreex; the rest is numpy. No module imports itself through others:
prt_addon's import graph, imports inside functions included, has no cycle."""

import ast
from pathlib import Path

import pytest

PACKAGE = Path(__file__).resolve().parents[1] / "prt_addon"
BLENDER_MODULES = {"bpy", "bmesh", "gpu", "gpu_extras", "bpy_extras"}


def import_statements(path: Path, source: str | None = None):
    """(module, names) for every import statement of a file (or of `source` as if it were that file), inside
    functions too: `import a.b` gives ('a.b', []), `from m import x, y` gives (m, ['x', 'y']) with a relative m
    resolved within prt_addon."""
    package = path.relative_to(PACKAGE.parent).with_suffix("").parts[:-1]
    for node in ast.walk(ast.parse(path.read_text(encoding="utf-8") if source is None else source)):
        if isinstance(node, ast.Import):
            yield from ((alias.name, []) for alias in node.names)
        elif isinstance(node, ast.ImportFrom):
            base = package[: len(package) - node.level + 1] if node.level else ()
            yield ".".join(base + ((node.module,) if node.module else ())), [alias.name for alias in node.names]


def imports(path: Path, source: str | None = None) -> set[str]:
    """Absolute names of the modules a file (or `source` as if it were that file) imports and of the names it
    imports from them."""
    found = set()
    for module, names in import_statements(path, source):
        found |= {module} | {f"{module}.{name}" for name in names}
    return found


def modules(room: str = ""):
    return sorted((PACKAGE / room).rglob("*.py"))


@pytest.mark.parametrize("path", modules("core"), ids=lambda p: p.name)
def test_core_imports_no_blender_module_and_nothing_above_it(path):
    names = imports(path)
    assert not {name.split(".")[0] for name in names} & BLENDER_MODULES
    assert not [name for name in names if name.startswith("prt_addon.") and not name.startswith("prt_addon.core")]


def interface_imports(names) -> list[str]:
    """The names that reach the interface: ui/, or the package's register() and unregister(), which register it."""
    return [name for name in names if name in ("prt_addon.ui", "prt_addon.register", "prt_addon.unregister")
            or name.startswith("prt_addon.ui.")]


@pytest.mark.parametrize("path", [p for p in modules() if "ui" not in p.relative_to(PACKAGE).parts[:-1]
                                  and p != PACKAGE / "__init__.py"], ids=lambda p: str(p.relative_to(PACKAGE)))
def test_nothing_outside_ui_imports_ui_or_the_packages_register(path):
    assert not interface_imports(imports(path))


@pytest.mark.parametrize("path", modules("core"), ids=lambda p: str(p.relative_to(PACKAGE / "core")))
def test_only_the_bvhtree_engine_imports_mathutils(path):
    uses_mathutils = "mathutils" in {name.split(".")[0] for name in imports(path)}
    assert uses_mathutils == (path == PACKAGE / "core" / "engines" / "bvhtree.py")


@pytest.mark.parametrize("path", modules(), ids=lambda p: str(p.relative_to(PACKAGE)))
def test_only_the_embree_engine_imports_embreex(path):
    uses_embreex = "embreex" in {name.split(".")[0] for name in imports(path)}
    assert uses_embreex == (path == PACKAGE / "core" / "engines" / "embree.py")


def test_the_rules_see_imports():
    """The scan resolves relative imports and sees imports inside functions."""
    assert "mathutils.bvhtree.BVHTree" in imports(PACKAGE / "core" / "engines" / "bvhtree.py")
    assert "prt_addon.core.engines.reference.ReferenceEngine" in imports(PACKAGE / "core" / "engines" / "__init__.py")
    assert "prt_addon.blender.handlers.engine" in imports(PACKAGE / "ui" / "lights.py")
    assert "prt_addon.ui" in imports(PACKAGE / "__init__.py")
    command = PACKAGE / "commands" / "common.py"
    assert interface_imports(imports(command, "def f():\n    from .. import register")) == ["prt_addon.register"]
    assert interface_imports(imports(command, "from .. import ui")) == ["prt_addon.ui"]
    assert set(interface_imports(imports(PACKAGE / "blender" / "schema.py", "from ..ui.status import x"))) == {
        "prt_addon.ui.status", "prt_addon.ui.status.x"}


def module_of(path: Path) -> str:
    parts = path.relative_to(PACKAGE.parent).with_suffix("").parts
    return ".".join(parts[:-1] if parts[-1] == "__init__" else parts)


def import_graph() -> dict[str, set[str]]:
    """Each prt_addon module → the prt_addon modules it imports, inside functions too: `from m import x` imports
    m.x where that is a module, else m (x is a name m defines)."""
    known = {module_of(path) for path in modules()}
    graph = {}
    for path in modules():
        targets = set()
        for module, names in import_statements(path):
            targets |= {f"{module}.{name}" if f"{module}.{name}" in known else module for name in names} or {module}
        graph[module_of(path)] = targets & known
    return graph


def cycles(graph: dict[str, set[str]]) -> set[frozenset]:
    """The modules of each cycle of `graph`: every set of modules that all reach each other (a module importing
    itself alone)."""
    reach = {}
    for start in graph:
        seen, todo = set(), list(graph[start])
        while todo:
            module = todo.pop()
            if module not in seen:
                seen.add(module)
                todo.extend(graph.get(module, ()))
        reach[start] = seen
    return {frozenset(other for other in graph if other in reach[module] and module in reach[other])
            for module in graph if module in reach[module]}


def test_no_module_imports_itself_through_others():
    assert cycles(import_graph()) == set()


def test_the_graph_and_the_cycle_check_see_cycles():
    """Teeth: a cycle of three with a module hanging off it is found, alone; and the real graph holds a cycle once
    the core's plain values import the estimator that imports them, or storage the texel maps that import it."""
    assert cycles({"a": {"b"}, "b": {"c"}, "c": {"a"}, "d": {"a"}, "e": {"e"}}) == {frozenset("abc"), frozenset("e")}
    graph = import_graph()
    graph["prt_addon.core.bake"].add("prt_addon.core.estimator")
    graph["prt_addon.blender.storage"].add("prt_addon.blender.texel_maps")
    found = cycles(graph)
    assert any({"prt_addon.core.bake", "prt_addon.core.estimator"} <= cycle for cycle in found)
    assert frozenset({"prt_addon.blender.storage", "prt_addon.blender.texel_maps"}) in found
