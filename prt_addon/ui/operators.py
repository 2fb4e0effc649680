"""Operators: the bake (modal in the UI, synchronous in background mode), clearing a bake, adding a probe volume and
the glTF export; the modal driver of jobs (core.progress.Job) that the validation shares."""

import bpy
from bpy_extras.io_utils import ExportHelper

from ..blender import geometry, gltf, storage
from ..blender.texel_bake import OBJECT_PREFIX
from ..blender.scene_bake import SceneBake
from ..core import checks
from ..core import settings as spec
from ..core.errors import InputError
from ..core.progress import format_duration, old_objects_frozen
from .checks import checked_bake


def _report_outcome(operator, report):
    for problem in report.problems + report.notes:
        operator.report({"WARNING"}, problem)
    operator.report({"INFO"}, report.summary.line())
    operator.report({"INFO"}, report.summary.curve_line())


class ModalJob:
    """An operator that drives a job (core.progress.Job) from timer events: a progress bar in the panel, the
    window manager's progress, time left in the status bar, Esc cancels. Subclasses make the job (make_job, which
    may raise InputError) and take its outcome (finish); in background mode, where timers never fire, invoke runs
    execute: the same job run by Job.run with log lines."""
    status_property = ""  # the WindowManager property, a PRT_PG_job_status, that the panel reads
    label = ""            # what the status bar calls the job
    kept = ""             # what a cancelled or failed job leaves

    _job = None
    _timer = None

    def start(self, context):
        try:
            return self.make_job(context)
        except InputError as problem:
            self.report({"ERROR"}, str(problem))
            return None

    def execute(self, context):
        job = self.start(context)
        if job is None:
            return {"CANCELLED"}
        try:
            outcome = job.run(log=print)
        except Exception as failure:  # nothing was written, or the scene was put back on the way out
            self.report({"ERROR"}, f"{self.label} failed, {self.kept}: {failure}")
            return {"CANCELLED"}
        self.finish(context, job, outcome)
        return {"FINISHED"}

    def invoke(self, context, event):
        if bpy.app.background:
            return self.execute(context)
        self._job = self.start(context)
        if self._job is None:
            return {"CANCELLED"}
        wm = context.window_manager
        status = getattr(wm, self.status_property)
        status.running = True
        status.fraction = 0.0
        wm.progress_begin(0, 1000)
        self._timer = wm.event_timer_add(0.02, window=context.window)
        wm.modal_handler_add(self)
        return {"RUNNING_MODAL"}

    def modal(self, context, event):
        if event.type == "ESC":
            self._job.cancel()
            self._end(context)
            self.report({"WARNING"}, f"{self.label} cancelled; {self.kept}")
            return {"CANCELLED"}
        if event.type != "TIMER":
            return {"PASS_THROUGH"}
        try:
            with old_objects_frozen():
                done = self._job.step(0.08)
        except Exception as failure:
            self._end(context)
            self.report({"ERROR"}, f"{self.label} failed, {self.kept}: {failure}")
            return {"CANCELLED"}
        progress = self._job.progress
        status = getattr(context.window_manager, self.status_property)
        status.fraction = progress.fraction
        status.text = f"{100 * progress.fraction:.0f} %, {format_duration(progress.remaining)} left (Esc cancels)"
        context.window_manager.progress_update(int(1000 * progress.fraction))
        context.workspace.status_text_set(f"{self.label}: {status.text}")
        for area in context.screen.areas:
            if area.type == "VIEW_3D":
                area.tag_redraw()
        if not done:
            return {"RUNNING_MODAL"}
        self._end(context)
        try:
            outcome = self._job.outcome()
        except Exception as failure:
            self.report({"ERROR"}, f"{self.label} failed, {self.kept}: {failure}")
            return {"CANCELLED"}
        self.finish(context, self._job, outcome)
        return {"FINISHED"}

    def _end(self, context):
        wm = context.window_manager
        if self._timer is not None:
            wm.event_timer_remove(self._timer)
            self._timer = None
        wm.progress_end()
        getattr(wm, self.status_property).running = False
        context.workspace.status_text_set(None)


class BakeJob(ModalJob):
    """What the bake operators share (Bake, and Bake Stale in stale.py; Blender does not register a subclass of a
    registered operator): the panel's status, when they can run, and the outcome's report."""
    bl_options = {"REGISTER", "UNDO"}
    status_property = "prt_bake_status"
    label = "PRT bake"
    kept = "previous data kept"

    @classmethod
    def poll(cls, context):
        status = context.window_manager.prt_bake_status
        return context.mode == "OBJECT" and not status.running

    def checked_bake(self, context, receivers=None, volumes=None):
        """The bake as a job (blender.scene_bake), once the checks on its plan pass: the panel lists them,
        warnings are reported, errors stop it."""
        plan, executor, found = checked_bake(context, receivers, volumes)
        for check in found:
            if check.level == checks.WARNING:
                self.report({"WARNING"}, f"{check.subject}: {check.text}")
        checks.stop_on_errors(found)
        return SceneBake.of_plan(plan, executor)

    def finish(self, context, scene_bake, summary):
        _report_outcome(self, scene_bake.report())
        print(summary.line())
        print(summary.curve_line())


class PRT_OT_bake(BakeJob, bpy.types.Operator):
    """Bake SH transfer into the selected meshes (all visible meshes when none is selected)"""
    bl_idname = "prt.bake"
    bl_label = "Bake PRT"

    def make_job(self, context):
        return self.checked_bake(context)


class PRT_OT_clear(bpy.types.Operator):
    """Remove the PRT bake (attributes and metadata) from the selected meshes"""
    bl_idname = "prt.clear"
    bl_label = "Clear PRT Bake"
    bl_options = {"REGISTER", "UNDO"}

    @classmethod
    def poll(cls, context):
        return context.mode == "OBJECT" and any(ob.type == "MESH" for ob in context.selected_objects)

    def execute(self, context):
        for ob in context.selected_objects:
            if ob.type != "MESH":
                continue
            try:
                geometry.check_writable(ob)
            except InputError as problem:
                self.report({"WARNING"}, str(problem))
                continue
            storage.remove_transfer(ob.data)
        return {"FINISHED"}


class PRT_OT_add_probe_volume(bpy.types.Operator):
    """Add a PRT probe volume at the 3D cursor: scale its cube over the scene; the bake stores a transfer matrix at
    each of its probes, which lights the dynamic objects inside it with the static scene's shadows and bounces"""
    bl_idname = "prt.add_probe_volume"
    bl_label = "Add Probe Volume"
    bl_options = {"REGISTER", "UNDO"}

    @classmethod
    def poll(cls, context):
        return context.mode == "OBJECT"

    def execute(self, context):
        volume = bpy.data.objects.new("PRT Probe Volume", None)
        volume.empty_display_type = "CUBE"
        volume.location = context.scene.cursor.location
        setattr(volume, OBJECT_PREFIX + spec.PROBE_VOLUME.name, True)
        context.collection.objects.link(volume)
        for ob in context.selected_objects:
            ob.select_set(False)
        volume.select_set(True)
        context.view_layer.objects.active = volume
        return {"FINISHED"}


class PRT_OT_export_gltf(bpy.types.Operator, ExportHelper):
    """Export the visible baked meshes and the camera as glTF binary: transfer rotated into glTF's frame and packed
    for the profile, the SH lights in the extras, the colours under the current lights as COLOR_0"""
    bl_idname = "prt.export_gltf"
    bl_label = "Export glTF"
    filename_ext = ".glb"
    filter_glob: bpy.props.StringProperty(default="*.glb", options={"HIDDEN"})
    profile: bpy.props.EnumProperty(name="Profile", items=[
        ("web", "Web", "WebGL's budget of 12 VEC4 attributes; beyond it a float data texture"),
        ("godot", "Godot", "CUSTOM0-3 only (16 floats); beyond it the export is refused"),
        ("generic", "Generic", "As many VEC4 attributes as the order needs")], default="web")

    @classmethod
    def poll(cls, context):
        return context.mode == "OBJECT" and bool(storage.baked_objects(context.scene.objects))

    def execute(self, context):
        try:
            done = gltf.export(context.scene, self.filepath, self.profile)
        except InputError as problem:
            self.report({"ERROR"}, str(problem))
            return {"CANCELLED"}
        for note in done["notes"]:
            self.report({"WARNING"}, note)
        self.report({"INFO"}, f"PRT: wrote {done['path']} ({len(done['objects'])} objects, {self.profile})")
        return {"FINISHED"}


classes = (PRT_OT_bake, PRT_OT_clear, PRT_OT_add_probe_volume, PRT_OT_export_gltf)

register, unregister = bpy.utils.register_classes_factory(classes)
