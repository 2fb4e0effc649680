"""Operators: the bake (modal in the UI, synchronous in background mode) and clearing a bake."""

import bpy

from .. import baking, mesh_data
from ..core.progress import format_duration


def _report_outcome(operator, scene_bake):
    for problem in scene_bake.problems + scene_bake.notes:
        operator.report({"WARNING"}, problem)
    operator.report({"INFO"}, scene_bake.summary.line())


class PRT_OT_bake(bpy.types.Operator):
    """Bake SH transfer into the selected meshes (all visible meshes when none is selected)"""
    bl_idname = "prt.bake"
    bl_label = "Bake PRT"
    bl_options = {"REGISTER", "UNDO"}

    _scene_bake = None
    _timer = None

    @classmethod
    def poll(cls, context):
        status = context.window_manager.prt_bake_status
        return context.mode == "OBJECT" and not status.running

    def _start(self, context):
        settings = context.scene.prt_bake
        try:
            return baking.SceneBake(context, settings.to_settings(), workers=settings.workers)
        except mesh_data.InputError as problem:
            self.report({"ERROR"}, str(problem))
            return None

    def execute(self, context):
        scene_bake = self._start(context)
        if scene_bake is None:
            return {"CANCELLED"}
        try:
            scene_bake.run(log=print)
        except Exception as failure:  # the previous bake is untouched: nothing was written
            self.report({"ERROR"}, f"bake failed, previous data kept: {failure}")
            return {"CANCELLED"}
        _report_outcome(self, scene_bake)
        print(scene_bake.summary.line())
        return {"FINISHED"}

    def invoke(self, context, event):
        if bpy.app.background:
            return self.execute(context)
        self._scene_bake = self._start(context)
        if self._scene_bake is None:
            return {"CANCELLED"}
        wm = context.window_manager
        wm.prt_bake_status.running = True
        wm.prt_bake_status.fraction = 0.0
        wm.progress_begin(0, 1000)
        self._timer = wm.event_timer_add(0.02, window=context.window)
        wm.modal_handler_add(self)
        return {"RUNNING_MODAL"}

    def modal(self, context, event):
        if event.type == "ESC":
            self._scene_bake.cancel()
            self._finish(context)
            self.report({"WARNING"}, "PRT bake cancelled; previous data kept")
            return {"CANCELLED"}
        if event.type != "TIMER":
            return {"PASS_THROUGH"}
        try:
            done = self._scene_bake.step(0.08)
        except Exception as failure:
            self._finish(context)
            self.report({"ERROR"}, f"bake failed, previous data kept: {failure}")
            return {"CANCELLED"}
        progress = self._scene_bake.progress
        status = context.window_manager.prt_bake_status
        status.fraction = progress.fraction
        status.text = f"{100 * progress.fraction:.0f} %, {format_duration(progress.remaining)} left (Esc cancels)"
        context.window_manager.progress_update(int(1000 * progress.fraction))
        context.workspace.status_text_set(f"PRT bake: {status.text}")
        for area in context.screen.areas:
            if area.type == "VIEW_3D":
                area.tag_redraw()
        if not done:
            return {"RUNNING_MODAL"}
        self._scene_bake.store()
        self._finish(context)
        _report_outcome(self, self._scene_bake)
        return {"FINISHED"}

    def _finish(self, context):
        wm = context.window_manager
        if self._timer is not None:
            wm.event_timer_remove(self._timer)
            self._timer = None
        wm.progress_end()
        wm.prt_bake_status.running = False
        context.workspace.status_text_set(None)


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
                mesh_data.check_writable(ob)
            except mesh_data.InputError as problem:
                self.report({"WARNING"}, str(problem))
                continue
            mesh_data.remove_transfer(ob.data)
        return {"FINISHED"}


classes = (PRT_OT_bake, PRT_OT_clear)


def register():
    for cls in classes:
        bpy.utils.register_class(cls)


def unregister():
    for cls in reversed(classes):
        bpy.utils.unregister_class(cls)
