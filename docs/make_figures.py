"""The manual's figures, made in one command from scenes built here, baked and rendered as a user would.

    .venv/bin/python docs/make_figures.py [--quick] [--out docs/figures]

dynamic_limits.png: what the probe volumes and dynamic objects cannot show (README, Dynamic objects and Probe
volumes), each panel the PRT display (EEVEE, blender.image_validation) over Cycles rendering the same scene under
the same band-limited light (order 8, every surface white, direct light only):
(a) a dynamic sphere over a floor under a sun: Cycles shows its shadow on the floor, PRT does not (a dynamic
    object casts no shadow on the static scene);
(b) a row of small dynamic spheres crossing a wall's shadow edge inside a probe volume of 1 m spacing: each sphere
    (lit at its centre, as a small object may be) takes the trilinear blend of the probes around its centre, so those within a spacing of the edge get light
    blended across it, while Cycles shows the change where the edge is.
Each panel's numbers, printed and read back by tests/test_figures.py, are measured on the two renders: (a) the
floor's mean brightness in a disc at the shadow's centre, Cycles ÷ PRT; (b) per sphere, the distance of its centre
from the edge and |PRT − Cycles| over a disc inside its outline, relative to the brightest sphere in Cycles.

--quick renders at half size with fewer samples: the same scenes, for the smoke test (tests/test_figures.py).
"""

import argparse
from dataclasses import dataclass
import math
import os
import sys
import tempfile

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
sys.path.insert(0, ROOT)

import bpy  # noqa: E402  (before mathutils, which the add-on imports)
from bpy_extras.object_utils import world_to_camera_view  # noqa: E402
from matplotlib.backends.backend_agg import FigureCanvasAgg  # noqa: E402
from matplotlib.figure import Figure  # noqa: E402
from mathutils import Vector  # noqa: E402
import numpy as np  # noqa: E402

from prt_addon.blender import schema, storage  # noqa: E402
from prt_addon.blender.image_validation import band_limited_renders, render_settings_restored  # noqa: E402
from prt_addon.blender.scene_bake import SceneBake  # noqa: E402
from prt_addon.blender.validation import scene_light  # noqa: E402
from prt_addon.commands.common import schema_registered  # noqa: E402
from prt_addon.core import shading  # noqa: E402
from prt_addon.core.bake import BakeSettings  # noqa: E402
from prt_addon.core.colour import linear_to_srgb  # noqa: E402

ORDER = 8  # a band-limited sun sharp enough that its own penumbra at the spheres is narrower than the probe spacing
SUN = {"theta": math.radians(35.0), "phi": 0.0, "angular_radius": 0.05, "strength": 2.0}  # from +X, 55° up
SKY = 0.1
FULL = {"resolution": (480, 270), "bake_samples": 1024, "cycles_samples": 32}
QUICK = {"resolution": (240, 136), "bake_samples": 512, "cycles_samples": 8}
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


def baked_and_rendered(scene, preset):
    """Bakes the scene (order 8, shadowed) and renders both sides → (PRT, Cycles), each (H, W, 3) linear, top row
    first."""
    bpy.ops.object.select_all(action="DESELECT")  # the bake takes the selected meshes only, if any are
    SceneBake(bpy.context, BakeSettings(order=ORDER, mode="shadowed", samples=preset["bake_samples"])).run(
        log=lambda line: None)
    receivers = storage.baked_objects(bpy.context.view_layer.objects)
    totals, _ = scene_light(bpy.context, [ORDER])
    width, height = preset["resolution"]
    with tempfile.TemporaryDirectory(prefix="prt_figures_") as folder, render_settings_restored(scene):
        shown, cycles, *_ = band_limited_renders(bpy.context, receivers, totals, ORDER, preset["cycles_samples"],
                                                 1, 0, folder)
    return [pixels.reshape(height, width, 3)[::-1] for pixels in (shown, cycles[0])]


def pixel_of(scene, point, width, height) -> tuple[float, float]:
    """(column, row) of a world point in an image of the camera's view, top row first."""
    seen = world_to_camera_view(scene, scene.camera, Vector(point))
    return seen.x * width, (1.0 - seen.y) * height


def disc_mean(image, scene, centre, radius) -> float:
    """Mean brightness (RGB mean) of `image` (top row first) over a disc of DISC × the projected radius of a
    sphere of `radius` at world `centre`."""
    height, width = image.shape[:2]
    column, row = pixel_of(scene, centre, width, height)
    side = scene.camera.matrix_world.to_3x3() @ Vector((radius, 0.0, 0.0))
    reach = DISC * abs(pixel_of(scene, Vector(centre) + side, width, height)[0] - column)
    rows, columns = np.mgrid[0:height, 0:width]
    inside = (rows + 0.5 - row) ** 2 + (columns + 0.5 - column) ** 2 <= reach ** 2
    if not inside.any():
        raise RuntimeError(f"no pixel within {reach:.1f} of ({column:.0f}, {row:.0f})")
    return float(image[inside].mean())


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


def shadow_panel(preset) -> Panel:
    """(a): a dynamic sphere (r 0.5) 1.2 m over the floor, no probe volume; the floor along x through its shadow,
    and the ratio at the shadow's centre."""
    scene = new_scene((0.6, -5.5, 3.2), (-0.6, 0.0, 0.5), preset["resolution"])
    centre = np.array([0.0, 0.0, 1.2])
    dynamic_sphere(tuple(centre), 0.5)
    prt, cycles = baked_and_rendered(scene, preset)
    direction = sun_direction()
    shadow = centre - centre[2] / direction[2] * direction
    ratio = disc_mean(cycles, scene, shadow, 0.3) / disc_mean(prt, scene, shadow, 0.3)
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


def edge_panel(preset) -> Panel:
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
    prt, cycles = baked_and_rendered(scene, preset)
    means = np.array([[disc_mean(image, scene, (SPHERE_X, y, SPHERE_HEIGHT), SPHERE_RADIUS) for y in SPHERE_ROW]
                      for image in (prt, cycles)])
    differences = np.abs(means[0] - means[1]) / means[1].max()
    for y, (shown, truth), difference in zip(SPHERE_ROW, means.T, differences):
        print(f"(b) sphere at y {y:+.2f} m, {abs(y):.2f} m from the edge ({'shadow' if y > 0 else 'lit'}): "
              f"PRT {shown:.4f}, Cycles {truth:.4f}, differs by {100 * difference:.1f} %")
    return Panel("(b) probes 1 m apart blur a shadow edge\nfiner than their spacing", prt, cycles,
                 SPHERE_ROW, *means, "spheres, y (m): the edge at 0", {"edge": [0.0], "probes": PROBE_Y})


def to_srgb(image, scale):
    return linear_to_srgb(np.clip(image * scale, 0.0, 1.0))


def write_figure(path, panels):
    """The panels side by side: PRT above Cycles (one exposure per panel: its brightest Cycles pixels at 0.8
    linear), and below them the profile of both."""
    height, width = panels[0].prt.shape[:2]
    dpi = 100
    figure = Figure(figsize=(2 * width / dpi + 0.6, 2.7 * height / dpi + 1.0), dpi=dpi, layout="constrained")
    FigureCanvasAgg(figure)
    axes = figure.subplots(3, 2, height_ratios=(height, height, 0.7 * height))
    for column, panel in enumerate(panels):
        scale = 0.8 / np.percentile(panel.cycles, 99)
        for row, (image, side) in enumerate(((panel.prt, "PRT"), (panel.cycles, "Cycles"))):
            ax = axes[row, column]
            ax.imshow(to_srgb(image, scale), interpolation="nearest")
            ax.set_xticks([]), ax.set_yticks([])
            ax.set_ylabel(side, fontsize=9)
        axes[0, column].set_title(panel.caption, fontsize=9, loc="left")
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
    figure.savefig(path)


def main(argv=None):
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--quick", action="store_true", help="half size, fewer samples: a smoke run")
    parser.add_argument("--out", default=os.path.join(ROOT, "docs", "figures"), help="folder for the PNGs")
    args = parser.parse_args(argv)
    preset = QUICK if args.quick else FULL
    os.makedirs(args.out, exist_ok=True)
    with schema_registered(relighting=True):
        panels = [shadow_panel(preset), edge_panel(preset)]
    path = os.path.join(args.out, "dynamic_limits.png")
    write_figure(path, panels)
    print(f"wrote {path}")


if __name__ == "__main__":
    main()
