"""The rooms keep to their rules: core/ imports neither bpy (nor bmesh, gpu) nor anything above it, and nothing
outside ui/ imports ui/ (only the package's register() does, to register it). The core's one dependency beyond
numpy is mathutils' BVHTree, the ray caster."""

import ast
from pathlib import Path

import pytest

PACKAGE = Path(__file__).resolve().parents[1] / "prt_addon"
BLENDER_MODULES = {"bpy", "bmesh", "gpu", "gpu_extras", "bpy_extras"}


def imports(path: Path) -> set[str]:
    """Absolute names of the modules a file imports (relative imports resolved within prt_addon)."""
    package = path.relative_to(PACKAGE.parent).with_suffix("").parts[:-1]
    found = set()
    for node in ast.walk(ast.parse(path.read_text(encoding="utf-8"))):
        if isinstance(node, ast.Import):
            found |= {alias.name for alias in node.names}
        elif isinstance(node, ast.ImportFrom):
            base = package[: len(package) - node.level + 1] if node.level else ()
            module = ".".join(base + ((node.module,) if node.module else ()))
            found.add(module)
            found |= {f"{module}.{alias.name}" for alias in node.names}
    return found


def modules(room: str = ""):
    return sorted((PACKAGE / room).rglob("*.py"))


@pytest.mark.parametrize("path", modules("core"), ids=lambda p: p.name)
def test_core_imports_no_blender_module_and_nothing_above_it(path):
    names = imports(path)
    assert not {name.split(".")[0] for name in names} & BLENDER_MODULES
    assert not [name for name in names if name.startswith("prt_addon.") and not name.startswith("prt_addon.core")]


@pytest.mark.parametrize("path", [p for p in modules() if "ui" not in p.relative_to(PACKAGE).parts[:-1]
                                  and p != PACKAGE / "__init__.py"], ids=lambda p: str(p.relative_to(PACKAGE)))
def test_nothing_outside_ui_imports_ui(path):
    assert not [name for name in imports(path) if name == "prt_addon.ui" or name.startswith("prt_addon.ui.")]


def test_the_rules_see_imports():
    """The scan resolves relative imports and sees imports inside functions."""
    assert "mathutils.bvhtree.BVHTree" in imports(PACKAGE / "core" / "bake.py")
    assert "prt_addon.blender.relighting.Relighter" in imports(PACKAGE / "ui" / "handlers.py")
    assert "prt_addon.ui" in imports(PACKAGE / "__init__.py")
