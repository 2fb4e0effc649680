"""Ground truth from Cycles: the same band-limited light, baked by a path tracer into the receivers' vertices.

PRT with a light band-limited to the bake's order is exact up to Monte Carlo noise (∫ L̃·T = Σ L̃_k T_k), so
Cycles lit by the SH-reconstructed environment must agree with it. What makes the two comparable:
- the light is the scene's SH lights, summed and windowed as the display shows them (DEFAULT_LIGHT when there are
  none), reconstructed as an equirectangular World texture. Cycles cannot emit the negative lobes of a ringing
  light, so they are clamped, and the clamped share of the light is reported;
- every mesh gets a pure Diffuse BSDF (the Principled BSDF's specular layer takes about 4 % of the diffuse
  light) coloured by the per-vertex albedo the bake reads from its materials (mesh_data.vertex_albedo), through a
  colour attribute; what the bake does not see (lamps, curves, text, meshes hidden in the viewport) is hidden
  from render;
- Cycles bakes diffuse direct light × albedo into a colour attribute (plus indirect light, with as many diffuse
  bounces as the bake, for interreflected bakes), in passes with different seeds. Their spread measures Cycles'
  own noise, which is taken out of the measured difference: the two noises are independent, so their squares add.
Everything this changes in the scene is put back exactly afterwards.
"""

from contextlib import contextmanager
from dataclasses import dataclass
import math
import time

import bpy
import numpy as np

from . import display, mesh_data
from .core import lights, lobes, shading
from .core.progress import Progress

REFERENCE_ATTRIBUTE = "_prt_cycles_reference"
ALBEDO_ATTRIBUTE = "_prt_validation_albedo"
ENVIRONMENT_SIZE = (256, 512)  # rows, columns: order ≤ 10 is smooth at this resolution
DEFAULT_SAMPLES = 64  # Cycles samples per pass
DEFAULT_PASSES = 4
# Without SH lights in the scene: a sun where a new SH sun starts, Hanning-windowed, over a sky. Its
# reconstruction is nowhere negative at any order (minimum 0.25 at order 4, 0.21 at order 10), so Cycles is lit
# by exactly the light PRT uses.
DEFAULT_SUN = {"theta": math.radians(35.0), "phi": math.radians(-60.0), "angular_radius": 0.2, "irradiance": 2.0}
DEFAULT_SKY = 0.3
DEFAULT_LIGHT = ("a Hanning-windowed sun (θ 35°, φ -60°, radius 0.2 rad, irradiance 2) over a sky of "
                 "radiance 0.3")
CLAMPED_NOTE_ABOVE = 1e-4  # share of the light's magnitude; below it the clamp changes nothing measurable
INTERREFLECTED_MODE = "interreflected"  # compared with Cycles' indirect diffuse light too
# Object types Cycles renders but the bake neither shades nor shadows with.
NOT_BAKED_TYPES = frozenset({"LIGHT", "CURVE", "SURFACE", "META", "FONT", "CURVES", "POINTCLOUD", "VOLUME"})


# -- the light --------------------------------------------------------------------------------------------------
def default_light(order: int) -> np.ndarray:
    """DEFAULT_LIGHT as grey (3, order²) coefficients."""
    direction = shading.direction_from_angles(DEFAULT_SUN["theta"], DEFAULT_SUN["phi"])
    sun = shading.sun_coefficients(order, direction, DEFAULT_SUN["angular_radius"], DEFAULT_SUN["irradiance"])
    grey = lobes.constant_sky(order, DEFAULT_SKY) + lobes.apply_window(sun, lobes.window(order, "hanning"))
    return np.tile(grey, (3, 1))


def scene_light(context, orders) -> tuple[dict, bool]:
    """({order: (3, order²)}, True): the scene's SH lights as the display sums them; ({...}, False): the default
    light, when no SH light of the scene shines."""
    from .ui.lights import scene_lights
    scene = context.evaluated_depsgraph_get().scene_eval
    found = scene_lights(scene)
    if not found:
        return {order: default_light(order) for order in orders}, False
    return lights.LightCache().totals(found, orders, scene.prt_display.window), True


def clamped_fraction(pixels: np.ndarray) -> float:
    """The share of the light's magnitude (∫ |L| dω over the channels) in negative lobes, which Cycles cannot
    emit; pixels is an equirect image (H, W, channels)."""
    solid_angles = lobes.equirect_solid_angles(*pixels.shape[:2])[..., None]
    magnitude = float((np.abs(pixels) * solid_angles).sum())
    return float((np.maximum(-pixels, 0.0) * solid_angles).sum()) / magnitude if magnitude > 0 else 0.0


def environment_image(pixels: np.ndarray, name: str = "PRT band-limited light"):
    """A float equirect image of (H, W, 3) radiance in Blender's layout, negative values clamped to zero."""
    height, width = pixels.shape[:2]
    rgba = np.ones((height, width, 4), dtype=np.float32)
    rgba[..., :3] = np.maximum(pixels, 0.0)
    image = bpy.data.images.new(name, width, height, alpha=True, float_buffer=True)
    image.pixels.foreach_set(rgba.ravel())
    return image


def prt_colours(transfer: np.ndarray, light: np.ndarray, albedo: np.ndarray) -> np.ndarray:
    """ρ · max(Σ_k L_k T_k, 0), (V, 3) float64, for transfer (V, n²) or (V, 3, n²) and albedo ρ (V, 3)."""
    return albedo * np.maximum(shading.shade(transfer, light).astype(np.float64), 0.0)


def vertex_albedo(ob, notes: list) -> np.ndarray:
    """(V, 3) albedo per vertex as the bake reads it, from ob's own materials also while the PRT display's
    materials stand in for them."""
    shown = [slot.material for slot in ob.material_slots]
    for slot, material in zip(ob.material_slots, display.original_materials(ob)):
        slot.material = material
    try:
        return mesh_data.vertex_albedo(ob, ob.data, notes)
    finally:
        for slot, material in zip(ob.material_slots, shown):
            slot.material = material


# -- the comparison ---------------------------------------------------------------------------------------------
@dataclass
class Comparison:
    """PRT's colours against the mean of Cycles' passes. Every value is relative to the RMS over vertices of
    ‖Cycles‖ (RGB norms), so dark vertices do not divide by zero."""
    name: str
    vertices: int
    measured: float        # RMS over vertices of ‖PRT − Cycles‖
    cycles_noise: float    # RMS of the noise of Cycles' mean, from the spread of its passes
    max_difference: float  # largest ‖PRT − Cycles‖, Cycles' noise included

    @property
    def error(self) -> float:
        """PRT's own RMS error: the measured difference with Cycles' independent noise taken out."""
        return math.sqrt(max(self.measured ** 2 - self.cycles_noise ** 2, 0.0))

    def text(self) -> str:
        return (f"error {100 * self.error:.2f} % RMS (measured {100 * self.measured:.2f} %, "
                f"Cycles noise {100 * self.cycles_noise:.2f} %), max {100 * self.max_difference:.1f} %")

    def as_dict(self) -> dict:
        return {"vertices": self.vertices, "rel_rms_error": self.error, "measured_rel_rms": self.measured,
                "cycles_noise_rel_rms": self.cycles_noise, "rel_max_difference": self.max_difference}


def compare(name: str, prt: np.ndarray, passes: np.ndarray) -> Comparison:
    """prt (V, 3) against Cycles' passes (k ≥ 2, V, 3): equal samples, different seeds."""
    cycles = passes.mean(axis=0)
    scale = float(np.sqrt(np.mean(np.sum(cycles ** 2, axis=1)))) or 1.0
    difference = np.linalg.norm(prt - cycles, axis=1)
    noise = np.sum(passes.var(axis=0, ddof=1), axis=1) / len(passes)  # per vertex, variance of the mean
    return Comparison(name, len(prt), float(np.sqrt(np.mean(difference ** 2))) / scale,
                      float(np.sqrt(np.mean(noise))) / scale, float(difference.max(initial=0.0)) / scale)


# -- Cycles -----------------------------------------------------------------------------------------------------
@dataclass
class LightGroup:
    """Receivers baked under the same conditions: one SH order (so one light), and the same bounces (None: direct
    light only)."""
    objects: list
    environment: np.ndarray  # (H, W, 3) equirect reconstruction of the light
    bounces: int | None
    indirect_only: bool = False  # only the bounced light: what colour bleeding is made of


class CyclesReference:
    """Cycles' diffuse radiance × albedo at the receivers' vertices: per light group, `passes` bakes of `samples`
    each with different seeds. step() runs one bake; the scene is restored after the last one or on cancel()."""

    def __init__(self, context, groups: list, albedos: dict, samples: int, passes: int):
        self.context = context
        self.groups = groups
        self.albedos = albedos  # every rendered mesh object → (V, 3)
        self.samples = samples
        self.passes = passes
        self.radiance = {ob.name: [] for group in groups for ob in group.objects}  # (V, 3) per pass
        self.time_s = 0.0
        self.progress = Progress("PRT validate")
        self._work = self._all_passes()
        self._total_vertices = passes * sum(len(ob.data.vertices) for group in groups for ob in group.objects)
        self._done_vertices = 0
        self.finished = False

    def step(self, budget_s=None) -> bool:
        """Runs one pass, whatever `budget_s` (a Cycles bake cannot be split); True once all have run."""
        if not self.finished:
            self.finished = next(self._work, StopIteration) is StopIteration
        return self.finished

    def cancel(self):
        self._work.close()  # leaves the `with` below: the scene is restored

    def _all_passes(self):
        receivers = [ob for group in self.groups for ob in group.objects]
        with _scene_restored(self.context, list(self.albedos)) as created:
            environment = _prepare_scene(self.context, receivers, self.albedos, self.samples, created)
            first = True
            for group in self.groups:
                image = environment_image(group.environment)
                created.append((bpy.data.images, image))
                environment.image = image
                for seed in range(self.passes):
                    if not first:
                        yield  # one pass per step; the last step also restores the scene
                    first = False
                    self._bake(group, seed)

    def _bake(self, group: LightGroup, seed: int):
        context = self.context
        cycles = context.scene.cycles
        cycles.seed = seed
        if group.bounces is not None:
            cycles.max_bounces = cycles.diffuse_bounces = group.bounces
        names = {ob.name for ob in group.objects}
        for ob in context.view_layer.objects:
            ob.select_set(ob.name in names)
        context.view_layer.objects.active = group.objects[0]
        start = time.perf_counter()
        bpy.ops.object.bake(type="DIFFUSE", target="VERTEX_COLORS", use_selected_to_active=False,
                            pass_filter={"COLOR"} | ({"INDIRECT"} if group.bounces else set())
                            | (set() if group.indirect_only else {"DIRECT"}))
        self.time_s += time.perf_counter() - start
        for ob in group.objects:
            values = np.empty(len(ob.data.vertices) * 4, dtype=np.float32)
            ob.data.color_attributes[REFERENCE_ATTRIBUTE].data.foreach_get("color", values)
            self.radiance[ob.name].append(values.reshape(-1, 4)[:, :3].astype(np.float64))
            self._done_vertices += len(ob.data.vertices)
        self.progress.fraction = self._done_vertices / max(1, self._total_vertices)


def _prepare_scene(context, receivers, albedos, samples, created):
    """Cycles on the CPU, a World showing an environment texture (returned, its image set per light group), a
    Diffuse BSDF coloured by its per-vertex albedo on every rendered mesh, what the bake does not see hidden, and
    a colour attribute to bake into on each receiver."""
    scene = context.scene
    scene.render.engine = "CYCLES"
    scene.cycles.device = "CPU"
    scene.cycles.samples = samples
    scene.cycles.sample_clamp_indirect = 0.0  # a clamp would darken the bounced light: no bias wanted
    world = bpy.data.worlds.new("PRT validation")
    created.append((bpy.data.worlds, world))
    if world.node_tree is None:  # before Blender 5.0 new worlds have no node tree
        world.use_nodes = True
    nodes = world.node_tree.nodes
    environment = nodes.new("ShaderNodeTexEnvironment")
    background = next(node for node in nodes if node.type == "BACKGROUND")
    world.node_tree.links.new(environment.outputs["Color"], background.inputs["Color"])
    scene.world = world
    material = _diffuse_material()
    created.append((bpy.data.materials, material))
    for ob, albedo in albedos.items():
        ob.data.color_attributes.new(ALBEDO_ATTRIBUTE, "FLOAT_COLOR", "POINT")
        rgba = np.concatenate([albedo, np.ones((len(albedo), 1))], axis=1).astype(np.float32)
        ob.data.color_attributes[ALBEDO_ATTRIBUTE].data.foreach_set("color", rgba.ravel())
        if not ob.material_slots:  # else Cycles' default surface, a Principled BSDF, would shade it
            ob.data.materials.append(None)
        for slot in ob.material_slots:
            slot.material = material
    for ob in _not_baked(context, receivers):
        ob.hide_render = True
    for ob in receivers:
        attributes = ob.data.color_attributes
        attributes.new(REFERENCE_ATTRIBUTE, "FLOAT_COLOR", "POINT")
        attributes.active_color = attributes[REFERENCE_ATTRIBUTE]  # what a vertex-colour bake writes
    return environment


def rendered_meshes(context, receivers):
    """The meshes Cycles renders and the bake sees: visible ones, and the receivers."""
    names = {ob.name for ob in receivers}
    return [ob for ob in context.view_layer.objects
            if ob.type == "MESH" and not ob.hide_render and (ob.visible_get() or ob.name in names)]


def _not_baked(context, receivers):
    """Objects Cycles would render that the bake does not see: other object types, and hidden meshes."""
    names = {ob.name for ob in receivers}
    return [ob for ob in context.view_layer.objects if not ob.hide_render and (
        ob.type in NOT_BAKED_TYPES or ob.type == "MESH" and not ob.visible_get() and ob.name not in names)]


def _diffuse_material():
    """A Diffuse BSDF whose colour is each mesh's ALBEDO_ATTRIBUTE."""
    material = display.new_node_material("PRT validation")
    nodes, links = material.node_tree.nodes, material.node_tree.links
    albedo = nodes.new("ShaderNodeVertexColor")
    albedo.layer_name = ALBEDO_ATTRIBUTE
    diffuse = nodes.new("ShaderNodeBsdfDiffuse")
    output = nodes.new("ShaderNodeOutputMaterial")
    links.new(albedo.outputs["Color"], diffuse.inputs["Color"])
    links.new(diffuse.outputs["BSDF"], output.inputs["Surface"])
    return material


@contextmanager
def _scene_restored(context, meshes):
    """Puts back the world, render settings, materials, render visibility, colour attributes and selection, then
    removes every data-block the body added to the yielded list as (collection, block)."""
    scene = context.scene
    layer_objects = list(context.view_layer.objects)
    saved = {
        "world": scene.world, "engine": scene.render.engine,
        "cycles": {key: getattr(scene.cycles, key) for key in
                   ("device", "samples", "seed", "max_bounces", "diffuse_bounces", "sample_clamp_indirect")},
        "materials": {ob: [slot.material for slot in ob.material_slots] for ob in layer_objects
                      if ob.type == "MESH"},
        "hide_render": {ob: ob.hide_render for ob in layer_objects},
        "colours": {ob: (ob.data.color_attributes.active_color_name, ob.data.color_attributes.default_color_name)
                    for ob in meshes},
        "selected": [ob for ob in layer_objects if ob.select_get()],
        "active": context.view_layer.objects.active,
    }
    created = []
    try:
        yield created
    finally:
        scene.world = saved["world"]
        scene.render.engine = saved["engine"]
        for key, value in saved["cycles"].items():
            setattr(scene.cycles, key, value)
        for ob, materials in saved["materials"].items():
            if not materials and ob.data.materials:
                ob.data.materials.clear()  # the slot given above (pop would leave the object a stale empty slot)
            for slot, material in zip(ob.material_slots, materials):
                slot.material = material
        for ob, hidden in saved["hide_render"].items():
            ob.hide_render = hidden
        for ob, (active, default) in saved["colours"].items():
            attributes = ob.data.color_attributes
            for name in (REFERENCE_ATTRIBUTE, ALBEDO_ATTRIBUTE):
                if name in attributes:
                    attributes.remove(attributes[name])
            if active:
                attributes.active_color_name = active
            if default:
                attributes.default_color_name = default
        for ob in layer_objects:
            ob.select_set(ob in saved["selected"])
        context.view_layer.objects.active = saved["active"]
        for collection, block in reversed(created):  # the world before the image it shows
            collection.remove(block)


# -- validation -------------------------------------------------------------------------------------------------
class Validation:
    """The receivers' PRT colours against Cycles under the same light; shared by the operator and the command
    line. Receivers are the named objects, else the selected meshes, else every visible mesh, that have a bake."""

    def __init__(self, context, samples: int = DEFAULT_SAMPLES, passes: int = DEFAULT_PASSES, object_names=None):
        if samples < 1:
            raise mesh_data.InputError(f"Cycles samples must be at least 1, not {samples}")
        if passes < 2:
            raise mesh_data.InputError(f"passes must be at least 2 (Cycles' noise is measured from their spread), "
                                       f"not {passes}")
        context.view_layer.update()
        self.problems: list[str] = []  # one sentence per object that is not validated
        self.notes: list[str] = []     # validated, but the user should know
        self.receivers = self._receivers(context, object_names)  # (object, bake metadata)
        orders = sorted({meta["order"] for _, meta in self.receivers})
        self.lights, self.scene_light = scene_light(context, orders)
        if not self.scene_light:
            self.notes.append(f"no SH lights in the scene: validating under the default light, {DEFAULT_LIGHT}")
        environments = {order: lobes.reconstruct_equirect(self.lights[order], *ENVIRONMENT_SIZE) for order in orders}
        self.clamped = {order: clamped_fraction(pixels) for order, pixels in environments.items()}
        for order, share in self.clamped.items():
            if share > CLAMPED_NOTE_ABOVE:
                self.notes.append(
                    f"the order-{order} light rings: {100 * share:.2f} % of it is negative, which Cycles cannot "
                    f"emit, so Cycles sees a clamped light and the two differ; a Window (Display panel) removes it")
        receivers = [ob for ob, _ in self.receivers]
        self.albedos = {ob: vertex_albedo(ob, self.notes) for ob in rendered_meshes(context, receivers)}
        unshadowed = [ob.name for ob, meta in self.receivers if meta["mode"] == "unshadowed"]
        if unshadowed:
            self.notes.append(f"{', '.join(map(repr, unshadowed))}: unshadowed bakes, while Cycles casts shadows; "
                              f"they agree only where nothing occludes")
        groups = {}
        for ob, meta in self.receivers:
            key = (meta["order"], meta.get("bounces") if meta["mode"] == INTERREFLECTED_MODE else None)
            groups.setdefault(key, LightGroup([], environments[key[0]], key[1])).objects.append(ob)
        self.cycles = CyclesReference(context, list(groups.values()), self.albedos, samples, passes)
        self.shade_time_s = 0.0

    def _receivers(self, context, object_names):
        found = []
        for ob in mesh_data.receivers_from_selection(context, object_names):
            try:
                mesh_data.check_writable(ob)
                _, meta = mesh_data.read_transfer(ob.data)
            except (mesh_data.InputError, mesh_data.StaleBake) as problem:
                self.problems.append(str(problem))
                continue
            if ob.hide_render:
                self.problems.append(f"{ob.name!r} is hidden from render, so Cycles cannot bake it")
                continue
            found.append((ob, meta))
        if not found:
            raise mesh_data.InputError("nothing to validate: " + ("; ".join(self.problems) or "no mesh objects"))
        return found

    @property
    def progress(self):
        return self.cycles.progress

    def step(self, budget_s=None) -> bool:
        return self.cycles.step(budget_s)

    def cancel(self):
        self.cycles.cancel()

    def run(self, log=print) -> list:
        """All Cycles passes with a progress line after each (background mode, command line); the comparisons."""
        while not self.step():
            log(self.progress.line())
        log(self.progress.line())
        return self.comparisons()

    def comparisons(self) -> list:
        """Per receiver, and last all vertices together: its current PRT colours against Cycles' passes."""
        start = time.perf_counter()
        colours = []
        for ob, meta in self.receivers:
            transfer, _ = mesh_data.read_transfer(ob.data)
            colours.append(prt_colours(transfer, self.lights[meta["order"]], self.albedos[ob]))
        self.shade_time_s = time.perf_counter() - start
        passes = [np.stack(self.cycles.radiance[ob.name]) for ob, _ in self.receivers]
        return ([compare(ob.name, prt, cycles) for (ob, _), prt, cycles in zip(self.receivers, colours, passes)]
                + [compare("all", np.concatenate(colours), np.concatenate(passes, axis=1))])

    def bake_time_s(self) -> float:
        """Seconds of the bakes validated. Objects baked together store the same date and time, which tell one
        bake from another (each mesh's bake_id is its own)."""
        return sum({(meta["date"], meta.get("time_s", 0.0)): meta.get("time_s", 0.0)
                    for _, meta in self.receivers}.values())

    def lines(self, comparisons) -> list[str]:
        """The summary line, then one line per object."""
        overall = comparisons[-1]
        light = "scene light" if self.scene_light else "default light"
        summary = (f"PRT validate: {len(self.receivers)} objects, {overall.vertices} vertices vs Cycles "
                   f"({self.cycles.passes} × {self.cycles.samples} samples): {overall.text()}; "
                   f"PRT bake {self.bake_time_s():.1f} s, shading {1000 * self.shade_time_s:.0f} ms, "
                   f"Cycles {self.cycles.time_s:.1f} s; {light}, {100 * max(self.clamped.values()):.2f} % clamped")
        return [summary] + [f"  {c.name}: {c.text()}" for c in comparisons[:-1]]

    def report_dict(self, comparisons) -> dict:
        metadata = {ob.name: meta for ob, meta in self.receivers}
        return {
            "objects": [ob.name for ob, _ in self.receivers], **comparisons[-1].as_dict(),
            "cycles": {"samples": self.cycles.samples, "passes": self.cycles.passes, "device": "CPU",
                       "time_s": self.cycles.time_s},
            "prt": {"bake_time_s": self.bake_time_s(), "shade_time_s": self.shade_time_s},
            "light": {"source": "scene" if self.scene_light else "default",
                      "description": None if self.scene_light else DEFAULT_LIGHT,
                      "clamped_fraction": {str(order): share for order, share in self.clamped.items()}},
            "per_object": {c.name: {**c.as_dict(), **_bake_facts(metadata[c.name])}
                           for c in comparisons[:-1]},
            "notes": self.notes, "problems": self.problems,
        }


def _bake_facts(meta) -> dict:
    return {"order": meta["order"], "mode": meta["mode"], "samples": meta["samples"],
            "est_rms_rel_error": meta["est_rms_rel_error"], "bake_time_s": meta.get("time_s", 0.0)}
