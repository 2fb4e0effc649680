"""The sidebar tab "PRT" in the 3D View: where every PRT panel lives (SidebarPanel), and the Bake panel with the
active object's stored bake, or the active probe volume's probes. The Lights and Display panels are in lights.py,
Validation in validation.py."""

import bpy

from ..blender import layouts, probe_volumes, storage
from ..blender.fingerprint import placement_changes
from ..blender.request import ray_engine_label
from ..core import engines, rules
from .checks import draw_checklist
from .presets import draw_presets
from .stale import draw_status


class SidebarPanel:
    """Where every PRT panel lives: the 3D View's sidebar, tab "PRT"."""
    bl_space_type = "VIEW_3D"
    bl_region_type = "UI"
    bl_category = "PRT"


class PRT_PT_bake(SidebarPanel, bpy.types.Panel):
    bl_label = "Bake"
    bl_idname = "PRT_PT_bake"

    def draw(self, context):
        layout = self.layout
        layout.use_property_split = True
        layout.use_property_decorate = False
        settings = context.scene.prt_bake
        draw_presets(layout)
        layout.prop(settings, "mode")
        row = layout.row(heading="Order")
        row.prop(settings, "order_from_lights")
        column = layout.column()
        column.prop(settings, "order_target" if settings.order_from_lights else "order")
        column = layout.column()
        column.enabled = settings.mode != "unshadowed"
        column.prop(settings, "samples")
        column.prop(settings, "target_error")
        sub = column.column()
        sub.enabled = settings.target_error > 0
        sub.prop(settings, "max_samples")
        column.prop(settings, "workers")
        column.prop(settings, "ray_engine")
        if settings.ray_engine == "auto":
            engine, note = engines.choose("auto")
            column.label(text=f"Casts with {ray_engine_label(engine)}" + (": Embree is not installed" if note else ""),
                         icon="INFO" if note else "NONE")
        column.prop(settings, "seed")
        if settings.mode == "interreflected":
            bounce = layout.column()
            bounce.prop(settings, "auto_bounces")
            bounce.prop(settings, "bounce_tolerance" if settings.auto_bounces else "bounces")
        status = context.window_manager.prt_bake_status
        if status.running:
            layout.progress(factor=status.fraction, type="BAR", text=status.text)
        else:
            row = layout.row(align=True)
            row.operator("prt.bake", icon="RENDER_STILL")
            row.operator("prt.clear", icon="X", text="")
            layout.operator("prt.bake_stale", icon="FILE_REFRESH")
            layout.operator("prt.add_probe_volume", icon="LIGHTPROBE_VOLUME")
            draw_checklist(layout, context)
            layout.operator("prt.export_gltf", icon="EXPORT")


class ActiveMeshPanel(SidebarPanel):
    """A panel about the active object, shown while it is a mesh."""

    @classmethod
    def poll(cls, context):
        ob = context.active_object
        return ob is not None and ob.type == "MESH"


class PRT_PT_storage(ActiveMeshPanel, bpy.types.Panel):
    """Where the active object's transfer is stored: per vertex, per texel, or Auto."""
    bl_label = "Storage"
    bl_idname = "PRT_PT_storage"
    bl_parent_id = "PRT_PT_bake"

    def draw(self, context):
        layout = self.layout
        layout.use_property_split = True
        layout.use_property_decorate = False
        ob = context.active_object
        layout.prop(ob, "prt_storage")
        column = layout.column()
        column.enabled = ob.prt_storage != "vertex"
        column.prop(ob, "prt_resolution")
        sub = column.column()
        sub.enabled = ob.prt_resolution == 0
        sub.prop(ob, "prt_texel_size")
        column.prop_search(ob, "prt_uv_map", ob.data, "uv_layers")
        sub = column.column()
        sub.enabled = not ob.prt_uv_map
        sub.prop(ob, "prt_new_uv_map")
        layout.prop(ob, "prt_dynamic")
        row = layout.row()
        row.enabled = ob.prt_dynamic
        row.prop(ob, "prt_probe_light")


class PRT_PT_bake_info(ActiveMeshPanel, bpy.types.Panel):
    """What is stored on the active object: how, when, and how accurate."""
    bl_label = "Stored Bake"
    bl_idname = "PRT_PT_bake_info"
    bl_parent_id = "PRT_PT_bake"

    def draw(self, context):
        layout = self.layout
        mesh = context.active_object.data
        if storage.METADATA_KEY not in mesh:
            layout.label(text="Not baked", icon="INFO")
            return
        meta = mesh[storage.METADATA_KEY]
        if meta.get("vertex_count") != len(mesh.vertices):
            layout.label(text="Stale: the mesh changed since the bake", icon="ERROR")
        draw_status(layout, context, context.active_object)
        column = layout.column(align=True)
        column.label(text=f"Order {meta['order']}, {meta['mode']}, {meta['samples']} samples")
        if meta.get(storage.DYNAMIC_KEY):
            column.label(text="Dynamic: in its own frame, against itself only")
            column.label(text=f"Lit by the order-{storage.light_order(meta)} light, to order {meta['order']} "
                              f"through probes")
        column.label(text=f"{meta['rays']:,} rays in {meta.get('time_s', 0.0):.1f} s")
        if "ray_engine" in meta:
            column.label(text=f"Cast with {meta['ray_engine']}")
        column.label(text=f"Est. error RMS {meta['est_rms_rel_error']:.4f}, max {meta['est_max_rel_error']:.4f}")
        if meta.get("est_rule_rms_rel_error"):  # the doubt of the points decided by rule, within that RMS
            column.label(text=f"  of which decided by rule {meta['est_rule_rms_rel_error']:.4f}")
        for row in meta.get("error_curve", []):  # what more time bought: the bake's error after each round
            column.label(text=f"  after {row['after']}: {row['seconds']:.1f} s, {row['rays']:,} rays, "
                              f"RMS {row['est_rms_rel_error']:.4f}")
        if "est_interp_rms_rel_error" in meta:
            column.label(text=f"Between vertices RMS {meta['est_interp_rms_rel_error']:.4f}, "
                              f"max {meta['est_interp_max_rel_error']:.4f}")
        described = layouts.stored(mesh).describe(meta)
        if described:
            column.label(text=described)
        decided = meta.get("decided_by_rule")
        if decided:  # where an artist should look first when the bake disagrees with Cycles
            column.label(text="Decided by rule, not rays (Display: Decided by Rule):", icon="ERROR")
            for code, key in rules.KEYS.items():
                if decided.get(key):
                    column.label(text=f"  {decided[key]} {rules.WORDS[code]}")
        if meta.get("inside_another_part"):  # black by rays, as in Cycles: a part hidden in another, or misplaced
            column.label(text=f"{meta['inside_another_part']} points inside another part (black)", icon="ERROR")
        column.label(text=f"Baked {meta['date']}")


class PRT_PT_probe_volume(SidebarPanel, bpy.types.Panel):
    """The active probe volume: its probes per axis and what its bake stored."""
    bl_label = "Probe Volume"
    bl_idname = "PRT_PT_probe_volume"
    bl_parent_id = "PRT_PT_bake"

    @classmethod
    def poll(cls, context):
        return context.active_object is not None and probe_volumes.is_probe_volume(context.active_object)

    def draw(self, context):
        layout = self.layout
        layout.use_property_split = True
        ob = context.active_object
        layout.prop(ob, "prt_probe_resolution")
        meta = ob.get(probe_volumes.METADATA_KEY)
        if meta is None:
            layout.label(text="Not baked", icon="INFO")
            return
        moved = placement_changes(ob)
        if moved:  # told at once, as a mesh's changed vertex count is: it costs a 4 × 4 matrix's digest
            layout.label(text=f"Stale: {', '.join(moved)} since the bake", icon="ERROR")
            layout.label(text="Its probes light from where they were baked")
        draw_status(layout, context, ob)
        column = layout.column(align=True)
        column.label(text=f"Order {meta['order']} light, arriving to order {meta['received_order']}")
        column.label(text=f"{meta['mode'].capitalize()}, {meta['rays']} rays per probe")
        column.label(text=f"{meta['inside_probes']} probes inside geometry, left out")
        column.label(text=f"Est. error max {meta['est_max_error']:.4f}")
        column.label(text=f"Baked {meta['date']}")


classes = (PRT_PT_bake, PRT_PT_storage, PRT_PT_bake_info, PRT_PT_probe_volume)

register, unregister = bpy.utils.register_classes_factory(classes)
