"""Settings the artist edits, stored in the scene so they save with the file, and the state of a running job.

The bake settings' properties are made from core.settings, the one definition the command line also reads."""

import bpy
from bpy.props import BoolProperty, EnumProperty, FloatProperty, IntProperty, PointerProperty, StringProperty

from ..blender.lights import scene_fidelity
from ..core import settings as spec
from ..core.bake import BakeSettings
from .registration import classes_and_properties


def setting_property(setting: spec.Setting):
    """The Blender property for one setting: its label, description, default and range."""
    common = {"name": setting.label, "description": setting.description, "default": setting.default}
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


class PRT_PG_job_status(bpy.types.PropertyGroup):
    """What a panel shows while a modal job (a bake, a validation) runs (window-manager level: never saved)."""
    running: BoolProperty(default=False)
    fraction: FloatProperty(default=0.0, min=0.0, max=1.0, subtype="FACTOR")
    text: StringProperty(default="")


classes = (PRT_PG_bake_settings, PRT_PG_job_status)


# Each object's storage choice (blender.texel_bake reads them as prt_storage, prt_resolution, ...).
OBJECT_STORAGE = [(bpy.types.Object, "prt_" + setting.name, setting_property(setting)) for setting in spec.TEXEL] + [
    (bpy.types.Object, "prt_uv_map", StringProperty(
        name="Lightmap UV Map", description="The UV map its texels follow; empty: PRT's own 'PRT Lightmap' map")),
    (bpy.types.Object, "prt_new_uv_map", BoolProperty(
        name="Add Lightmap UV Map", default=True, description="Without a chosen UV map, PRT may add its own "
        "'PRT Lightmap' map (Lightmap Pack); the object's own UV maps are never changed")),
]

register, unregister = classes_and_properties(classes, [
    (bpy.types.Scene, "prt_bake", PointerProperty(type=PRT_PG_bake_settings)),
    (bpy.types.WindowManager, "prt_bake_status", PointerProperty(type=PRT_PG_job_status)),
] + OBJECT_STORAGE)
