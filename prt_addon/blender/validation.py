"""Validation against Cycles: the baked receivers' PRT colours compared with Cycles (blender.cycles) under the same
light, and the report.

PRT with a light band-limited to the bake's order is exact up to Monte Carlo noise (∫ L̃·T = Σ L̃_k T_k), so
Cycles lit by the SH-reconstructed environment must agree with it. The light is the scene's SH lights, summed and
windowed as the display shows them (core.lights.default_light when there are none). Cycles' noise, measured from
the spread of its passes, is taken out of the measured difference: the two noises are independent, so their
squares add (core.statistics), in the RMS and vertex by vertex, for the 99th percentile and the worst vertices.
The report names the object with the largest p99 and where its worst vertices are (indices and world positions).

A dynamic object's bake is its own, against itself only, in its own frame: it is shaded as the display shades it,
each vertex from the light the probe volume around it carries there (blender.relighting.dynamic_radiance), or with
one light (displayed_light: the distant light, or what the probes carry to its centre), turned into its frame.
Outside every probe volume nothing of the scene reaches it, so Cycles renders it alone, the other meshes hidden
from its pass; inside one, Cycles renders it in the scene.

With reference "light", Cycles also runs under the scene's lights as they are (an environment's image itself, a
sun as a Sun lamp, a sky as a constant: cycles.real_light_world), and the report adds that total error beside
PRT's own and their difference, what band-limiting the light costs. A sun split off an environment is drawn by its
lamp, not by PRT, so there the vertices are compared with Cycles under the image without its sun (a note says so);
the hybrid is compared in image space (blender.image_validation).
"""

from dataclasses import asdict, dataclass
import time

import numpy as np

from ..core import lights, lobes, sh, shading
from ..core.errors import InputError
from ..core.progress import WrappingJob
from ..core.statistics import clamped_fraction, compare, worst_object
from . import geometry, layouts, materials, mesh_arrays, storage
from .cycles import CyclesReference, LightGroup, rendered_meshes
from .lights import scene_lights, split_sun
from .probe_volumes import light_at
from .relighting import Relighter, bounds_centre, displayed_light, dynamic_radiance, is_dynamic

ENVIRONMENT_SIZE = (256, 512)  # rows, columns: order ≤ 10 is smooth at this resolution
DEFAULT_SAMPLES = 64  # Cycles samples per pass
DEFAULT_PASSES = 4
REFERENCES = ("band-limited", "light")  # what Cycles is lit by: the light PRT uses, or also the real light
CLAMPED_NOTE_ABOVE = 1e-4  # share of the light's magnitude; below it the clamp changes nothing measurable
INTERREFLECTED_MODE = "interreflected"  # compared with Cycles' indirect diffuse light too


def scene_light(context, orders) -> tuple[dict, bool]:
    """({order: (3, order²)}, True): the scene's SH lights as the display sums them; ({...}, False): the default
    light, when no SH light of the scene shines."""
    scene = context.evaluated_depsgraph_get().scene_eval
    found = scene_lights(scene)
    if not found:
        return {order: lights.default_light(order) for order in orders}, False
    return lights.LightCache().totals(found, orders, scene.prt_display.window), True


def prt_colours(transfer: np.ndarray, light: np.ndarray, albedo: np.ndarray) -> np.ndarray:
    """ρ · max(Σ_k L_k T_k, 0), (V, 3) float64, for transfer (V, n²) or (V, 3, n²) and albedo ρ (V, 3)."""
    return albedo * np.maximum(shading.shade(transfer, light).astype(np.float64), 0.0)


@dataclass
class ValidationReport:
    """What `validate --report` writes."""
    objects: list
    vertices: int
    rel_rms_error: float
    measured_rel_rms: float
    cycles_noise_rel_rms: float
    rel_p99_error: float
    measured_rel_p99: float
    rel_max_difference: float
    worst: dict  # {"object": name, "vertices": [{"index", "rel_error", "position"}, ...]}
    cycles: dict
    prt: dict
    light: dict
    per_object: dict
    notes: list
    problems: list
    real_light: dict | None = None  # reference "light": {rel_rms_error, own_rel_rms_error, band_limiting, ...}

    def as_dict(self) -> dict:
        return asdict(self)


class Validation(WrappingJob):
    """The receivers' PRT colours against Cycles under the same light; shared by the operator and the command
    line. Receivers are the named objects, else the selected meshes, else every visible mesh, that have a bake."""

    def __init__(self, context, samples: int = DEFAULT_SAMPLES, passes: int = DEFAULT_PASSES, object_names=None,
                 reference: str = REFERENCES[0]):
        if reference not in REFERENCES:
            raise InputError(f"reference must be one of {', '.join(REFERENCES)}, not {reference!r}")
        if samples < 1:
            raise InputError(f"Cycles samples must be at least 1, not {samples}")
        if passes < 2:
            raise InputError(f"passes must be at least 2 (Cycles' noise is measured from their spread), "
                                       f"not {passes}")
        context.view_layer.update()
        self.context = context  # as CyclesReference keeps it, for where the worst vertices are
        self.problems: list[str] = []  # one sentence per object that is not validated
        self.notes: list[str] = []     # validated, but the user should know
        self.receivers = self._receivers(context, object_names)  # (object, bake metadata)
        orders = sorted({storage.light_order(meta) for _, meta in self.receivers})
        self.lights, self.scene_light = scene_light(context, orders)
        if not self.scene_light:
            self.notes.append(f"no SH lights in the scene: validating under the default light, {lights.DEFAULT_LIGHT}")
        environments = {order: lobes.reconstruct_equirect(self.lights[order], *ENVIRONMENT_SIZE) for order in orders}
        self.clamped = {order: clamped_fraction(pixels) for order, pixels in environments.items()}
        for order, share in self.clamped.items():
            if share > CLAMPED_NOTE_ABOVE:
                self.notes.append(
                    f"the order-{order} light rings: {100 * share:.2f} % of it is negative, which Cycles cannot "
                    f"emit, so Cycles sees a clamped light and the two differ; a Window (Display panel) removes it")
        receivers = [ob for ob, _ in self.receivers]
        self.albedos = {ob: materials.vertex_albedo(ob, ob.data, self.notes)
                        for ob in rendered_meshes(context, receivers)}
        unshadowed = [ob.name for ob, meta in self.receivers if meta["mode"] == "unshadowed"]
        if unshadowed:
            self.notes.append(f"{', '.join(map(repr, unshadowed))}: unshadowed bakes, while Cycles casts shadows; "
                              f"they agree only where nothing occludes")
        self.probes = Relighter().probes(context.scene)
        groups = {}
        for ob, meta in self.receivers:
            alone = ob.name if self._alone(ob, meta) else None
            bounces = meta.get("bounces") if meta["mode"] == INTERREFLECTED_MODE else None
            key = (storage.light_order(meta), bounces, alone)
            groups.setdefault(key, LightGroup([], environments[key[0]], key[1], alone=alone is not None)
                              ).objects.append(ob)
        per_corner = {ob.name for ob, meta in self.receivers if meta.get("domain") == "CORNER"}
        if per_corner:
            self.notes.append(f"{', '.join(map(repr, sorted(per_corner)))}: baked per face corner (vertices split "
                              f"by their corner normals), so compared with Cycles corner by corner")
        self.cycles = CyclesReference(context, list(groups.values()), self.albedos, samples, passes, per_corner)
        self.light_cycles = None  # Cycles under the real light, for reference "light"
        if reference == "light":
            self.light_cycles = self._real_light_reference(samples, passes, per_corner)
        self.shade_time_s = 0.0

    def _receivers(self, context, object_names):
        found = []
        # Unnamed and no selected mesh has a bake (a file saved with its floor selected): every visible one that has.
        candidates = (geometry.receivers_from_selection(context, object_names)
                      if object_names or storage.baked_objects(context.selected_objects)
                      else storage.baked_objects(context.view_layer.objects))
        for ob in candidates:
            try:
                geometry.check_writable(ob)
                _, meta = storage.read_transfer(ob.data)
            except InputError as problem:
                self.problems.append(str(problem))
                continue
            if ob.hide_render:
                self.problems.append(f"{ob.name!r} is hidden from render, so Cycles cannot bake it")
                continue
            found.append((ob, meta))
        if not found:
            raise InputError("nothing to validate: " + ("; ".join(self.problems) or "no mesh objects"))
        return found

    def _alone(self, ob, meta) -> bool:
        """A dynamic object outside every probe volume: only the distant light reaches it."""
        light = self.lights[storage.light_order(meta)]
        return is_dynamic(ob.data) and light_at(self.probes, bounds_centre(ob), light) is None

    def _real_light_reference(self, samples, passes, per_corner):
        scene = self.context.scene
        if not self.scene_light:
            raise InputError("validating against the real light needs the scene's SH lights; it has none")
        split = [entry.name for entry in scene.prt_lights if split_sun(entry, scene) is not None]
        if split:
            self.notes.append(f"{', '.join(map(repr, split))}: the sun split off into a lamp is not PRT's; the "
                              f"vertices are compared with Cycles under the rest of the light (image space compares "
                              f"the hybrid)")
        groups = {}
        for ob, meta in self.receivers:
            bounces = meta.get("bounces") if meta["mode"] == INTERREFLECTED_MODE else None
            alone = ob.name if self._alone(ob, meta) else None
            groups.setdefault((bounces, alone), LightGroup([], None, bounces, alone=alone is not None)
                              ).objects.append(ob)
        return CyclesReference(self.context, list(groups.values()), self.albedos, samples, passes, per_corner,
                               scene_light=True)

    def _jobs(self) -> list:
        return [job for job in (self.cycles, self.light_cycles) if job is not None]

    def inner(self) -> CyclesReference:
        """Its steps are Cycles' passes, one a step (a pass cannot be split, whatever the budget): under the
        band-limited light, then under the real light."""
        return next((job for job in self._jobs() if not job.finished), self._jobs()[-1])

    def step(self, budget_s: float) -> bool:
        self.inner().step(budget_s)
        return all(job.finished for job in self._jobs())

    def cancel(self):
        for job in self._jobs():
            if not job.finished:
                job.cancel()

    def outcome(self) -> list:
        return self.comparisons()

    def comparisons(self) -> list:
        """Per receiver, and last all vertices together: its current PRT colours against Cycles' passes."""
        return self._compared(self._prt_colours(), self.cycles)

    def light_comparisons(self) -> list | None:
        """As comparisons(), against Cycles under the real light; None unless the reference is "light"."""
        return None if self.light_cycles is None else self._compared(self._prt_colours(), self.light_cycles)

    def _compared(self, colours, cycles) -> list:
        passes = [np.stack(cycles.radiance[ob.name]) for ob, _ in self.receivers]
        return ([compare(ob.name, prt, cycles) for (ob, _), prt, cycles in zip(self.receivers, colours, passes)]
                + [compare("all", np.concatenate(colours), np.concatenate(passes, axis=1))])

    def _prt_colours(self) -> list:
        start = time.perf_counter()
        colours = []
        probes = Relighter().probes(self.context.scene)  # as they are now: a volume may have been baked again since
        for ob, meta in self.receivers:
            light, radiance = self.lights[storage.light_order(meta)], None
            if is_dynamic(ob.data):  # lit per vertex through the probes, as the display shades it where it stands
                baked = layouts.stored(ob.data).read(ob.data)
                radiance = dynamic_radiance(ob, ob, baked, baked.layout.points(ob.data, baked), light, probes)
            colours.append(self.colours(ob, displayed_light(ob, light, probes), radiance))
        self.shade_time_s = time.perf_counter() - start
        return colours

    def colours(self, ob, light, radiance=None) -> np.ndarray:
        """The receiver's PRT colours under `light` (3, n²) in its transfer's frame (fitted to its transfer's order,
        core.sh.fitted), or from `radiance` (P, 3) formed per shading point (blender.relighting.dynamic_radiance),
        per vertex, or per face corner where its bake is per corner, as Cycles bakes it."""
        transfer, _ = storage.read_transfer(ob.data)
        corner_points = storage.corner_points_of(ob.data)
        albedo = self.albedos[ob]
        if corner_points is not None:
            transfer, albedo = transfer[corner_points], albedo[mesh_arrays.mesh_corner_vertices(ob.data)]
            radiance = None if radiance is None else radiance[corner_points]
        if radiance is None:
            return prt_colours(transfer, sh.fitted(light, transfer.shape[-1]), albedo)
        return albedo * np.maximum(radiance, 0.0)

    def store_errors(self, comparisons):
        """Each receiver's per-vertex (per-corner) error against Cycles on its mesh, for the viewport's Difference
        from Cycles heatmap (storage.VALIDATION_ERROR_ATTRIBUTE)."""
        for (ob, _), comparison in zip(self.receivers, comparisons):
            storage.write_validation_error(ob.data, comparison.errors)

    @property
    def vertices(self) -> int:
        """The receivers' mesh vertices (compared per vertex, or per face corner where baked per corner)."""
        return sum(len(ob.data.vertices) for ob, _ in self.receivers)

    def bake_time_s(self) -> float:
        """Seconds of the bakes validated. Objects baked together store the same date and time, which tell one
        bake from another (each mesh's bake_id is its own)."""
        return sum({(meta["date"], meta.get("time_s", 0.0)): meta.get("time_s", 0.0)
                    for _, meta in self.receivers}.values())

    def lines(self, comparisons) -> list[str]:
        """The summary line, then one line per object."""
        overall = comparisons[-1]
        light = "scene light" if self.scene_light else "default light"
        summary = (f"PRT validate: {len(self.receivers)} objects, {self.vertices} vertices vs Cycles "
                   f"({self.cycles.passes} × {self.cycles.samples} samples): {overall.text()}; "
                   f"PRT bake {self.bake_time_s():.1f} s, shading {1000 * self.shade_time_s:.0f} ms, "
                   f"Cycles {self.cycles.time_s:.1f} s; {light}, {100 * max(self.clamped.values()):.2f} % clamped")
        return ([summary] + [f"  {c.name}: {c.text()}" for c in comparisons[:-1]] + [self.worst_line(comparisons)]
                + self.light_lines(comparisons))

    def light_lines(self, comparisons) -> list[str]:
        """Against the real light: the total error, PRT's own (the band-limited comparison) and what band-limiting
        costs, overall and per object; nothing unless the reference is "light"."""
        real = self.light_comparisons()
        if real is None:
            return []
        rows = [f"  {'overall' if own.name == 'all' else own.name}: total {100 * total.error:.2f} % RMS, PRT's own "
                f"{100 * own.error:.2f} %, band-limiting {100 * (total.error - own.error):+.2f} points"
                for own, total in zip(comparisons[-1:] + comparisons[:-1], real[-1:] + real[:-1])]
        return [f"Against the real light (Cycles {self.light_cycles.passes} × {self.light_cycles.samples} samples, "
                f"{self.light_cycles.time_s:.1f} s, its noise {100 * real[-1].cycles_noise:.2f} %):"] + rows

    def worst_line(self, comparisons) -> str:
        """The worst object, its worst vertices' indices and errors, and where the worst one is."""
        worst = self.worst(comparisons)
        p99 = next(c.p99 for c in comparisons[:-1] if c.name == worst["object"])
        kind, kinds = ("vertex", "vertices") if worst["domain"] == "POINT" else ("corner", "corners")
        rows = ", ".join(f"{v['index']} ({100 * v['rel_error']:.1f} %)" for v in worst["vertices"])
        first = worst["vertices"][0]
        return (f"  worst: {worst['object']}, p99 {100 * p99:.1f} %; {kinds} {rows}; {kind} {first['index']} "
                f"at ({', '.join(f'{x:.2f}' for x in first['position'])})")

    def worst(self, comparisons) -> dict:
        """The object with the largest p99 (core.statistics.worst_object) and its worst vertices (face corners
        where its bake is per corner: `domain`), largest error first: index, error (relative to the RMS of the
        object's Cycles colours, Cycles' noise taken out) and world position, as the viewport shows it."""
        found = worst_object(comparisons[:-1])
        ob, meta = next((ob, meta) for ob, meta in self.receivers if ob.name == found.name)
        indices = [index for index, _ in found.worst]
        domain = meta.get("domain", "POINT")
        vertices = indices if domain == "POINT" else mesh_arrays.mesh_corner_vertices(ob.data)[indices]
        positions = world_positions(self.context, ob, vertices)
        return {"object": found.name, "domain": domain,
                "vertices": [{"index": index, "rel_error": error, "position": [float(x) for x in position]}
                             for (index, error), position in zip(found.worst, positions)]}

    def report(self, comparisons) -> ValidationReport:
        metadata = {ob.name: meta for ob, meta in self.receivers}
        overall = comparisons[-1].as_dict()
        del overall["vertices"]
        return ValidationReport(
            objects=[ob.name for ob, _ in self.receivers], vertices=self.vertices, **overall,
            cycles={"samples": self.cycles.samples, "passes": self.cycles.passes, "device": "CPU",
                    "time_s": self.cycles.time_s},
            prt={"bake_time_s": self.bake_time_s(), "shade_time_s": self.shade_time_s},
            light={"source": "scene" if self.scene_light else "default",
                   "description": None if self.scene_light else lights.DEFAULT_LIGHT,
                   "clamped_fraction": {str(order): share for order, share in self.clamped.items()}},
            per_object={c.name: {**c.as_dict(), **_bake_facts(metadata[c.name])} for c in comparisons[:-1]},
            worst=self.worst(comparisons),
            notes=self.notes, problems=self.problems, real_light=self._real_light_report(comparisons))

    def _real_light_report(self, comparisons) -> dict | None:
        real = self.light_comparisons()
        if real is None:
            return None

        def errors(own, total):
            return {"rel_rms_error": total.error, "measured_rel_rms": total.measured,
                    "cycles_noise_rel_rms": total.cycles_noise, "rel_p99_error": total.p99,
                    "own_rel_rms_error": own.error, "band_limiting": total.error - own.error}

        return {**errors(comparisons[-1], real[-1]),
                "cycles": {"samples": self.light_cycles.samples, "passes": self.light_cycles.passes,
                           "time_s": self.light_cycles.time_s},
                "per_object": {own.name: errors(own, total) for own, total in zip(comparisons[:-1], real[:-1])}}


def world_positions(context, ob, indices) -> np.ndarray:
    """World positions (N, 3) of the object's vertices `indices` on its evaluated mesh, which the bake and Cycles
    saw (the original mesh's, if its modifiers have since changed the vertex count)."""
    evaluated = ob.evaluated_get(context.evaluated_depsgraph_get())
    mesh = evaluated.to_mesh()
    try:
        positions = mesh_arrays.mesh_positions(mesh if len(mesh.vertices) == len(ob.data.vertices) else ob.data)
    finally:
        evaluated.to_mesh_clear()
    return geometry.points_to_world(np.array(evaluated.matrix_world), positions[np.asarray(indices, dtype=int)])


def _bake_facts(meta) -> dict:
    return {"order": meta["order"], "mode": meta["mode"], "samples": meta["samples"],
            "est_rms_rel_error": meta["est_rms_rel_error"], "bake_time_s": meta.get("time_s", 0.0)}
