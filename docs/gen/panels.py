"""Where the sidebar shows each saved property, read from the panels' own drawing code: every `prop` call of a PRT
panel, its data traced to the property group it is (`settings = context.scene.prt_bake` → prt_bake), so the
settings page names the panel a user finds a setting in, and a setting moved to another panel moves there too."""

import ast
import inspect
import re
import textwrap

import bpy

from prt_addon import ui

OBJECT = "object"  # the owner of the per-object properties (context.active_object)
# Data a drawing function is handed rather than reads: the light the Lights panel draws is one of scene.prt_lights.
HANDED = {"light": "prt_lights"}


def panels() -> list[type]:
    """The sidebar's PRT panels, in the order they register."""
    return [item for module in ui.modules for item in vars(module).values()
            if isinstance(item, type) and issubclass(item, bpy.types.Panel) and item is not bpy.types.Panel]


def panel_path(panel: type) -> str:
    """The panel as a user finds it: PRT › Bake › Storage."""
    by_id = {item.bl_idname: item for item in panels()}
    names = [panel.bl_label]
    while getattr(panel, "bl_parent_id", None):
        panel = by_id[panel.bl_parent_id]
        names.insert(0, panel.bl_label)
    return " › ".join([panel.bl_category] + names)


def drawn() -> dict[tuple[str, str], str]:
    """{(owner, property): the first panel that draws it}; owner is a property group (prt_bake, prt_display, ...)
    or OBJECT."""
    found = {}
    for panel in panels():
        tree = ast.parse(textwrap.dedent(inspect.getsource(panel)))
        for function in [node for node in ast.walk(tree) if isinstance(node, ast.FunctionDef)]:
            for owner, name in _props(function):
                found.setdefault((owner, name), panel_path(panel))
    return found


def _props(function: ast.FunctionDef):
    """(owner, property) of each prop call in the function, every name a conditional expression may give."""
    sources = {target.id: ast.unparse(node.value) for node in ast.walk(function) if isinstance(node, ast.Assign)
               for target in node.targets if isinstance(target, ast.Name)}
    for call in [node for node in ast.walk(function) if isinstance(node, ast.Call)]:
        if not (isinstance(call.func, ast.Attribute) and call.func.attr in ("prop", "prop_search", "template_ID")
                and len(call.args) >= 2 and isinstance(call.args[0], ast.Name)):
            continue
        owner = _owner(call.args[0].id, sources)
        for constant in [node for node in ast.walk(call.args[1]) if isinstance(node, ast.Constant)]:
            yield owner, constant.value


def _owner(variable: str, sources: dict) -> str:
    source = sources.get(variable)
    if source is None:
        if variable not in HANDED:
            raise ValueError(f"a panel draws properties of {variable!r}, which docs/gen/panels.py cannot trace: "
                             f"name its property group in HANDED")
        return HANDED[variable]
    groups = re.findall(r"\bprt_\w+", source)
    if groups:
        return groups[-1]
    if "active_object" in source:
        return OBJECT
    raise ValueError(f"a panel draws properties of {variable} = {source}, which docs/gen/panels.py cannot trace")
