# A bundled PRT bake preset: its values are core/presets.py's, the same that `prt bake --preset final` applies.
import bpy
bpy.ops.prt.bake_preset(preset="final")
