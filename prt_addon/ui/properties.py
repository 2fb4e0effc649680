"""Settings the artist edits, stored in the scene so they save with the file."""

import bpy
from bpy.props import EnumProperty, FloatProperty, IntProperty, PointerProperty

from ..core import bake
from .registration import classes_and_properties


class PRT_PG_bake_settings(bpy.types.PropertyGroup):
    mode: EnumProperty(
        name="Mode",
        items=[
            ("unshadowed", "Unshadowed", "Cosine term only: exact, instant, no rays"),
            ("shadowed", "Shadowed", "Cosine term and visibility from ray casts: soft shadows"),
            ("interreflected", "Interreflected",
             "Shadows plus light bounced between surfaces, coloured by their albedo (no extra rays)"),
        ],
        default="shadowed",
    )
    order: IntProperty(name="Order", description="SH bands (order n stores n² coefficients)",
                       default=4, min=1, max=bake.MAX_ORDER)
    samples: IntProperty(name="Samples", description="Rays per vertex (first round when a target error is set)",
                         default=256, min=bake.MIN_SAMPLES, max=bake.MAX_SAMPLES)
    target_error: FloatProperty(
        name="Target Error",
        description="Keep sampling each vertex until its estimated relative error is below this (0: off)",
        default=0.0, min=0.0, max=1.0, precision=4, step=0.1)
    max_samples: IntProperty(name="Max Samples", description="Ray budget per vertex when a target error is set",
                             default=16384, min=bake.MIN_SAMPLES, max=bake.MAX_SAMPLES)
    workers: IntProperty(name="Workers", description="Processes that cast rays in parallel",
                         default=1, min=1, max=64)
    seed: IntProperty(name="Seed", description="Random seed: the same seed gives the same bake", default=0, min=0)
    auto_bounces: bpy.props.BoolProperty(
        name="Auto Bounces", description="Bounce until the rest of the series is below the tolerance", default=True)
    bounces: IntProperty(name="Bounces", description="Interreflection bounces", default=2, min=0, max=1000)
    bounce_tolerance: FloatProperty(name="Tolerance", description="Relative error left by 'auto' bounces",
                                    default=1e-3, min=1e-8, max=0.5, precision=5)

    def to_settings(self) -> bake.BakeSettings:
        return bake.BakeSettings(order=self.order, mode=self.mode, samples=self.samples,
                                 target_error=self.target_error, max_samples=self.max_samples, seed=self.seed,
                                 bounces=None if self.auto_bounces else self.bounces,
                                 bounce_tolerance=self.bounce_tolerance)


class PRT_PG_bake_status(bpy.types.PropertyGroup):
    """What the panel shows while a modal job (a bake, a validation) runs (window-manager level: never saved)."""
    running: bpy.props.BoolProperty(default=False)
    fraction: FloatProperty(default=0.0, min=0.0, max=1.0, subtype="FACTOR")
    text: bpy.props.StringProperty(default="")


classes = (PRT_PG_bake_settings, PRT_PG_bake_status)


register, unregister = classes_and_properties(classes, [
    (bpy.types.Scene, "prt_bake", PointerProperty(type=PRT_PG_bake_settings)),
    (bpy.types.WindowManager, "prt_bake_status", PointerProperty(type=PRT_PG_bake_status)),
])
