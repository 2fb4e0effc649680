"""The checklist under the Bake button: the checks before any ray of the bake (blender.checks, on its plan), run on
demand by Check and by every bake, kept in this session's memory for the panel to list. It is the interface's state
of the moment: never saved in the file (Check writes nothing), and cleared when another file is opened, whose
objects it does not describe."""

import bpy
from bpy.props import EnumProperty, StringProperty
import numpy as np

from ..blender.checks import all_checks
from ..blender.execute import local_executor
from ..blender.fault_checks import FAULTS, fault_faces
from ..blender.geometry import visible_mesh_objects
from ..blender.mesh_arrays import mesh_corner_edges, mesh_corner_vertices
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


def checked_bake(context, receivers=None, volumes=None):
    """The plan of the bake the panel's settings describe (of `receivers`, or the default ones, and the probe
    volumes `volumes`, or every visible one: blender.request.read_request), the executor that would bake it, and
    every check on them, stored for the panel; nothing is written and no ray of the bake is cast. The plan is None
    when the bake cannot start (the checklist then holds why)."""
    settings = context.scene.prt_bake
    executor = local_executor(spec.worker_count(settings.workers))
    try:
        plan = plan_bake(read_request(context, settings.to_settings(), receivers, volume_names=volumes))
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


class PRT_OT_select_faults(bpy.types.Operator):
    """Select the faces at this fault in Edit Mode"""
    bl_idname = "prt.select_faults"
    bl_label = "Select"
    bl_options = {"REGISTER", "UNDO"}

    object_name: StringProperty(name="Object")
    fault: EnumProperty(name="Fault", items=[(fault, fault.capitalize(), "") for fault in FAULTS])

    @classmethod
    def poll(cls, context):
        return context.mode in {"OBJECT", "EDIT_MESH"}

    def execute(self, context):
        ob = bpy.data.objects.get(self.object_name)
        if ob is None or ob.type != "MESH":
            self.report({"ERROR"}, f"no mesh object named {self.object_name!r}")
            return {"CANCELLED"}
        if context.mode != "OBJECT":
            bpy.ops.object.mode_set(mode="OBJECT")
        others = [other for other in visible_mesh_objects(context) if other is not ob]
        faces = fault_faces(ob, self.fault, others)
        select_faces(ob.data, faces)
        for other in context.selected_objects:
            other.select_set(False)
        ob.select_set(True)
        context.view_layer.objects.active = ob
        bpy.ops.object.mode_set(mode="EDIT")
        context.tool_settings.mesh_select_mode = (False, False, True)
        self.report({"INFO"}, f"{ob.name}: {len(faces)} faces selected ({self.fault})")
        return {"FINISHED"}


def select_faces(mesh, faces):
    """Selects exactly `faces` of the mesh, and their edges and vertices, as Edit Mode reads them."""
    chosen = np.zeros(len(mesh.polygons), dtype=bool)
    chosen[faces] = True
    mesh.polygons.foreach_set("select", chosen)
    sizes = np.empty(len(mesh.polygons), dtype=np.int32)
    mesh.polygons.foreach_get("loop_total", sizes)
    for elements, indices in ((mesh.vertices, mesh_corner_vertices(mesh)), (mesh.edges, mesh_corner_edges(mesh))):
        selected = np.zeros(len(elements), dtype=bool)
        selected[indices[np.repeat(chosen, sizes)]] = True
        elements.foreach_set("select", selected)


def draw_checklist(layout, context):
    """The Check button and the last checklist, one line per finding; a fault of a mesh has a Select button."""
    layout.operator("prt.check_bake", icon="VIEWZOOM")
    column = layout.column(align=True)
    for check in _checklist:
        if not check.select:
            column.label(text=f"{check.subject}: {check.text}", icon=ICONS[check.level])
            continue
        row = column.row(align=True)
        row.label(text=f"{check.subject}: {check.text}", icon=ICONS[check.level])
        select = row.operator("prt.select_faults", text="", icon="RESTRICT_SELECT_OFF")
        select.object_name, select.fault = check.select


_register_classes, _unregister_classes = bpy.utils.register_classes_factory((PRT_OT_check_bake,
                                                                             PRT_OT_select_faults))


def register():
    _register_classes()
    bpy.app.handlers.load_post.append(forget_checklist)


def unregister():
    if forget_checklist in bpy.app.handlers.load_post:
        bpy.app.handlers.load_post.remove(forget_checklist)
    _checklist.clear()
    _unregister_classes()
