"""The scene's SH lights: its settings (the `prt_lights` collection the interface defines) turned into the core's
lights, described for reports, and aimed from the command line."""

import math

import numpy as np
from mathutils import Vector

from ..core import lights, shading
from ..core.errors import InputError


def sun_direction(entry) -> tuple:
    """Towards the sun in world space: the followed object's local +Z (a Sun shines along −Z), else θ, φ."""
    if entry.sun_object is not None:
        return tuple(entry.sun_object.matrix_world.to_quaternion() @ Vector((0.0, 0.0, 1.0)))
    return shading.direction_from_angles(entry.theta, entry.phi)


def sun_angular_radius(entry) -> float:
    """The disc's radius: a followed Sun's Angle / 2, else the entry's own."""
    if entry.sun_object is not None:
        return entry.sun_object.data.angle / 2
    return entry.angular_radius


def rgb(entry) -> tuple:
    return tuple(entry.strength * c for c in entry.colour)


def environment_image(entry, scene):
    """The chosen image, else the World's Environment Texture; None when there is neither or it is empty."""
    image = entry.image or _world_environment_image(scene.world)
    if image is None or 0 in image.size:
        return None
    return image.original


def to_light(entry, scene):
    """The core's light for these settings, or None when it cannot shine (disabled, no image)."""
    if not entry.use:
        return None
    if entry.kind == "SUN":
        return lights.Sun(sun_direction(entry), sun_angular_radius(entry), rgb(entry))
    if entry.kind == "SKY":
        return lights.Sky(rgb(entry))
    image = environment_image(entry, scene)
    if image is None:
        return None
    matrix = np.array(entry.rotation.to_matrix(), dtype=np.float64)
    return lights.Environment((image.name_full, *image.size), tuple(matrix.ravel()), rgb(entry),
                              pixels=lambda: _equirect_pixels(image))


def scene_lights(scene) -> list:
    """The scene's enabled SH lights that can shine, as the core's lights: what the display sums."""
    return [light for light in (to_light(entry, scene) for entry in scene.prt_lights) if light]


def describe(entry, scene) -> str:
    """One line for reports: what shines, from where, how strongly."""
    colour = ", ".join(f"{c:g}" for c in rgb(entry))
    state = "" if entry.use else " (off)"
    if entry.kind == "SUN":
        source = (f"following {entry.sun_object.name!r}" if entry.sun_object else
                  f"θ {math.degrees(entry.theta):.1f}°, φ {math.degrees(entry.phi):.1f}°")
        radius = math.degrees(sun_angular_radius(entry))
        return f"sun {entry.name!r}{state}: {source}, radius {radius:.2f}°, irradiance ({colour})"
    if entry.kind == "SKY":
        return f"sky {entry.name!r}{state}: radiance ({colour})"
    image = environment_image(entry, scene)
    return f"environment {entry.name!r}{state}: {image.name if image else 'no image'}, × ({colour})"


def aim_sun(scene, index: int, theta_deg=None, phi_deg=None) -> str | None:
    """Sets SH light `index`'s θ and/or φ (degrees); one that followed a Sun object stops following it, keeping
    its direction and disc. Returns a sentence saying so, else None."""
    if not 0 <= index < len(scene.prt_lights):
        raise InputError(f"no SH light {index}: the file has {len(scene.prt_lights)} "
                         f"(0-{len(scene.prt_lights) - 1})")
    entry = scene.prt_lights[index]
    if entry.kind != "SUN":
        raise InputError(f"SH light {index} ({entry.name!r}) is a {entry.kind.lower()}, not a sun: it has no θ, φ")
    said = None
    if entry.sun_object is not None:
        said = f"SH light {entry.name!r} no longer follows {entry.sun_object.name!r}"
        entry.angular_radius = sun_angular_radius(entry)
        entry.theta, entry.phi = _angles_of(sun_direction(entry))
        entry.sun_object = None
    if theta_deg is not None:
        entry.theta = math.radians(theta_deg)
    if phi_deg is not None:
        entry.phi = math.radians(phi_deg)
    return said


def _angles_of(direction):
    x, y, z = direction
    return math.acos(max(-1.0, min(1.0, z))), math.atan2(y, x)


def _world_environment_image(world):
    if world is None or world.node_tree is None:
        return None
    for node in world.node_tree.nodes:
        if node.type == "TEX_ENVIRONMENT" and node.image is not None:
            return node.image
    return None


def _equirect_pixels(image) -> np.ndarray:
    """(H, W, 3) float32, row 0 at the bottom (Blender's layout, as the core expects)."""
    width, height = image.size
    flat = np.empty(width * height * image.channels, dtype=np.float32)
    image.pixels.foreach_get(flat)
    pixels = flat.reshape(height, width, image.channels)
    return pixels[..., :3] if image.channels >= 3 else np.repeat(pixels[..., :1], 3, axis=2)
