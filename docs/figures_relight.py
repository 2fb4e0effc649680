"""relight.png: the demo scene (`prt demo`'s, baked at order 4, shadowed) rendered in EEVEE with its PRT colours,
before and after the sun moves, side by side: the two renders `prt demo` makes, through `prt relight`
(commands.relight.relight_file), the second with the sun turned round to the back (commands.demo.MOVED_SUN).

Printed, and read back by tests/test_figures.py: the floor's brightness where the moved sun puts the torus's
shadow (a disc on the floor below the tube's near side along the sun's ray, linear radiance), after ÷ before, and
the share of the picture whose brightness changed by more than CHANGED of the brightest pixel.
"""

import math
import os

import bpy
import numpy as np

from figures_common import disc_mean, new_figure, read_png, save, show_image
from prt_addon.blender import lights, sample_scenes
from prt_addon.commands.demo import MOVED_SUN, RENDER_SAMPLES
from prt_addon.commands.relight import relight_file
from prt_addon.core import shading
from prt_addon.core.colour import srgb_to_linear

NAME = "relight.png"
RESOLUTION = {"full": (640, 480), "quick": (320, 240)}
SAMPLES = {"full": RENDER_SAMPLES, "quick": 2}
CHANGED = 0.05
TUBE_NEAR = (0.0, -sample_scenes.TORUS_MAJOR_RADIUS, sample_scenes.TORUS_HEIGHT)  # the tube's centre, camera side
DISC = 0.5  # of the tube's radius: the floor measured, well inside its shadow


def make(run) -> str:
    blend = run.demo_blend()
    resolution, samples = run.pick(RESOLUTION), run.pick(SAMPLES)
    renders = {}
    for moved in (False, True):
        aim = {"light_index": 0, "theta_deg": MOVED_SUN[0], "phi_deg": MOVED_SUN[1]} if moved else {}
        path = os.path.join(run.scratch, f"relight_{'after' if moved else 'before'}.png")
        relight_file(blend, path, samples=samples, resolution=resolution, **aim)
        renders[moved] = read_png(path), sun_angles(bpy.context.scene)
    (before, sun_before), (after, sun_after) = renders[False], renders[True]
    scene = bpy.context.scene  # the file as the second render left it: its camera is the renders'
    shadow = floor_shadow(TUBE_NEAR, shading.direction_from_angles(*map(math.radians, MOVED_SUN)))
    ratio = (disc_mean(srgb_to_linear(after), scene, shadow, sample_scenes.TORUS_MINOR_RADIUS, DISC)
             / disc_mean(srgb_to_linear(before), scene, shadow, sample_scenes.TORUS_MINOR_RADIUS, DISC))
    changed = float(np.mean(np.abs(after - before).mean(axis=2) > CHANGED * before.max()))
    print(f"relight: floor in the moved sun's shadow of the torus: after ÷ before {ratio:.3f}")
    print(f"relight: {100 * changed:.1f} % of the pixels changed by more than {100 * CHANGED:g} % of the brightest")

    height, width = before.shape[:2]
    figure = new_figure(2 * width + 40, height + 70)
    left, right = figure.subplots(1, 2)
    show_image(left, before, f"Before: the sun at θ {sun_before[0]:.0f}°, φ {sun_before[1]:.0f}° (the file's)")
    show_image(right, after, f"After: prt relight --light-theta {MOVED_SUN[0]:g} --light-phi {MOVED_SUN[1]:g}")
    figure.suptitle("The demo scene's PRT bake in EEVEE: the sun moves, the shadows follow", fontsize=11)
    return save(figure, run.path(NAME))


def sun_angles(scene) -> tuple[float, float]:
    """θ from the zenith and φ from +X, in degrees, of the scene's first SH light (the demo's sun)."""
    x, y, z = lights.sun_direction(scene.prt_lights[0])
    return math.degrees(math.acos(max(-1.0, min(1.0, z)))), math.degrees(math.atan2(y, x))


def floor_shadow(point, toward_sun) -> np.ndarray:
    """Where the ray from `point` away from the sun meets the floor (z 0)."""
    point, toward_sun = np.asarray(point), np.asarray(toward_sun)
    return point - point[2] / toward_sun[2] * toward_sun
