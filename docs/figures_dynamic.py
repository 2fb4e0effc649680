"""dynamic_limits.png: what the probe volumes and dynamic objects cannot show (Limits), each panel the PRT display
(EEVEE, blender.image_validation) over Cycles rendering the same scene under the same band-limited light (order 8,
every surface white, direct light only):
(a) a dynamic sphere over a floor under a sun: Cycles shows its shadow on the floor, PRT does not (a dynamic
    object casts no shadow on the static scene);
(b) a row of small dynamic spheres crossing a wall's shadow edge inside a probe volume of 1 m spacing: each sphere
    (lit at its centre, as a small object may be) takes the trilinear blend of the probes around its centre, so
    those within a spacing of the edge get light blended across it, while Cycles shows the change where the edge is.
Each panel's numbers, printed and read back by tests/test_figures.py, are measured on the two renders: (a) the
floor's mean brightness in a disc at the shadow's centre, Cycles ÷ PRT; (b) per sphere, the distance of its centre
from the edge and |PRT − Cycles| over a disc inside its outline, relative to the brightest sphere in Cycles.
"""

from dataclasses import dataclass
import math

import bpy
from mathutils import Vector
import numpy as np

from figures_common import (band_limited_pair, disc_mean, exposure, new_figure, pixel_of, save, show_image,
                            to_srgb)
from prt_addon.blender import schema
from prt_addon.blender.scene_bake import SceneBake
from prt_addon.core import shading
from prt_addon.core.bake import BakeSettings

NAME = "dynamic_limits.png"

ORDER = 8  # a band-limited sun sharp enough that its own penumbra at the spheres is narrower than the probe spacing
SUN = {"theta": math.radians(35.0), "phi": 0.0, "angular_radius": 0.05, "strength": 2.0}  # from +X, 55° up
SKY = 0.1
PRESETS = {"full": {"resolution": (480, 270), "bake_samples": 1024, "cycles_samples": 32},
           "quick": {"resolution": (240, 136), "bake_samples": 512, "cycles_samples": 8}}
SPHERE_ROW = np.linspace(-1.25, 1.25, 6)  # (b) the small spheres' y: the shadow edge is at y 0
PROBE_Y = [-1.5, -0.5, 0.5, 1.5]
SPHERE_X, SPHERE_HEIGHT, SPHERE_RADIUS = -0.3, 0.5, 0.12
DISC = 0.5  # of a sphere's projected radius, or (a) the shadow's: the pixels measured, away from edges


def sun_direction() -> np.ndarray:
    return np.asarray(shading.direction_from_angles(SUN["theta"], SUN["phi"]))


def new_scene(camera_at, target, resolution):
    """An empty file with a floor (8 × 8 m, 32 × 32 quads, so per-vertex shadows show), the sun and sky as SH
    lights (Hanning-windowed: no ringing) and a camera looking at `target`."""
    bpy.ops.wm.read_homefile(use_empty=True)
    scene = bpy.context.scene
    bpy.ops.mesh.primitive_grid_add(x_subdivisions=32, y_subdivisions=32, size=8.0)
    sun = schema.add_light(scene, "SUN")
    for key, value in SUN.items():
        setattr(sun, key, value)
    schema.add_light(scene, "SKY").strength = SKY
    scene.prt_display.window = "hanning"
    bpy.ops.object.camera_add(location=camera_at)
    camera = bpy.context.object
    camera.rotation_euler = (Vector(target) - Vector(camera_at)).to_track_quat("-Z", "Y").to_euler()
    scene.camera = camera
    scene.render.resolution_x, scene.render.resolution_y = resolution
    return scene


def dynamic_sphere(location, radius, segments=32):
    bpy.ops.mesh.primitive_uv_sphere_add(segments=segments, ring_count=segments // 2, radius=radius,
                                         location=location)
    ob = bpy.context.object
    ob.data.shade_smooth()
    ob.prt_dynamic = True
    ob.prt_probe_light = "centre"  # small beside the probe spacing: one blend for the whole sphere
    return ob








@dataclass
class Panel:
    caption: str
    prt: np.ndarray  # (H, W, 3) linear, top row first
    cycles: np.ndarray
    along: np.ndarray  # the profile's abscissa (m) and its PRT and Cycles brightness
    prt_profile: np.ndarray
    cycles_profile: np.ndarray
    along_label: str
    marks: dict  # label: abscissas drawn as vertical lines


def shadow_panel(preset, folder) -> Panel:
    """(a): a dynamic sphere (r 0.5) 1.2 m over the floor, no probe volume; the floor along x through its shadow,
    and the ratio at the shadow's centre."""
    scene = new_scene((0.6, -5.5, 3.2), (-0.6, 0.0, 0.5), preset["resolution"])
    centre = np.array([0.0, 0.0, 1.2])
    dynamic_sphere(tuple(centre), 0.5)
    prt, cycles = baked_and_rendered(scene, preset, folder)
    direction = sun_direction()
    shadow = centre - centre[2] / direction[2] * direction
    ratio = disc_mean(cycles, scene, shadow, 0.3, DISC) / disc_mean(prt, scene, shadow, 0.3, DISC)
    print(f"(a) floor at the dynamic sphere's shadow: Cycles ÷ PRT {ratio:.3f} "
          f"(Cycles shows its shadow, PRT does not)")
    along = np.linspace(shadow[0] - 1.5, shadow[0] + 1.5, 61)
    profiles = [pixels_along(image, scene, [(x, shadow[1], 0.0) for x in along]) for image in (prt, cycles)]
    return Panel("(a) a dynamic object casts no shadow\non the static scene", prt, cycles, along, *profiles,
                 "floor through the shadow, x (m)", {"sun's ray through its centre": [shadow[0]]})


def pixels_along(image, scene, points) -> np.ndarray:
    """The brightness of the pixel each world point falls in."""
    height, width = image.shape[:2]
    found = []
    for point in points:
        column, row = pixel_of(scene, point, width, height)
        found.append(image[min(int(row), height - 1), min(int(column), width - 1)].mean())
    return np.array(found)


def edge_panel(preset, folder) -> Panel:
    """(b): a wall (x −0.1..0.1, y 0..4, 2 m high) whose end at y 0 casts the shadow edge, the sun in the xz plane
    so the edge is the plane y = 0 at every height; the row of small spheres 0.2 m behind the wall along y, each
    at a probe's x and z (the volume: 1 × 4 × 1 probes, 1 m apart along y, at y ±0.5 and ±1.5), so they are blended
    along y alone: between the probes at y −0.5 (lit) and +0.5 (in shadow) the light is a ramp."""
    scene = new_scene((-1.8, 0.0, 4.3), (SPHERE_X, 0.0, 0.3), preset["resolution"])
    bpy.ops.mesh.primitive_cube_add(size=1.0, location=(0.0, 2.0, 1.0), scale=(0.2, 4.0, 2.0))
    volume = bpy.data.objects.new("PRT Probe Volume", None)
    volume.empty_display_type = "CUBE"
    volume.location, volume.scale = (SPHERE_X, 0.0, SPHERE_HEIGHT), (0.2, 2.0, 0.5)
    volume.prt_probe_volume, volume.prt_probe_resolution = True, (1, 4, 1)
    scene.collection.objects.link(volume)
    for y in SPHERE_ROW:
        dynamic_sphere((SPHERE_X, y, SPHERE_HEIGHT), SPHERE_RADIUS, segments=16)
    prt, cycles = baked_and_rendered(scene, preset, folder)
    means = np.array([[disc_mean(image, scene, (SPHERE_X, y, SPHERE_HEIGHT), SPHERE_RADIUS, DISC) for y in SPHERE_ROW]
                      for image in (prt, cycles)])
    differences = np.abs(means[0] - means[1]) / means[1].max()
    for y, (shown, truth), difference in zip(SPHERE_ROW, means.T, differences):
        print(f"(b) sphere at y {y:+.2f} m, {abs(y):.2f} m from the edge ({'shadow' if y > 0 else 'lit'}): "
              f"PRT {shown:.4f}, Cycles {truth:.4f}, differs by {100 * difference:.1f} %")
    return Panel("(b) probes 1 m apart blur a shadow edge\nfiner than their spacing", prt, cycles,
                 SPHERE_ROW, *means, "spheres, y (m): the edge at 0", {"edge": [0.0], "probes": PROBE_Y})




def write_figure(path, panels):
    """The panels side by side: PRT above Cycles (one exposure per panel: its brightest Cycles pixels at 0.8
    linear), and below them the profile of both."""
    height, width = panels[0].prt.shape[:2]
    figure = new_figure(2 * width + 60, 2.7 * height + 100)
    axes = figure.subplots(3, 2, height_ratios=(height, height, 0.7 * height))
    for column, panel in enumerate(panels):
        scale = exposure(panel.cycles)
        for row, (image, side) in enumerate(((panel.prt, "PRT"), (panel.cycles, "Cycles"))):
            show_image(axes[row, column], to_srgb(image, scale), panel.caption if row == 0 else None)
            axes[row, column].set_ylabel(side, fontsize=9)
        ax = axes[2, column]
        ax.plot(panel.along, panel.prt_profile, "o-" if len(panel.along) < 20 else "-", label="PRT", ms=4)
        ax.plot(panel.along, panel.cycles_profile, "s-" if len(panel.along) < 20 else "-", label="Cycles", ms=4)
        for (label, places), style in zip(panel.marks.items(), (":", "--")):
            for place in places:
                ax.axvline(place, color="grey", linestyle=style, linewidth=0.8,
                           label=label if place == places[0] else None)
        ax.set_xlabel(panel.along_label, fontsize=8)
        ax.set_ylabel("radiance", fontsize=8)
        ax.set_ylim(bottom=0.0)
        ax.tick_params(labelsize=7)
        ax.legend(fontsize=7, loc="upper right" if column else "lower left")
    return save(figure, path)


def baked_and_rendered(scene, preset, folder):
    """Bakes the scene (order 8, shadowed) and renders both sides → (PRT, Cycles), each (H, W, 3) linear, top row
    first."""
    bpy.ops.object.select_all(action="DESELECT")  # the bake takes the selected meshes only, if any are
    SceneBake(bpy.context, BakeSettings(order=ORDER, mode="shadowed", samples=preset["bake_samples"])).run(
        log=lambda line: None)
    return band_limited_pair(bpy.context, ORDER, preset["cycles_samples"], folder)


def make(run) -> str:
    preset = run.pick(PRESETS)
    panels = [shadow_panel(preset, run.scratch), edge_panel(preset, run.scratch)]
    return write_figure(run.path(NAME), panels)
