"""The checklist under the Bake button: the checks before any ray of the bake (blender.checks, on its plan), run on
demand by Check and by every bake, kept on the window manager (interface state, not the scene's data) for the
panel to list."""

import bpy
from bpy.props import CollectionProperty, EnumProperty, PointerProperty, StringProperty

from ..blender.checks import all_checks
from ..blender.execute import local_executor
from ..blender.plan import plan_bake
from ..blender.registration import classes_and_properties
from ..blender.request import read_request
from ..core import checks, settings as spec
from ..core.errors import InputError

ICONS = {checks.ERROR: "CANCEL", checks.WARNING: "ERROR", checks.INFO: "INFO", checks.OK: "CHECKMARK"}
LEVEL_ITEMS = [(level, level.capitalize(), "How serious the finding is") for level in checks.LEVELS]


class PRT_PG_check(bpy.types.PropertyGroup):
    level: EnumProperty(items=LEVEL_ITEMS)
    subject: StringProperty()
    text: StringProperty()


class PRT_PG_checklist(bpy.types.PropertyGroup):
    items: CollectionProperty(type=PRT_PG_check)


def checked_bake(context, receivers=None):
    """The plan of the bake the panel's settings describe (of `receivers`, or the default ones), the executor that
    would bake it, and every check on them, stored for the panel; nothing is written and no ray of the bake is
    cast. The plan is None when the bake cannot start (the checklist then holds why)."""
    settings = context.scene.prt_bake
    executor = local_executor(spec.worker_count(settings.workers))
    try:
        plan = plan_bake(read_request(context, settings.to_settings(), receivers))
    except InputError as problem:
        plan, found = None, [checks.Check(checks.ERROR, "bake", str(problem))]
    else:
        found = all_checks(context, plan, executor, output=None, required=False)
    items = context.window_manager.prt_checks.items
    items.clear()
    for check in found:
        item = items.add()
        item.level, item.subject, item.text = check.level, check.subject, check.text
    return plan, executor, found


class PRT_OT_check_bake(bpy.types.Operator):
    """Check the bake before any ray is cast: output, memory, time, and the objects' problems"""
    bl_idname = "prt.check_bake"
    bl_label = "Check"

    @classmethod
    def poll(cls, context):
        return context.mode == "OBJECT" and not context.window_manager.prt_bake_status.running

    def execute(self, context):
        _, _, found = checked_bake(context)
        errors = len(checks.errors(found))
        warnings = sum(check.level == checks.WARNING for check in found)
        self.report({"WARNING" if errors else "INFO"}, f"PRT checks: {errors} errors, {warnings} warnings")
        return {"FINISHED"}


def draw_checklist(layout, context):
    """The Check button and the last checklist, one line per finding."""
    layout.operator("prt.check_bake", icon="VIEWZOOM")
    column = layout.column(align=True)
    for item in context.window_manager.prt_checks.items:
        column.label(text=f"{item.subject}: {item.text}", icon=ICONS[item.level])


classes = (PRT_PG_check, PRT_PG_checklist, PRT_OT_check_bake)

register, unregister = classes_and_properties(classes, [
    (bpy.types.WindowManager, "prt_checks", PointerProperty(type=PRT_PG_checklist)),
])
