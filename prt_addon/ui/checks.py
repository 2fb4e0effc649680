"""The checklist under the Bake button: the checks before any ray of the bake (blender.checks, on its plan), run on
demand by Check and by every bake, kept in this session's memory for the panel to list. It is the interface's state
of the moment: never saved in the file (Check writes nothing), and cleared when another file is opened, whose
objects it does not describe."""

import bpy

from ..blender.checks import all_checks
from ..blender.execute import local_executor
from ..blender.plan import plan_bake
from ..blender.request import read_request
from ..core import checks, settings as spec
from ..core.errors import InputError

ICONS = {checks.ERROR: "CANCEL", checks.WARNING: "ERROR", checks.INFO: "INFO", checks.OK: "CHECKMARK"}
_checklist: list[checks.Check] = []  # the last checks, for the panel


def last_checklist() -> list[checks.Check]:
    return list(_checklist)


@bpy.app.handlers.persistent
def forget_checklist(*args):
    _checklist.clear()


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
    _checklist[:] = found
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
    for check in _checklist:
        column.label(text=f"{check.subject}: {check.text}", icon=ICONS[check.level])


_register_classes, _unregister_classes = bpy.utils.register_classes_factory((PRT_OT_check_bake,))


def register():
    _register_classes()
    bpy.app.handlers.load_post.append(forget_checklist)


def unregister():
    if forget_checklist in bpy.app.handlers.load_post:
        bpy.app.handlers.load_post.remove(forget_checklist)
    _checklist.clear()
    _unregister_classes()
