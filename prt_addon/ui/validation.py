"""Validation against Cycles from the sidebar: the operator (modal in the UI, synchronous in background mode) and a
panel with the scene's validation settings (blender.schema) and the last result."""

import bpy
from bpy.props import CollectionProperty, FloatProperty, IntProperty, PointerProperty, StringProperty

from ..blender.registration import classes_and_properties
from ..blender.validation import Validation
from .operators import ModalJob
from .panels import SidebarPanel
from .status import PRT_PG_job_status


class PRT_PG_compared(bpy.types.PropertyGroup):
    """One object's comparison (`name` from PropertyGroup); relative to the RMS of Cycles' colours."""
    vertices: IntProperty()
    error: FloatProperty()
    cycles_noise: FloatProperty()
    p99: FloatProperty()  # 99th percentile of the per-vertex error, Cycles' noise taken out
    real_error: FloatProperty(default=-1.0)  # against the real light (negative: not compared)


class PRT_PG_validation_result(bpy.types.PropertyGroup):
    """The last validation, for the panel (window-manager level: never saved)."""
    compared: CollectionProperty(type=PRT_PG_compared)  # per object, then "all"
    worst_object: StringProperty()    # the object with the largest p99
    worst_vertices: StringProperty()  # its worst vertices' indices, worst first, comma-separated
    prt_bake_s: FloatProperty()
    cycles_s: FloatProperty()
    light: StringProperty()
    notes: StringProperty()  # one per line


class PRT_OT_validate(ModalJob, bpy.types.Operator):
    """Compare the PRT colours with Cycles lit by the same band-limited light (the scene is put back afterwards)"""
    bl_idname = "prt.validate"
    bl_label = "Validate with Cycles"
    bl_options = {"REGISTER"}
    status_property = "prt_validate_status"
    label = "PRT validate"
    kept = "the scene is as it was"

    @classmethod
    def poll(cls, context):
        return context.mode == "OBJECT" and not context.window_manager.prt_validate_status.running

    def make_job(self, context):
        settings = context.scene.prt_validate
        return Validation(context, settings.samples, settings.passes, reference=settings.reference)

    def finish(self, context, validation, comparisons):
        store_result(context.window_manager.prt_validation, validation, comparisons)
        validation.store_errors(comparisons)
        context.scene.update_tag()  # the Difference from Cycles heatmap shows the new errors
        for sentence in validation.problems + validation.notes:
            self.report({"WARNING"}, sentence)
        lines = validation.lines(comparisons)
        self.report({"INFO"}, lines[0])
        print("\n".join(lines))


def store_result(result, validation, comparisons):
    result.compared.clear()
    real = validation.light_comparisons() or [None] * len(comparisons)
    for comparison, total in zip(comparisons, real):
        entry = result.compared.add()
        entry.name = comparison.name
        entry.vertices = comparison.vertices
        entry.error, entry.cycles_noise, entry.p99 = comparison.error, comparison.cycles_noise, comparison.p99
        entry.real_error = total.error if total is not None else -1.0
    worst = validation.worst(comparisons)
    result.worst_object = worst["object"]
    result.worst_vertices = ", ".join(str(vertex["index"]) for vertex in worst["vertices"])
    result.prt_bake_s = validation.bake_time_s()
    result.cycles_s = validation.cycles.time_s
    clamped = 100 * max(validation.clamped.values())
    result.light = f"{'Scene' if validation.scene_light else 'Default'} light, {clamped:.2f} % clamped"
    result.notes = "\n".join(validation.problems + validation.notes)


class PRT_PT_validate(SidebarPanel, bpy.types.Panel):
    """Cycles as ground truth: how far the PRT colours are from it, and what each took."""
    bl_label = "Validation"
    bl_idname = "PRT_PT_validate"

    def draw(self, context):
        layout = self.layout
        layout.use_property_split = True
        layout.use_property_decorate = False
        settings = context.scene.prt_validate
        column = layout.column(align=True)
        column.prop(settings, "samples")
        column.prop(settings, "passes")
        layout.prop(settings, "reference")
        status = context.window_manager.prt_validate_status
        if status.running:
            layout.progress(factor=status.fraction, type="BAR", text=status.text)
        else:
            layout.operator("prt.validate", icon="CHECKMARK")
        result = context.window_manager.prt_validation
        if not result.compared:
            return
        column = layout.column(align=True)
        column.label(text="Error against Cycles, RMS and p99 (its noise taken out):")
        for entry in result.compared:
            row = column.row()
            row.label(text=f"{entry.name} ({entry.vertices} vertices)")
            row.label(text=f"{100 * entry.error:.2f} %, p99 {100 * entry.p99:.1f} %  "
                           f"(noise {100 * entry.cycles_noise:.2f} %)")
            if entry.real_error >= 0.0:
                column.label(text=f"    real light: total {100 * entry.real_error:.2f} %, band-limiting "
                                  f"{100 * (entry.real_error - entry.error):+.2f} points")
        column.label(text=f"Worst: {result.worst_object}, vertices {result.worst_vertices}", icon="VERTEXSEL")
        column.label(text=f"PRT bake {result.prt_bake_s:.1f} s, Cycles {result.cycles_s:.1f} s")
        column.label(text=result.light)
        for note in result.notes.splitlines():
            column.label(text=note, icon="INFO")


classes = (PRT_PG_compared, PRT_PG_validation_result, PRT_OT_validate, PRT_PT_validate)


register, unregister = classes_and_properties(classes, [
    (bpy.types.WindowManager, "prt_validate_status", PointerProperty(type=PRT_PG_job_status)),
    (bpy.types.WindowManager, "prt_validation", PointerProperty(type=PRT_PG_validation_result)),
])
