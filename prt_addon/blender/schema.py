"""The settings PRT saves in the file: the scene's bake settings (`prt_bake`), SH lights (`prt_lights`,
`prt_active_light`), display switches (`prt_display`) and validation settings (`prt_validate`), and each object's
storage choice (`prt_storage`, `prt_resolution`, ...), dynamic object (`prt_dynamic`,
`prt_probe_light`) and probe volume (`prt_probe_volume`, `prt_probe_resolution`).
The command line, the checks and the interface all read them, so they register on their own, without any panel or
operator (register, unregister).

The bake settings' properties are made from core.settings, the one definition the command line also reads. Every
light and display property is animatable and drivable, and has an update callback: Blender then tags the scene when
it is set from Python too (not only from the UI), so the relighting handler (blender.handlers) sees the change.
"""

import math

import bpy
from bpy.props import (BoolProperty, CollectionProperty, EnumProperty, FloatProperty, FloatVectorProperty,
                       IntProperty, IntVectorProperty, PointerProperty, StringProperty)

from ..core import settings as spec
from ..core.bake import BakeSettings
from .heatmaps import SHADED
from .lights import scene_fidelity, sync_sun_lamps
from .registration import classes_and_properties
from .texel_bake import OBJECT_PREFIX
from .validation import DEFAULT_PASSES, DEFAULT_SAMPLES, REFERENCES

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
DISPLAY_MODES = [
    (SHADED, "Shaded", "The PRT colours under the SH lights"),
    ("ERROR", "Estimated Error", "Heatmap of the bake's estimated relative error: where more rays would help"),
    ("DIFFERENCE", "Difference from Cycles", "Heatmap of the last validation's error against Cycles "
                                             "(the Validation panel's button stores it)"),
    ("RULE", "Decided by Rule", "Where the bake decided a point by rule instead of measuring it with rays (lying "
                                "on a surface, touching one at an angle, normal against its face): where to look "
                                "when it disagrees with Cycles"),
]


def setting_property(setting: spec.Setting, **extra):
    """The Blender property for one setting: its label, description, default and range (and `extra` arguments,
    e.g. an update callback)."""
    common = {"name": setting.label, "description": setting.description, "default": setting.default, **extra}
    if isinstance(setting.default, bool):
        return BoolProperty(**common)
    if isinstance(setting.default, tuple):
        return IntVectorProperty(size=len(setting.default), min=setting.minimum, max=setting.maximum, **common)
    if setting.choices:
        return EnumProperty(items=list(setting.choices), **common)
    if isinstance(setting.default, float):
        return FloatProperty(min=setting.minimum, max=setting.maximum, precision=5, step=0.1, **common)
    limits = {"min": setting.minimum} | ({"max": setting.maximum} if setting.maximum is not None else {})
    return IntProperty(**limits, **common)


class PRT_PG_bake_settings(bpy.types.PropertyGroup):
    __annotations__ = {setting.name: setting_property(setting)
                       for setting in spec.BAKE + (spec.WORKERS, spec.ORDER_TARGET)}
    __annotations__["auto_bounces"] = BoolProperty(
        name="Auto Bounces", description="Bounce until the rest of the series is below the tolerance", default=True)
    __annotations__["order_from_lights"] = BoolProperty(
        name="From Lights", default=False,
        description="Bake at the lowest order whose predicted shading error under the scene's SH lights meets the "
                    "target (the Lights panel's Order from Lights); without SH lights, the Order above")

    def to_settings(self) -> BakeSettings:
        values = {setting.name: getattr(self, setting.name) for setting in spec.BAKE}
        if self.auto_bounces:
            values["bounces"] = None
        if self.order_from_lights and self.id_data.prt_lights:
            values["order"] = scene_fidelity(self.id_data, self.order_target).recommended
        return BakeSettings(**values)

    def set_values(self, values: dict):
        """Sets the named settings (a preset's); bounces None means auto, as in BakeSettings."""
        for name, value in values.items():
            if name == "bounces":
                self.auto_bounces = value is None
                if value is None:
                    continue
            setattr(self, name, value)


def _tag_scene(self, context):
    self.id_data.update_tag()


def _tag_object(self, context):
    """Tags the object, from Python too, so the relighting (blender.handlers) shades it again."""
    self.update_tag()


def _split_sun_changed(self, context):
    sync_sun_lamps(self.id_data, create=True)  # the lamp is made or removed here, never in a handler
    self.id_data.update_tag()


def _display_mode_changed(display, context):
    """A heatmap shows through the display materials, so choosing one switches the PRT display on."""
    if display.mode != SHADED and not display.show_prt:
        display.show_prt = True
    display.id_data.update_tag()


def _is_sun_object(self, ob):
    return ob.type == "LIGHT" and ob.data.type == "SUN"


class PRT_PG_light(bpy.types.PropertyGroup):
    """One SH light; `name` (from PropertyGroup) is what the list shows. What it means as light is blender.lights'."""
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


def add_light(scene, kind: str):
    """A new SH light of `kind` (KINDS), named for it and made the active one: the sidebar's + and the commands'
    light options add lights this way."""
    light = scene.prt_lights.add()
    light.kind = kind
    light.name = next(entry[1] for entry in KINDS if entry[0] == kind)
    scene.prt_active_light = len(scene.prt_lights) - 1
    return light


class PRT_PG_display(bpy.types.PropertyGroup):
    show_prt: BoolProperty(
        name="PRT Display", default=False, update=_tag_scene,
        description="Show the PRT colours through display materials (the scene's own materials are kept "
                    "and put back when this is off)")
    mode: EnumProperty(name="Show", items=DISPLAY_MODES, default=SHADED, update=_display_mode_changed,
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


class PRT_PG_validate_settings(bpy.types.PropertyGroup):
    samples: IntProperty(name="Cycles Samples", description="Cycles samples per pass",
                         default=DEFAULT_SAMPLES, min=1, soft_max=4096)
    passes: IntProperty(name="Passes", description="Cycles passes with different seeds: their spread measures "
                        "Cycles' own noise, which is taken out of the comparison",
                        default=DEFAULT_PASSES, min=2, max=64)
    reference: EnumProperty(name="Against", default=REFERENCES[0], items=[
        (REFERENCES[0], "Band-Limited Light", "Cycles under the light PRT uses: PRT's own error"),
        (REFERENCES[1], "Real Light", "Also Cycles under the scene's lights as they are (environment images, Sun "
                                      "lamps): the total error and what band-limiting costs (twice the Cycles time)"),
    ])


classes = (PRT_PG_bake_settings, PRT_PG_light, PRT_PG_display, PRT_PG_validate_settings)

OBJECT_STORAGE = [(bpy.types.Object, OBJECT_PREFIX + setting.name, setting_property(setting))
                  for setting in spec.TEXEL] + [
    (bpy.types.Object, OBJECT_PREFIX + "uv_map", StringProperty(
        name="Lightmap UV Map", description="The UV map its texels follow; empty: PRT's own 'PRT Lightmap' map")),
    (bpy.types.Object, OBJECT_PREFIX + "new_uv_map", BoolProperty(
        name="Add Lightmap UV Map", default=True, description="Without a chosen UV map, PRT may add its own "
        "'PRT Lightmap' map (Lightmap Pack); the object's own UV maps are never changed")),
    (bpy.types.Object, OBJECT_PREFIX + spec.PROBE_LIGHT.name, setting_property(spec.PROBE_LIGHT, update=_tag_object)),
] + [(bpy.types.Object, OBJECT_PREFIX + setting.name, setting_property(setting))
     for setting in (spec.DYNAMIC, spec.PROBE_VOLUME, spec.PROBE_RESOLUTION)]

register, unregister = classes_and_properties(classes, [
    (bpy.types.Scene, "prt_bake", PointerProperty(type=PRT_PG_bake_settings)),
    (bpy.types.Scene, "prt_lights", CollectionProperty(type=PRT_PG_light)),
    (bpy.types.Scene, "prt_active_light", IntProperty(name="Active SH Light", default=0, min=0)),
    (bpy.types.Scene, "prt_display", PointerProperty(type=PRT_PG_display)),
    (bpy.types.Scene, "prt_validate", PointerProperty(type=PRT_PG_validate_settings)),
] + OBJECT_STORAGE)
