"""The scene's SH lights: its settings (the `prt_lights` collection the interface defines) turned into the core's
lights, described for reports, and aimed from the command line; an environment's sun split off into a Blender Sun
lamp (core.sun_extraction), which follows the environment's rotation."""

import math

import bpy
import numpy as np
from mathutils import Vector

from ..core import light_fidelity, lights, shading, sun_extraction
from ..core.settings import MAX_ORDER
from ..core.errors import InputError

SUN_LAMP_PREFIX = "PRT Sun"  # the lamps made for split-off suns: "PRT Sun: <SH light's name>"


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
    if entry.split_sun:  # PRT carries the image without its sun; a lamp draws the sun
        key = (image.name_full, *image.size, "without its sun")
        return lights.Environment(key, tuple(matrix.ravel()), rgb(entry), pixels=lambda: _found_sun(image)[1])
    return lights.Environment((image.name_full, *image.size), tuple(matrix.ravel()), rgb(entry),
                              pixels=lambda: _equirect_pixels(image))


def real_light(scene, without_split_suns: bool = False):
    """The scene's SH lights as they are, for a renderer: ([(image, rotation Euler, rgb)] of the environments,
    whole (or, `without_split_suns`, an (H, W, 3) array of the image without the sun split off it); [core Sun] of
    the suns; the skies' summed rgb)."""
    environments, suns, sky = [], [], np.zeros(3)
    for entry in scene.prt_lights:
        light = to_light(entry, scene)
        if isinstance(light, lights.Sun):
            suns.append(light)
        elif isinstance(light, lights.Sky):
            sky += light.rgb
        elif light is not None:
            image = environment_image(entry, scene)
            if without_split_suns and split_sun(entry, scene) is not None:
                image = _found_sun(image)[1]
            environments.append((image, tuple(entry.rotation), rgb(entry)))
    return environments, suns, tuple(sky)


def split_sun(entry, scene) -> lights.Sun | None:
    """The sun split off an environment entry, in world space (turned by its rotation, × its colour and strength),
    or None: not an environment, the switch is off, no image, or no compact strong sun in it."""
    if entry.kind != "ENVIRONMENT" or not entry.split_sun or not entry.use:
        return None
    image = environment_image(entry, scene)
    found = _found_sun(image)[0] if image is not None else None
    if found is None:
        return None
    direction = entry.rotation.to_matrix() @ Vector(found.direction)
    colour = tuple(c * k for c, k in zip(found.irradiance, rgb(entry)))
    return lights.Sun(tuple(direction), found.angular_radius, colour)


def found_sun(entry, scene) -> sun_extraction.FoundSun | None:
    """What the environment entry's image holds as a sun, in the image's frame (whatever the switch)."""
    image = environment_image(entry, scene) if entry.kind == "ENVIRONMENT" else None
    return _found_sun(image)[0] if image is not None else None


_SUNS_FOUND = {}  # (image name, size) → (FoundSun or None, pixels without it): one search per image


def _found_sun(image):
    key = (image.name_full, *image.size)
    if key not in _SUNS_FOUND:
        _SUNS_FOUND.clear()  # one image at a time: the pixels are large
        _SUNS_FOUND[key] = sun_extraction.find_sun(_equirect_pixels(image))
    return _SUNS_FOUND[key]


def sync_sun_lamps(scene, create: bool = True):
    """Each environment entry's split-off sun drives its own Sun lamp (direction, Angle = 2 × radius, colour and
    Strength = irradiance). With `create` (a switch flipped, a command) lamps are made, and removed where the entry
    has no sun any more; without it (the handlers, which must not add or remove objects) a lamp whose entry has no
    sun is only hidden. Values are written only when they differ, so a handler's call starts no other update."""
    for entry in scene.prt_lights:
        sun = split_sun(entry, scene)
        lamp = entry.sun_lamp.original if entry.sun_lamp else None  # the handler reads the evaluated scene
        if sun is None and lamp is not None:
            if create:
                entry.sun_lamp = None
                _remove_lamp(lamp)
            else:
                _set(lamp, {"hide_render": True, "hide_viewport": True})
        elif sun is not None and (lamp is not None or create):
            if lamp is None:
                lamp = entry.sun_lamp = _new_lamp(scene, f"{SUN_LAMP_PREFIX}: {entry.name}")
            _set(lamp, {"hide_render": False, "hide_viewport": False})
            aim_lamp(lamp, sun)


def _new_lamp(scene, name):
    lamp = bpy.data.objects.new(name, bpy.data.lights.new(name, "SUN"))
    scene.collection.objects.link(lamp)
    return lamp


def _remove_lamp(lamp):
    data = lamp.data
    bpy.data.objects.remove(lamp)
    if data.users == 0:
        bpy.data.lights.remove(data)


def aim_lamp(lamp, sun: lights.Sun):
    """Gives a Sun lamp the core sun's direction (a lamp shines along its local −Z: its +Z points at the sun),
    Angle, colour and Strength (its irradiance)."""
    rotation = Vector((0.0, 0.0, 1.0)).rotation_difference(Vector(sun.direction)).to_euler()
    strength = max(sun.rgb)
    colour = tuple(c / strength for c in sun.rgb) if strength > 0 else (1.0, 1.0, 1.0)
    _set(lamp, {"rotation_euler": tuple(rotation)})
    _set(lamp.data, {"energy": strength, "color": colour, "angle": 2 * sun.angular_radius})


def _set(owner, values):
    """Writes only the values that differ: every write tags the depsgraph."""
    for name, value in values.items():
        current = getattr(owner, name)
        if not np.allclose(tuple(current) if hasattr(current, "__len__") else current, value, atol=1e-6):
            setattr(owner, name, value)


def scene_lights(scene) -> list:
    """The scene's enabled SH lights that can shine, as the core's lights: what the display sums."""
    return [light for light in (to_light(entry, scene) for entry in scene.prt_lights) if light]


def scene_fidelity(scene, target: float = light_fidelity.DEFAULT_TARGET) -> light_fidelity.LightFidelity:
    """How well each order up to MAX_ORDER carries the light PRT carries (split-off suns are the lamps'), through
    the display's window."""
    return light_fidelity.analyse(scene_lights(scene), range(1, MAX_ORDER + 1), target, scene.prt_display.window)


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
    sun = split_sun(entry, scene)
    split = "" if sun is None else f"; its sun split off into {entry.sun_lamp.name if entry.sun_lamp else 'a lamp'}"
    return f"environment {entry.name!r}{state}: {image.name if image else 'no image'}, × ({colour}){split}"


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
