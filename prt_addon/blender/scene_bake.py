"""One bake of a Blender scene, shared by the operator (modal or not) and the command line, and its report.

Nothing is written until every receiver is baked: a cancelled or failed bake leaves the previous data as it was.
"""

from dataclasses import asdict, dataclass, field, replace
import sys

import bpy
import numpy as np

from ..core import bake, corners, executors, interpolation, job, lobes, settings as spec, subsurface
from ..core.errors import InputError
from ..core.progress import JobSequence, WrappingJob, old_objects_frozen
from . import fingerprint, geometry, layouts, materials, texel_bake
from .occluders import occluders_from_depsgraph


INTERPOLATION_KEYS = ("est_interp_rms_rel_error", "est_interp_max_rel_error", "interp_points")


def _vertex_count(surface) -> int:
    """The surface's vertices (a split vertex's points share its position): probes follow the surface, not how
    finely its normals split it."""
    return len(corners.unique_rows(surface.vertex_positions)[0])


def local_executor(workers: int):
    """How `workers` processes bake on this machine (core.executors): this process alone for one; else workers
    running Blender's own binary in a real Blender; with the bpy module, forks of this process on Linux (they start
    in milliseconds instead of importing bpy for a second, and share the ray tree), the module's Python elsewhere
    (macOS and Windows cannot fork a process that runs Blender safely)."""
    if workers <= 1:
        return executors.InProcess()
    if bpy.app.binary_path:
        return executors.SpawnedWorkers(workers, [bpy.app.binary_path, "--background", "--factory-startup",
                                                  "--python-expr"])
    if sys.platform.startswith("linux"):
        return executors.ForkedWorkers(workers)
    return executors.SpawnedWorkers(workers, [sys.executable, "-c"])


def with_subsurface(surface, transfer, weight, mean_free_path, albedo, ior):
    """(1 − w)·T + w·T_sss/albedo per channel: light scattered beneath the surface (Jensen's dipole, gathered
    from the object's own incident transfer) mixed in by the Subsurface Weight. T_sss carries its colour, and the
    display multiplies by albedo, hence the division."""
    params = subsurface.dipole_parameters(mean_free_path, albedo, ior)
    areas = subsurface.vertex_areas(surface.receiver.positions, surface.triangles)
    scattered = subsurface.subsurface_transfer(surface.receiver.positions, surface.receiver.normals, areas,
                                               transfer, params)  # (V, 3, n²); channel c scatters channel c
    incident = transfer if transfer.ndim == 3 else transfer[:, None, :]
    divided = scattered / np.maximum(albedo, 1e-3)[None, :, None]
    return ((1.0 - weight) * np.broadcast_to(incident, scattered.shape) + weight * divided).astype(np.float32)


def _albedo_channels(albedos):
    """One channel when every surface is grey (transfer stays single-channel), else RGB."""
    grey = all(np.allclose(a, a[:, :1]) for a in albedos)
    return [a[:, :1] if grey else a for a in albedos]


@dataclass
class SolvedSurfaces:
    """The surfaces whose transfer the bake solves, in the one order the job, its results and the occluders'
    first vertices share: the receivers (stored on their objects), then the bouncers (visible meshes that only
    reflect light onto the receivers, in interreflected bakes)."""
    receivers: list
    bouncers: list = field(default_factory=list)

    @property
    def all(self) -> list:
        return self.receivers + self.bouncers


@dataclass
class BakeReport:
    """What `--report` writes and the demo's report holds: the job's summary, with the objects by name, what was
    not baked (problems) and what the user should know (notes)."""
    summary: job.Summary
    objects: list
    problems: list
    notes: list
    subsurface_objects: list
    storage: list = field(default_factory=list)  # what each texel or Auto object stores, and why

    def as_dict(self) -> dict:
        return {**asdict(self.summary), "objects": self.objects, "problems": self.problems, "notes": self.notes,
                "subsurface_objects": self.subsurface_objects, "storage": self.storage}


class SceneBake(WrappingJob):
    """Gathers receivers and occluders, runs the bake (a TransferJob, and one per finer lattice of texel
    receivers: core.texel_refine), then stores everything at once (its outcome)."""

    @old_objects_frozen()  # gathering makes many lists for Blender and numpy, as a job's steps do
    def __init__(self, context, settings: bake.BakeSettings, object_names=None, workers: int = 1,
                 storage_options=None, farm: bool = False):
        """storage_options: texel_bake.TexelOptions fields that override every receiver's own (the command
        line's). `farm`: a bake whose chunks farm shards bake (bake_only) and a merge stores (blender.farm); it
        stores every receiver per vertex."""
        problems = settings.problems()
        if problems:
            raise InputError("; ".join(problems))
        self.settings = settings
        context.view_layer.update()  # objects linked by scripts join the view layer only on update
        self.problems: list[str] = []  # one sentence per object that will not be baked
        self.notes: list[str] = []     # baked, but the user should know
        depsgraph = context.evaluated_depsgraph_get()
        candidates = geometry.receivers_from_selection(context, object_names)
        bouncing = settings.mode == "interreflected"
        self.objects, receivers, meshes = [], [], {}
        for ob in candidates:
            try:
                if ob.type == "MESH" and ob.data.name in meshes:
                    raise InputError(
                        f"{ob.name!r} shares its mesh with {meshes[ob.data.name]!r}, and the bake depends on "
                        f"where each object is; make it single-user (Object > Relations) to bake both")
                receivers.append(geometry.surface_from_object(ob, depsgraph, self.notes, albedo=bouncing))
                meshes[ob.data.name] = ob.name
                self.objects.append(ob)
            except InputError as problem:
                self.problems.append(str(problem))
        if not receivers:
            raise InputError("nothing to bake: " + ("; ".join(self.problems) or "no mesh objects"))
        if farm:  # before the occluders are gathered
            texel_bake.refuse_on_farm(self.objects, storage_options or {})
        # Taken now, from the scene as it is baked: objects may move while a modal bake runs.
        self.fingerprints = fingerprint.fingerprints(depsgraph, self.objects, settings, storage_options)
        # Every visible mesh reflects light onto the receivers in an interreflected bake, so its transfer is solved
        # too.
        bouncers = self._bouncing_surfaces(context, depsgraph, {ob.name for ob in self.objects}) if bouncing else []
        self.surfaces = SolvedSurfaces(receivers, bouncers)
        occluders = None
        if settings.mode != "unshadowed":
            occluders, sources = occluders_from_depsgraph(depsgraph, self.surfaces.all)
            if sources <= {ob.name for ob in self.objects}:
                self.notes.append("no visible mesh besides the receivers casts shadows; "
                                  "each receiver is shadowed by the receivers only")
        coloured = bouncing and _albedo_channels([s.albedo for s in self.surfaces.all])[0].shape[1] > 1
        planned = texel_bake.plan(self.objects, receivers, occluders, settings, storage_options or {}, depsgraph,
                                  self.problems, coloured)
        if not planned.objects:
            raise InputError("nothing to bake: " + "; ".join(self.problems))
        self.objects, self.surfaces.receivers = planned.objects, planned.surfaces
        self.storage_decisions = planned.decisions
        self.plan = planned  # with Auto's probes, baked before the bake
        self.notes += planned.decisions
        solved = self.surfaces.all
        albedo = _albedo_channels([s.albedo for s in solved]) if bouncing else None
        self.executor = local_executor(spec.worker_count(workers))

        def transfer_job(receivers, gather_only=False):
            return job.TransferJob(receivers, occluders, settings, self.executor,
                                   albedo=None if gather_only else albedo)
        # Texel receivers are baked lattice by lattice, coarse to fine; the first job is the one the checks size.
        self.levels = texel_bake.refining_job(solved, settings, transfer_job)
        self.job = self.levels.first
        self.probes, self.probe_job = self._probe_job(occluders)
        self.sequence = JobSequence([self.levels, self.probe_job],
                                    [self.job.total_vertices, max(1, self.probe_job.total_vertices)], "PRT bake")
        self.summary = None

    def _probe_job(self, occluders):
        """Points inside the receivers' faces, baked after them to measure what storage per vertex loses between
        vertices (core.interpolation); an interreflected bake's probes measure its direct transfer. Not for texel
        receivers (their estimate holds what interpolating between texels may miss: core.texel_refine), nor for
        the objects Auto's probes measured already. A farm shard bakes its share of their chunks too, so the merge
        casts no ray."""
        probes = {surface.receiver.name: interpolation.face_probes(
                      surface.triangles, surface.receiver.positions, surface.receiver.normals,
                      interpolation.probe_count(_vertex_count(surface)), self.settings.seed)
                  for surface in self.surfaces.receivers
                  if not isinstance(surface, texel_bake.TexelSurface)
                  and surface.receiver.name not in self.plan.measured}
        probes = {name: found for name, found in probes.items() if len(found.positions)}
        receivers = [bake.Receiver(name, found.positions, found.normals, bake.Receiver.key_for(name + " probes"))
                     for name, found in probes.items()]
        settings = replace(self.settings, mode="shadowed") if self.settings.mode == "interreflected" else self.settings
        return probes, job.TransferJob(receivers, occluders, settings, self.executor, name="probes")

    def bake_only(self, shard):
        """Bakes only farm shard (K, N)'s chunks of the vertices and of the probes: a farm bake's (`farm`) whole
        scene, gathered once, is shared so between forked shards (commands.farm_dask)."""
        self.executor = executors.FarmShard(shard, self.executor)
        self.job.run_by(self.executor)
        self.probe_job.run_by(self.executor)

    def build_ray_tree(self):
        """Builds the occluders' ray tree now (the jobs keep it), so that shards forked afterwards share it."""
        if self.job.occluders is not None:
            self.job.occluders.ray_caster()

    def _bouncing_surfaces(self, context, depsgraph, receiver_names):
        found = []
        for ob in geometry.visible_mesh_objects(context):
            if ob.name in receiver_names:
                continue
            try:
                found.append(geometry.surface_from_object(ob, depsgraph, self.notes, for_storage=False,
                                                          albedo=True))
            except InputError as problem:
                self.notes.append(f"{problem}; it casts shadows but reflects no light")
        return found

    def inner(self) -> JobSequence:
        return self.sequence

    def outcome(self) -> job.Summary:
        """Stores the bake, once, and returns its summary."""
        return self.summary or self.store()

    def store(self) -> job.Summary:
        """Writes every receiver's transfer (replacing older bakes) and returns the summary."""
        results = self.levels.results()[: len(self.surfaces.receivers)]  # bouncers are not stored
        self.summary = self.levels.summary(results)
        self._count_vertices()
        self._measure_interpolation(results)
        self.subsurface_objects = []
        for ob, surface, result in zip(self.objects, self.surfaces.receivers, results):
            material = materials.subsurface_material(ob) if self.settings.mode != "unshadowed" else None
            if material is not None and isinstance(surface, texel_bake.TexelSurface):
                self.notes.append(f"{ob.name!r}: its Subsurface Weight is left out of its texel bake")
                continue
            if material is not None:
                result.transfer = with_subsurface(surface, result.transfer, *material)
                self.subsurface_objects.append(ob.name)
        if self.levels.states:
            self.storage_decisions.append(f"texel lattices: {self.levels.lattice_line()}")
        for ob, surface, result in zip(self.objects, self.surfaces.receivers, results):
            extra = {"time_s": self.summary.time_s, fingerprint.FINGERPRINT_KEY: self.fingerprints[ob.name],
                     **{key: self.summary.per_object[ob.name][key] for key in INTERPOLATION_KEYS
                        if key in self.summary.per_object[ob.name]}}
            if self.summary.bounces is not None:
                extra["bounces"] = self.summary.bounces
            stored = (layouts.PerTexel(surface.receiver, surface.layout, surface.uv_map)
                      if isinstance(surface, texel_bake.TexelSurface) else layouts.for_surface(surface))
            stored.write(ob.data, result, extra, self.settings)
        return self.summary

    def _measure_interpolation(self, results):
        """The probes' interpolation error per object and overall, into the summary; the bake's time includes them."""
        scale = lobes.unshadowed_norm(self.settings.order)
        probe_results = dict(zip(self.probes, self.probe_job.results()))
        direct = self.job.direct or [result.transfer for result in results]
        everything = []
        for ob, result, transfer in zip(self.objects, results, direct):
            if ob.name in self.plan.measured:
                squared = self.plan.measured[ob.name]
            elif ob.name in self.probes:
                found = probe_results[ob.name]
                squared = interpolation.interpolation_errors(self.probes[ob.name], found.transfer, found.std_error,
                                                             transfer, result.std_error, scale)
            else:
                continue
            everything.append(squared)
            rms, worst = interpolation.summarise(squared)
            self.summary.per_object[ob.name].update(est_interp_rms_rel_error=rms, est_interp_max_rel_error=worst,
                                                    interp_points=len(squared))
        (self.summary.est_interp_rms_rel_error,
         self.summary.est_interp_max_rel_error) = interpolation.summarise(np.concatenate(everything or [[]]))
        self.summary.interp_points = self.probe_job.total_vertices + sum(map(len, self.plan.measured.values()))
        self.summary.interp_rays = self.probe_job.rays + self.plan.probe_rays
        self.summary.phases_s["probes_s"] = self.probe_job.progress.elapsed + self.plan.probe_s
        # A merge's time is the shards' seconds summed plus its own, as its job's summary counts it.
        self.summary.time_s = (self.sequence.progress.elapsed + self.plan.probe_s
                               + self.job.phase_times.get("shards_s", 0.0))

    def _count_vertices(self):
        """The summary in mesh vertices, with the shading points they were split into (core.corners)."""
        for ob, surface in zip(self.objects, self.surfaces.receivers):
            self.summary.per_object[ob.name].update(
                vertices=len(ob.data.vertices), points=len(surface.receiver.positions),
                split_vertices=surface.split_vertices)
        self.summary.vertices = sum(entry["vertices"] for entry in self.summary.per_object.values())
        self.summary.split_vertices = sum(entry["split_vertices"] for entry in self.summary.per_object.values())

    def report(self) -> BakeReport:
        return BakeReport(self.summary, [ob.name for ob in self.objects], self.problems, self.notes,
                          self.subsurface_objects, self.storage_decisions)
