"""The state of a running modal job (a bake, a validation), for the panels' progress bars. It lives at the window
manager's level and is never saved: it describes this session's job, not the file, so it is no part of the saved
settings' schema (blender.schema)."""

import bpy
from bpy.props import BoolProperty, FloatProperty, PointerProperty, StringProperty

from ..blender.registration import classes_and_properties


class PRT_PG_job_status(bpy.types.PropertyGroup):
    """What a panel shows while a modal job runs."""
    running: BoolProperty(default=False)
    fraction: FloatProperty(default=0.0, min=0.0, max=1.0, subtype="FACTOR")
    text: StringProperty(default="")


register, unregister = classes_and_properties((PRT_PG_job_status,), [
    (bpy.types.WindowManager, "prt_bake_status", PointerProperty(type=PRT_PG_job_status)),
])
