"""Bake presets through Blender's preset system: a menu (PRT_MT_bake_presets) with the bundled Draft, Production and
Final and the artist's own presets, added and removed with + and − (AddPresetBase writes them to the user's
scripts/presets/prt/bake). The bundled files only call PRT_OT_bake_preset, which applies core.presets' values, the
same the command line's --preset applies."""

import os

import bpy
from bl_operators.presets import AddPresetBase
from bpy.props import EnumProperty

from ..core import presets

PRESET_SUBDIR = "prt/bake"
BUNDLED = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))  # holds presets/prt/bake
PRESET_ITEMS = [(name, presets.label(name), preset.description) for name, preset in presets.PRESETS.items()]


class PRT_MT_bake_presets(bpy.types.Menu):
    bl_label = "Bake Presets"
    preset_subdir = PRESET_SUBDIR
    preset_operator = "script.execute_preset"
    preset_add_operator = "prt.bake_preset_add"
    draw = bpy.types.Menu.draw_preset


class PRT_OT_bake_preset_add(AddPresetBase, bpy.types.Operator):
    """Add or remove a PRT bake preset"""
    bl_idname = "prt.bake_preset_add"
    bl_label = "Add Bake Preset"
    preset_menu = "PRT_MT_bake_presets"
    preset_subdir = PRESET_SUBDIR
    preset_defines = ["settings = bpy.context.scene.prt_bake"]
    preset_values = [f"settings.{setting.name}" for setting in presets.FIELDS] + ["settings.auto_bounces"]

    def remove(self, context, filepath):
        """Removes the artist's own presets only: the bundled ones come back with every install anyway."""
        if os.path.commonpath([BUNDLED, os.path.abspath(filepath)]) == BUNDLED:
            raise PermissionError(f"{os.path.basename(filepath)} is a bundled preset")
        os.remove(filepath)


class PRT_OT_bake_preset(bpy.types.Operator):
    """Set the bake settings to a bundled preset"""
    bl_idname = "prt.bake_preset"
    bl_label = "Apply Bake Preset"
    bl_options = {"REGISTER", "UNDO", "INTERNAL"}

    preset: EnumProperty(items=PRESET_ITEMS)

    def execute(self, context):
        context.scene.prt_bake.set_values(presets.preset_values(self.preset))
        return {"FINISHED"}


def draw_presets(layout):
    """The preset menu with + and −, as Blender's own preset rows."""
    row = layout.row(align=True)
    row.menu("PRT_MT_bake_presets", text=PRT_MT_bake_presets.bl_label)
    row.operator("prt.bake_preset_add", text="", icon="ADD")
    row.operator("prt.bake_preset_add", text="", icon="REMOVE").remove_active = True


classes = (PRT_MT_bake_presets, PRT_OT_bake_preset_add, PRT_OT_bake_preset)
_register_classes, _unregister_classes = bpy.utils.register_classes_factory(classes)


def register():
    _register_classes()
    bpy.utils.register_preset_path(BUNDLED)


def unregister():
    bpy.utils.unregister_preset_path(BUNDLED)
    _unregister_classes()
