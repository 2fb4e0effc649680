"""Turning SH lights by angles, as the Drive Lights operator does, and putting back what it changed."""

import math

from mathutils import Matrix

from .lights import aim_sun

AIM_SETTINGS = ("theta", "phi", "angular_radius", "sun_object", "rotation")  # what turning a light may change


def turn(scene, index: int, d_theta: float, d_phi: float) -> str | None:
    """Turns SH light `index` as a sun moves from (θ, φ) to (θ + dθ, φ + dφ): a sun's own angles (θ kept within
    [0, π], φ wrapped into [−π, π)); an environment by Rz(dφ)·Ry(dθ) in world space (its light from the zenith
    moves as a sun at φ 0 would). A sun that followed a Sun object lets it go, keeping its direction
    (lights.aim_sun). Returns a sentence when that happened or nothing could turn (a sky), else None."""
    entry = scene.prt_lights[index]
    if entry.kind == "SKY":
        return f"{entry.name!r} is a sky, the same from every direction: nothing to turn"
    if entry.kind == "ENVIRONMENT":
        turned = Matrix.Rotation(d_phi, 3, "Z") @ Matrix.Rotation(d_theta, 3, "Y") @ entry.rotation.to_matrix()
        entry.rotation = turned.to_euler("XYZ", entry.rotation)  # the Euler nearest the old one: no jumps
        return None
    said = aim_sun(scene, index)
    if d_theta:
        entry.theta = min(max(entry.theta + d_theta, 0.0), math.pi)
    if d_phi:
        entry.phi = (entry.phi + d_phi + math.pi) % (2 * math.pi) - math.pi
    return said


def aim_text(entry) -> str:
    """Where a light comes from, for the viewport's header."""
    if entry.kind == "SKY":
        return f"sky {entry.name!r}"
    if entry.kind == "ENVIRONMENT":
        return f"environment {entry.name!r}: rotation " + " ".join(
            f"{axis} {_degrees(angle)}" for axis, angle in zip("XYZ", entry.rotation))
    if entry.sun_object is not None:
        return f"sun {entry.name!r}: follows {entry.sun_object.name!r}"
    return f"sun {entry.name!r}: θ {_degrees(entry.theta)}, φ {_degrees(entry.phi)}"


def _degrees(angle) -> str:
    return f"{round(math.degrees(angle), 1) + 0.0:.1f}°"  # + 0.0: never "-0.0°"


class Aims:
    """The scene's light aims, its active light and the named display switches as they were, to put back."""

    def __init__(self, scene, switches):
        self.scene = scene
        # the rotation as a tuple: an Euler read from a property is a view of it, which later changes reach
        self.lights = [{**{name: getattr(entry, name) for name in AIM_SETTINGS}, "rotation": tuple(entry.rotation)}
                       for entry in scene.prt_lights]
        self.active = scene.prt_active_light
        self.switches = {name: getattr(scene.prt_display, name) for name in switches}

    def restore(self):
        for entry, aim in zip(self.scene.prt_lights, self.lights):
            for name, value in aim.items():
                setattr(entry, name, value)
        self.scene.prt_active_light = self.active
        for name, value in self.switches.items():
            setattr(self.scene.prt_display, name, value)
