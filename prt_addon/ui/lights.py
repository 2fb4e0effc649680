"""SH lights and display switches, stored in the scene, with their list, add and remove operators, and the Lights
and Display panels of the sidebar tab "PRT". What the settings mean as light is blender.lights'.

Every property is animatable and drivable. Each one has an update callback: Blender then tags the scene when it
is set from Python too (not only from the UI), so the depsgraph handler sees the change.
"""

import math

import bpy
from bpy.props import (BoolProperty, CollectionProperty, EnumProperty, FloatProperty, FloatVectorProperty,
                       IntProperty, PointerProperty, StringProperty)

from ..blender.lights import environment_image, found_sun, scene_fidelity, sync_sun_lamps
from .handlers import engine
from .heatmaps import DISPLAY_MODES, draw_legend, mode_changed
from .panels import SidebarPanel
from .registration import classes_and_properties

KINDS = [
    ("SUN", "Sun", "A disc of light from one direction, optionally following a Sun light object", "LIGHT_SUN", 0),
    ("ENVIRONMENT", "Environment", "An equirectangular image around the scene (default: the World's)", "WORLD", 1),
    ("SKY", "Sky", "The same light from every direction", "LIGHT_HEMI", 2),
]
WINDOWS = [
    ("auto", "Auto", "The gentlest taper, up to Hanning, that leaves at most 1 % of the summed light negative"),
    ("none", "None", "Full sharpness; sharp lights ring (the negative values are clamped at display)"),
    ("hanning", "Hanning", "Tapers high bands strongly: softest, no visible ringing"),
    ("lanczos", "Lanczos", "Tapers high bands gently: between sharp and soft"),
]


def _tag_scene(self, context):
    self.id_data.update_tag()


def _split_sun_changed(self, context):
    sync_sun_lamps(self.id_data, create=True)  # the lamp is made or removed here, never in a handler
    self.id_data.update_tag()


def _is_sun_object(self, ob):
    return ob.type == "LIGHT" and ob.data.type == "SUN"


class PRT_PG_light(bpy.types.PropertyGroup):
    """One SH light; `name` (from PropertyGroup) is what the list shows."""
    kind: EnumProperty(name="Kind", items=KINDS, default="SUN", update=_tag_scene)
    use: BoolProperty(name="Enabled", description="Include this light in the sum", default=True,
                      update=_tag_scene)
    colour: FloatVectorProperty(name="Colour", subtype="COLOR", size=3, min=0.0, soft_max=1.0,
                                default=(1.0, 1.0, 1.0), update=_tag_scene)
    strength: FloatProperty(
        name="Strength", min=0.0, soft_max=10.0, default=1.0, update=_tag_scene,
        description="Sun: irradiance on a surface facing it (as Blender's Sun Strength). "
                    "Environment: multiplies the image. Sky: radiance")
    theta: FloatProperty(name="θ", description="Angle of the light from the zenith (+Z)", subtype="ANGLE",
                         min=0.0, max=math.pi, default=math.radians(35.0), update=_tag_scene)
    phi: FloatProperty(name="φ", description="Azimuth of the light, from +X towards +Y", subtype="ANGLE",
                       soft_min=-math.pi, soft_max=math.pi, default=math.radians(-60.0), update=_tag_scene)
    sun_object: PointerProperty(
        name="Sun Object", type=bpy.types.Object, poll=_is_sun_object, update=_tag_scene,
        description="Follow this Sun light: its rotation gives the direction and its Angle the disc size")
    angular_radius: FloatProperty(
        name="Radius", description="Angular radius of the sun's disc (a linked Sun's Angle / 2)",
        subtype="ANGLE", min=0.0, max=math.pi / 2, default=math.radians(2.5), update=_tag_scene)
    image: PointerProperty(name="Image", type=bpy.types.Image, update=_tag_scene,
                           description="Equirectangular image; empty: the World's Environment Texture")
    rotation: FloatVectorProperty(name="Rotation", subtype="EULER", size=3, update=_tag_scene,
                                  description="Turns the environment: what was along d comes from R·d")
    split_sun: BoolProperty(
        name="Split Off Sun", default=False, update=_split_sun_changed,
        description="Find a compact strong sun in the image, take it out of what PRT carries and let a Blender Sun "
                    "lamp draw it, with sharp shadows in EEVEE")
    sun_lamp: PointerProperty(name="Sun Lamp", type=bpy.types.Object,
                              description="The Sun lamp that draws the sun split off this environment")


class PRT_PG_display(bpy.types.PropertyGroup):
    show_prt: BoolProperty(
        name="PRT Display", default=False, update=_tag_scene,
        description="Show the PRT colours through display materials (the scene's own materials are kept "
                    "and put back when this is off)")
    mode: EnumProperty(name="Show", items=DISPLAY_MODES, default="SHADED", update=mode_changed,
                       description="The PRT colours, or a heatmap of where the bake is inaccurate")
    use_albedo: BoolProperty(name="Albedo Texture", default=True, update=_tag_scene,
                             description="Multiply the PRT colour by each material's Base Color texture")
    window: EnumProperty(name="Window", items=WINDOWS, default="auto", update=_tag_scene,
                         description="Taper high SH bands of the summed light against ringing")
    show_normals: BoolProperty(name="Normals", description="Draw the vertex normals of baked meshes",
                               default=False, update=_tag_scene)
    show_light_directions: BoolProperty(
        name="Light Directions", description="Draw a line from the 3D cursor towards each sun",
        default=False, update=_tag_scene)


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
        scene = context.scene
        light = scene.prt_lights.add()
        light.kind = self.kind
        light.name = next(entry[1] for entry in KINDS if entry[0] == self.kind)
        scene.prt_active_light = len(scene.prt_lights) - 1
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


classes = (PRT_PG_light, PRT_PG_display, PRT_UL_lights, PRT_OT_light_add, PRT_OT_light_remove,
           PRT_OT_analyse_lights, PRT_PT_lights, PRT_PT_light_fidelity, PRT_PT_display)


register, unregister = classes_and_properties(classes, [
    (bpy.types.Scene, "prt_lights", CollectionProperty(type=PRT_PG_light)),
    (bpy.types.Scene, "prt_active_light", IntProperty(name="Active SH Light", default=0, min=0)),
    (bpy.types.Scene, "prt_display", PointerProperty(type=PRT_PG_display)),
    (bpy.types.WindowManager, "prt_light_fidelity", StringProperty()),  # the last analysis, a line per order
])
