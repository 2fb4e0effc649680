"""What the manual's figures share: the run (its output folder, quick or full, a scratch folder and the demo scene
baked once for every figure that shows it), the renders PRT and Cycles make under one band-limited light, pixels
of world points, and writing a figure as a small PNG."""

from dataclasses import dataclass
import io
import os

import bpy  # noqa: F401  (before mathutils, which bpy_extras and this module import)
from bpy_extras.object_utils import world_to_camera_view
from matplotlib.backends.backend_agg import FigureCanvasAgg
from matplotlib.figure import Figure
from mathutils import Vector
import numpy as np
from PIL import Image

from prt_addon.blender import storage
from prt_addon.blender.image_validation import band_limited_renders, render_settings_restored
from prt_addon.blender.validation import scene_light
from prt_addon.commands.demo import save_baked_demo
from prt_addon.core import heatmap
from prt_addon.core.colour import linear_to_srgb
from prt_addon.core.outputs import replacing
from prt_addon.ui.heatmaps import SWATCHES

DPI = 100
LARGEST_PNG = 300_000  # bytes of a figure in true colour; a larger one is quantised to COLOURS colours
COLOURS = 256
WORKERS = 2  # the machine's cores
DEMO_SAMPLES = {"full": 256, "quick": 32}  # rays per vertex of the demo's bake (prt demo's default: 256)


@dataclass
class Run:
    """One run of make_figures: where the PNGs go, whether it is the quick smoke run, a scratch folder."""
    out: str
    quick: bool
    scratch: str
    _demo: str | None = None

    def pick(self, choices: dict):
        """choices["quick"] in the quick run, else choices["full"]."""
        return choices["quick" if self.quick else "full"]

    def path(self, name: str) -> str:
        return os.path.join(self.out, name)

    def demo_blend(self) -> str:
        """The demo scene as `prt demo` saves it (commands.demo: built, baked at order 4 shadowed, its SH sun
        following the Sun object and a sky, the PRT display on), baked on the first call."""
        if self._demo is None:
            path = os.path.join(self.scratch, "demo_baked.blend")
            save_baked_demo(path, WORKERS, self.pick(DEMO_SAMPLES))
            self._demo = path
        return self._demo


def band_limited_pair(context, order, cycles_samples, folder) -> tuple[np.ndarray, np.ndarray]:
    """The open scene's camera view under its SH lights band-limited to `order`, as `prt validate --image` renders
    it (blender.image_validation): (PRT display, Cycles), each (H, W, 3) linear, top row first."""
    scene = context.scene
    receivers = storage.baked_objects(context.view_layer.objects)
    totals, _ = scene_light(context, [order])
    width, height = scene.render.resolution_x, scene.render.resolution_y
    with render_settings_restored(scene):
        shown, cycles, *_ = band_limited_renders(context, receivers, totals, order, cycles_samples, 1, 0, folder)
    return tuple(pixels.reshape(height, width, 3)[::-1] for pixels in (shown, cycles[0]))


def pixel_of(scene, point, width, height) -> tuple[float, float]:
    """(column, row) of a world point in an image of the camera's view, top row first."""
    seen = world_to_camera_view(scene, scene.camera, Vector(point))
    return seen.x * width, (1.0 - seen.y) * height


def disc_mean(image, scene, centre, radius, fraction) -> float:
    """Mean brightness (RGB mean) of `image` (top row first) over a disc of `fraction` × the projected radius of a
    sphere of `radius` at world `centre`."""
    height, width = image.shape[:2]
    column, row = pixel_of(scene, centre, width, height)
    side = scene.camera.matrix_world.to_3x3() @ Vector((radius, 0.0, 0.0))
    reach = fraction * abs(pixel_of(scene, Vector(centre) + side, width, height)[0] - column)
    rows, columns = np.mgrid[0:height, 0:width]
    inside = (rows + 0.5 - row) ** 2 + (columns + 0.5 - column) ** 2 <= reach ** 2
    if not inside.any():
        raise RuntimeError(f"no pixel within {reach:.1f} of ({column:.0f}, {row:.0f})")
    return float(image[inside].mean())


def to_srgb(image, scale):
    return linear_to_srgb(np.clip(image * scale, 0.0, 1.0))


def exposure(reference) -> float:
    """One scale for a set of renders of the same light: the reference's brightest pixels (99th percentile) at
    0.8 linear."""
    return 0.8 / np.percentile(reference, 99)


def new_figure(width_px, height_px) -> Figure:
    figure = Figure(figsize=(width_px / DPI, height_px / DPI), dpi=DPI, layout="constrained")
    FigureCanvasAgg(figure)
    return figure


def show_image(ax, srgb, title=None):
    ax.imshow(srgb, interpolation="nearest")
    ax.set_xticks([]), ax.set_yticks([])
    if title:
        ax.set_title(title, fontsize=9, loc="left")


def colour_scale(ax, top, label):
    """The heatmaps' colour scale from 0 to `top`, in percent: the swatches the Display panel's legend draws."""
    ax.imshow(heatmap.legend_srgb(SWATCHES)[None], aspect="auto", extent=(0.0, 100 * top, 0.0, 1.0))
    ax.set_yticks([])
    ax.tick_params(labelsize=8)
    ax.set_xlabel(label, fontsize=8)


def read_png(path) -> np.ndarray:
    """(H, W, 3) sRGB in 0..1 of a PNG a command wrote."""
    with Image.open(path) as image:
        return np.asarray(image.convert("RGB"), dtype=np.float64) / 255.0


def save(figure, path) -> str:
    """Writes the figure as a small PNG (save_png)."""
    buffer = io.BytesIO()
    figure.savefig(buffer, format="png")
    buffer.seek(0)
    return save_png(buffer, path)


def save_png(source, path) -> str:
    """Writes the PNG read from `source` (a path or a file) at `path`: in true colour where that is at most
    LARGEST_PNG bytes, else as a palette PNG (COLOURS colours, dithered), where a render's gradients keep their
    look at a fraction of the size. Written whole or not at all: the committed figure stays until the new one is."""
    with Image.open(source) as image:
        rgb = image.convert("RGB")
    with replacing(str(path)) as temporary:
        rgb.save(temporary, format="PNG", optimize=True)
        if os.path.getsize(temporary) > LARGEST_PNG:
            rgb.quantize(COLOURS, method=Image.Quantize.MEDIANCUT, dither=Image.Dither.FLOYDSTEINBERG).save(
                temporary, format="PNG", optimize=True)
    return path
