"""Stale bakes from the sidebar: Check (what changed since each bake) and Bake Stale (rebake only that), and the
Stored Bake panel's status line.

The status is computed on demand, by Check, not on redraw: a fingerprint reads every visible mesh, too slow for a
redraw in a large scene, and depsgraph updates cannot tell an edit from the relighting's own colour writes (every
light change tags the baked meshes), so a cache cleared by them would be cleared by every light change. The panel
shows the last Check's answer with its time, for as long as the bake it checked is the stored one.
"""

import time

import bpy
from bpy.props import CollectionProperty, StringProperty

from ..blender import probe_volumes, storage
from ..blender.fingerprint import stale_line, stale_receivers, stale_volumes
from ..blender.registration import classes_and_properties
from .operators import BakeJob


class PRT_PG_stale_check(bpy.types.PropertyGroup):
    """One object's answer from the last Check (`name` from PropertyGroup; window-manager level: never saved)."""
    bake_id: StringProperty()  # the bake it was checked against
    changes: StringProperty()  # what changed, comma-separated; empty: up to date
    checked: StringProperty()  # local time of the check


class PRT_OT_check_stale(bpy.types.Operator):
    """Check which visible meshes' bakes and probe volumes' probes are out of date, and what changed since
    (geometry, transform, occluders, materials, settings; a volume's placement, resolution, static scene)"""
    bl_idname = "prt.check_stale"
    bl_label = "Check"
    bl_options = {"REGISTER"}

    @classmethod
    def poll(cls, context):
        return context.mode == "OBJECT"

    def execute(self, context):
        settings = context.scene.prt_bake.to_settings()
        baked = storage.baked_objects(context.view_layer.objects)
        volumes = {name: words for name, words in stale_volumes(context, settings).items()
                   if stored_bake_id(context.scene.objects[name])}
        if not baked and not volumes:
            self.report({"INFO"}, "no visible mesh or probe volume has a PRT bake")
            return {"CANCELLED"}
        changed = stale_receivers(context, settings, [ob.name for ob in baked]) if baked else {}
        record_checks(context.window_manager.prt_stale_checks, changed | volumes)
        self.report({"INFO"}, stale_line(changed, volumes))
        return {"FINISHED"}


def stored_bake_id(ob) -> str:
    """The id of the object's stored bake: a mesh's, or a probe volume's probes'; "" without one."""
    if probe_volumes.is_probe_volume(ob):
        return probe_volumes.bake_id(ob) or ""
    meta = ob.data.get(storage.METADATA_KEY) if ob.type == "MESH" else None
    return "" if meta is None else meta.get("bake_id", "")


def record_checks(checks, changed: dict):
    checks.clear()
    now = time.strftime("%H:%M:%S")
    for name, words in changed.items():
        entry = checks.add()
        entry.name, entry.changes, entry.checked = name, ", ".join(words), now
        entry.bake_id = stored_bake_id(bpy.data.objects[name])


class PRT_OT_bake_stale(BakeJob, bpy.types.Operator):
    """Rebake only the receivers (selected meshes, else visible meshes) whose geometry, transform, occluders,
    materials or bake settings changed since their bake, or that have none, and the visible probe volumes whose
    placement, resolution, static scene or settings changed; the others keep their bake exactly"""
    bl_idname = "prt.bake_stale"
    bl_label = "Bake Stale"

    def make_job(self, context):
        settings = context.scene.prt_bake.to_settings()
        changed, volumes = stale_receivers(context, settings), stale_volumes(context, settings)
        self.report({"INFO"}, stale_line(changed, volumes))
        stale = [name for name, words in changed.items() if words]
        stale_probes = [name for name, words in volumes.items() if words]
        return self.checked_bake(context, stale, stale_probes) if stale or stale_probes else None


def draw_status(layout, context, ob):
    """The last Check's answer for the object's stored bake (a mesh's, or a probe volume's), and the Check
    button."""
    check = context.window_manager.prt_stale_checks.get(ob.name)
    row = layout.row()
    if check is None or check.bake_id != stored_bake_id(ob):
        row.label(text="Status not checked", icon="QUESTION")
    elif check.changes:
        row.label(text=f"Stale: {check.changes} ({check.checked})", icon="ERROR")
    else:
        row.label(text=f"Up to date ({check.checked})", icon="CHECKMARK")
    row.operator("prt.check_stale", icon="VIEWZOOM")


classes = (PRT_PG_stale_check, PRT_OT_check_stale, PRT_OT_bake_stale)

register, unregister = classes_and_properties(classes, [
    (bpy.types.WindowManager, "prt_stale_checks", CollectionProperty(type=PRT_PG_stale_check)),
])
