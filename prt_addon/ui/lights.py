"""The SH lights' list, add and remove operators, and the Lights and Display panels of the sidebar tab "PRT". The
lights and display switches are the scene's saved settings (blender.schema); what they mean as light is
blender.lights'.
"""

import math

import bpy
from bpy.props import EnumProperty, StringProperty

from ..blender.handlers import engine
from ..blender.lights import environment_image, found_sun, scene_fidelity
from ..blender.registration import classes_and_properties
from ..blender.schema import KINDS, add_light
from .heatmaps import draw_legend
from .panels import SidebarPanel


class PRT_UL_lights(bpy.types.UIList):
    def draw_item(self, context, layout, data, item, icon, active_data, active_property, index=0, flt_flag=0):
        kind_icon = next(entry[3] for entry in KINDS if entry[0] == item.kind)
        row = layout.row(align=True)
        row.prop(item, "name", text="", emboss=False, icon=kind_icon)
        row.prop(item, "use", text="")


class PRT_OT_light_add(bpy.types.Operator):
    """Add an SH light to the scene"""
    bl_idname = "prt.light_add"
    bl_label = "Add SH Light"
    bl_options = {"REGISTER", "UNDO"}

    kind: EnumProperty(name="Kind", items=KINDS, default="SUN")

    def execute(self, context):
        add_light(context.scene, self.kind)
        return {"FINISHED"}


class PRT_OT_light_remove(bpy.types.Operator):
    """Remove the active SH light"""
    bl_idname = "prt.light_remove"
    bl_label = "Remove SH Light"
    bl_options = {"REGISTER", "UNDO"}

    @classmethod
    def poll(cls, context):
        return 0 <= context.scene.prt_active_light < len(context.scene.prt_lights)

    def execute(self, context):
        scene = context.scene
        scene.prt_lights.remove(scene.prt_active_light)
        scene.prt_active_light = min(scene.prt_active_light, len(scene.prt_lights) - 1)
        scene.update_tag()
        return {"FINISHED"}


class PRT_PT_lights(SidebarPanel, bpy.types.Panel):
    """The original program's light driver: a list of lights (its keys 1-8), the active one's θ and φ and settings."""
    bl_label = "Lights"
    bl_idname = "PRT_PT_lights"

    def draw(self, context):
        layout = self.layout
        scene = context.scene
        row = layout.row()
        row.template_list("PRT_UL_lights", "", scene, "prt_lights", scene, "prt_active_light", rows=3)
        column = row.column(align=True)
        column.operator_menu_enum("prt.light_add", "kind", icon="ADD", text="")
        column.operator("prt.light_remove", icon="REMOVE", text="")
        if not 0 <= scene.prt_active_light < len(scene.prt_lights):
            layout.label(text="Add a light to relight the baked meshes", icon="INFO")
            return
        layout.operator("prt.drive_lights", icon="VIEW_PAN")  # the original program's keys in the viewport
        layout.use_property_split = True
        self._draw_light(layout, scene, scene.prt_lights[scene.prt_active_light])

    @staticmethod
    def _draw_light(layout, scene, light):
        layout.prop(light, "kind")
        if light.kind == "SUN":
            layout.prop(light, "sun_object")
            column = layout.column(align=True)
            column.enabled = light.sun_object is None
            column.prop(light, "theta", slider=True)
            column.prop(light, "phi", slider=True)
            column.prop(light, "angular_radius")
        elif light.kind == "ENVIRONMENT":
            layout.template_ID(light, "image", open="image.open")
            if environment_image(light, scene) is None:
                layout.label(text="No usable image: pick one, or give the World an Environment Texture",
                             icon="ERROR")
            layout.prop(light, "rotation")
            layout.prop(light, "split_sun")
            if light.split_sun:
                _draw_found_sun(layout, light, scene)
        layout.prop(light, "colour")
        layout.prop(light, "strength")


def _draw_found_sun(layout, light, scene):
    found = found_sun(light, scene)
    column = layout.column(align=True)
    if found is None:
        column.label(text="No compact strong sun in this image: PRT carries all of it", icon="INFO")
        return
    x, y, z = found.direction
    irradiance = ", ".join(f"{c:.3g}" for c in found.irradiance)
    column.label(text=f"Sun at θ {math.degrees(math.acos(max(-1.0, min(1.0, z)))):.1f}°, "
                      f"φ {math.degrees(math.atan2(y, x)):.1f}° (in the image)", icon="LIGHT_SUN")
    column.label(text=f"Radius {math.degrees(found.angular_radius):.2f}°, irradiance ({irradiance})")
    column.label(text=f"{100 * found.share:.0f} % of the image's light, drawn by "
                      f"{light.sun_lamp.name if light.sun_lamp else 'no lamp yet'}")


class PRT_OT_analyse_lights(bpy.types.Operator):
    """How well each SH order carries the scene's lights: projection and predicted shading error per order"""
    bl_idname = "prt.analyse_lights"
    bl_label = "Analyse Lights"
    bl_options = {"REGISTER"}

    def execute(self, context):
        fidelity = scene_fidelity(context.evaluated_depsgraph_get().scene_eval, context.scene.prt_bake.order_target)
        context.window_manager.prt_light_fidelity = "\n".join(fidelity.table())
        self.report({"INFO"}, f"PRT lights: order {fidelity.recommended} recommended")
        return {"FINISHED"}


class PRT_PT_light_fidelity(SidebarPanel, bpy.types.Panel):
    """The error of each order from the lights alone, and the order the Bake panel's From Lights picks."""
    bl_label = "Order from Lights"
    bl_idname = "PRT_PT_light_fidelity"
    bl_parent_id = "PRT_PT_lights"
    bl_options = {"DEFAULT_CLOSED"}

    def draw(self, context):
        layout = self.layout
        layout.operator("prt.analyse_lights", icon="GRAPH")
        column = layout.column(align=True)
        for line in context.window_manager.prt_light_fidelity.splitlines():
            column.label(text=line)


class PRT_PT_display(SidebarPanel, bpy.types.Panel):
    """The original program's F1/F2 (own materials or PRT), T (albedo texture), N and L (normals, light directions)."""
    bl_label = "Display"
    bl_idname = "PRT_PT_display"
    bl_parent_id = "PRT_PT_lights"

    def draw(self, context):
        layout = self.layout
        layout.use_property_split = True
        display = context.scene.prt_display
        layout.prop(display, "show_prt", toggle=True, icon="SHADING_RENDERED")
        layout.prop(display, "mode")
        draw_legend(layout, display.mode)
        column = layout.column()
        column.enabled = display.show_prt and display.mode == "SHADED"
        column.prop(display, "use_albedo")
        layout.prop(display, "window")
        if display.window == "auto":
            for order, (strength, negative) in sorted(engine.auto_window.items()):
                layout.label(text=f"Order {order}: strength {strength:.2f} (Hanning 1), {100 * negative:.1f} % "
                                  f"negative")
        column = layout.column(heading="Overlays")
        column.prop(display, "show_normals")
        column.prop(display, "show_light_directions")


classes = (PRT_UL_lights, PRT_OT_light_add, PRT_OT_light_remove,
           PRT_OT_analyse_lights, PRT_PT_lights, PRT_PT_light_fidelity, PRT_PT_display)


register, unregister = classes_and_properties(classes, [
    (bpy.types.WindowManager, "prt_light_fidelity", StringProperty()),  # the last analysis, a line per order
])
