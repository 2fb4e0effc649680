"""SH lights from the command line: `--sun THETA,PHI[,IRRADIANCE]` (repeatable), `--env IMAGE [--env-rotation DEG]`,
`--sky RADIANCE` and `--replace-lights`. `prt relight` and `prt bake` share them, so a batch bake can save a file
that relights at once, and a file baked without the interface can be relit."""

import argparse
import math
import os

import bpy

from ..blender import lights
from ..blender.schema import add_light
from ..core.errors import InputError
from .common import log


def add_arguments(parser):
    group = parser.add_argument_group("SH lights to add (when the file has none, or with --replace-lights)")
    group.add_argument("--sun", action="append", type=_sun, metavar="THETA,PHI[,IRRADIANCE]",
                       help="a sun θ degrees from the zenith at azimuth φ degrees (from +X towards +Y), with this "
                            "irradiance on a surface facing it (default 1); repeat for more suns")
    group.add_argument("--env", metavar="IMAGE", help="an equirectangular image (.exr, .hdr, .png) around the scene")
    group.add_argument("--env-rotation", type=_finite("--env-rotation"), metavar="DEGREES",
                       help="turns --env about +Z")
    group.add_argument("--sky", type=_finite("--sky", at_least=0.0), metavar="RADIANCE",
                       help="the same radiance from every direction")
    group.add_argument("--replace-lights", action="store_true", help="remove the file's SH lights first")


def _finite(option: str, at_least: float | None = None):
    def parse(text: str) -> float:
        try:
            value = float(text)
        except ValueError:
            value = math.nan
        if not math.isfinite(value) or at_least is not None and value < at_least:
            bound = f" of at least {at_least:g}" if at_least is not None else ""
            raise argparse.ArgumentTypeError(f"{option} takes a number{bound}, not {text!r}")
        return value
    return parse


def _sun(text: str) -> tuple:
    try:
        values = [float(part) for part in text.split(",")]
    except ValueError:
        values = []
    if len(values) not in (2, 3) or not all(map(math.isfinite, values)):
        raise argparse.ArgumentTypeError(f"--sun takes THETA,PHI or THETA,PHI,IRRADIANCE (degrees), not {text!r}")
    theta, phi, irradiance = (values + [1.0])[:3]
    if not 0.0 <= theta <= 180.0:
        raise argparse.ArgumentTypeError(f"--sun's θ must be 0-180 degrees from the zenith, not {theta:g}")
    if irradiance < 0.0:
        raise argparse.ArgumentTypeError(f"--sun's irradiance must be at least 0, not {irradiance:g}")
    return theta, phi, irradiance


def add_lights(scene, args):
    """Adds the SH lights the options ask for and prints a line describing each; changes nothing when none are
    asked for. A file that has lights keeps them unless --replace-lights; a missing image changes nothing."""
    if args.env_rotation is not None and not args.env:
        raise InputError("--env-rotation turns the --env image; give --env IMAGE too")
    if not (args.sun or args.env or args.sky is not None):
        return
    if len(scene.prt_lights) and not args.replace_lights:
        have = ", ".join(repr(entry.name) for entry in scene.prt_lights)
        raise InputError(f"the file already has {len(scene.prt_lights)} SH lights ({have}); give --replace-lights "
                         f"to replace them")
    image = _image(args.env) if args.env else None
    scene.prt_lights.clear()
    for theta, phi, irradiance in args.sun or ():
        sun = add_light(scene, "SUN")
        sun.theta, sun.phi, sun.strength = math.radians(theta), math.radians(phi), irradiance
    if image is not None:
        environment = add_light(scene, "ENVIRONMENT")
        environment.image = image
        environment.rotation = (0.0, 0.0, math.radians(args.env_rotation or 0.0))
    if args.sky is not None:
        add_light(scene, "SKY").strength = args.sky
    scene.prt_active_light = 0
    for entry in scene.prt_lights:
        log(f"prt: added SH light: {lights.describe(entry, scene)}")


def _image(path: str):
    if not os.path.isfile(path):
        raise InputError(f"--env: no such image: {path}")
    image = bpy.data.images.load(os.path.abspath(path), check_existing=True)
    if 0 in image.size:
        raise InputError(f"--env: {path} could not be read as an image")
    return image
