"""One bake of a Blender scene, shared by the operator (modal or not) and the command line.

Nothing is written until every receiver is baked: a cancelled or failed bake leaves the previous data as it was.
"""

import sys

import bpy
import numpy as np

from . import mesh_data
from .core import bake, job, subsurface


def worker_launch():
    """How to start a worker: Blender's own binary in a real Blender. With the bpy module, a fork of this process
    on Linux (it starts in milliseconds instead of importing bpy for a second, and shares the ray tree); the
    module's Python elsewhere (macOS and Windows cannot fork a process that runs Blender safely)."""
    if bpy.app.binary_path:
        return [bpy.app.binary_path, "--background", "--factory-startup", "--python-expr"]
    if sys.platform.startswith("linux"):
        return job.FORK
    return [sys.executable, "-c"]


def with_subsurface(surface, transfer, weight, mean_free_path, albedo, ior):
    """(1 − w)·T + w·T_sss/albedo per channel: light scattered beneath the surface (Jensen's dipole, gathered
    from the object's own incident transfer) mixed in by the Subsurface Weight. T_sss carries its colour, and the
    display multiplies by albedo, hence the division."""
    params = subsurface.dipole_parameters(mean_free_path, 1.0, albedo, ior)
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


class SceneBake:
    """Gathers receivers and occluders, runs a TransferJob, then stores everything at once."""

    def __init__(self, context, settings: bake.BakeSettings, object_names=None, workers: int = 1):
        problems = settings.problems()
        if problems:
            raise mesh_data.InputError("; ".join(problems))
        self.settings = settings
        context.view_layer.update()  # objects linked by scripts join the view layer only on update
        self.problems: list[str] = []  # one sentence per object that will not be baked
        self.notes: list[str] = []     # baked, but the user should know
        depsgraph = context.evaluated_depsgraph_get()
        candidates = mesh_data.receivers_from_selection(context, object_names)
        bouncing = settings.mode == "interreflected"
        self.objects, surfaces, meshes = [], [], {}
        for ob in candidates:
            try:
                if ob.type == "MESH" and ob.data.name in meshes:
                    raise mesh_data.InputError(
                        f"{ob.name!r} shares its mesh with {meshes[ob.data.name]!r}, and the bake depends on "
                        f"where each object is; make it single-user (Object > Relations) to bake both")
                surfaces.append(mesh_data.surface_from_object(ob, depsgraph, self.notes, albedo=bouncing))
                meshes[ob.data.name] = ob.name
                self.objects.append(ob)
            except mesh_data.InputError as problem:
                self.problems.append(str(problem))
        if not surfaces:
            raise mesh_data.InputError("nothing to bake: " + ("; ".join(self.problems) or "no mesh objects"))
        if bouncing:  # every visible mesh reflects light onto the receivers, so its transfer is solved too
            surfaces += self._bouncing_surfaces(context, depsgraph, {ob.name for ob in self.objects})
        occluders = None
        if settings.mode != "unshadowed":
            occluders, sources = mesh_data.occluders_from_depsgraph(depsgraph, surfaces)
            if sources <= {ob.name for ob in self.objects}:
                self.notes.append("no visible mesh besides the receivers casts shadows; "
                                  "each receiver is shadowed by the receivers only")
        self.surfaces = surfaces
        self.receivers = [surface.receiver for surface in surfaces]
        self.job = job.TransferJob(self.receivers, occluders, settings, workers, worker_launch(),
                                   albedo=_albedo_channels([s.albedo for s in surfaces]) if bouncing else None)
        self.summary = None

    def _bouncing_surfaces(self, context, depsgraph, receiver_names):
        found = []
        for ob in mesh_data.visible_mesh_objects(context):
            if ob.name in receiver_names:
                continue
            try:
                found.append(mesh_data.surface_from_object(ob, depsgraph, self.notes, for_storage=False,
                                                           albedo=True))
            except mesh_data.InputError as problem:
                self.notes.append(f"{problem}; it casts shadows but reflects no light")
        return found

    @property
    def progress(self):
        return self.job.progress

    def step(self, budget_s: float = 0.1) -> bool:
        return self.job.step(budget_s)

    def run(self, log=print):
        """Synchronous bake with a log line every 5 % (background mode, command line)."""
        from .core.progress import LogThrottle
        throttle = LogThrottle(0.05)
        finished = False
        while not finished:
            finished = self.step(0.5)
            if throttle.due(self.progress.fraction):
                log(self.progress.line())
        return self.store()

    def cancel(self):
        self.job.cancel()

    def store(self) -> job.Summary:
        """Writes every receiver's transfer (replacing older bakes) and returns the summary."""
        results = self.job.results()[: len(self.objects)]  # the rest only reflected light onto these
        self.summary = self.job.summary(results)
        self.subsurface_objects = []
        for ob, surface, result in zip(self.objects, self.surfaces, results):
            material = mesh_data.subsurface_material(ob) if self.settings.mode != "unshadowed" else None
            if material is not None:
                result.transfer = with_subsurface(surface, result.transfer, *material)
                self.subsurface_objects.append(ob.name)
        for ob, result in zip(self.objects, results):
            extra = {"time_s": self.summary.time_s}
            if self.summary.bounces is not None:
                extra["bounces"] = self.summary.bounces
            mesh_data.write_transfer(ob, result, extra, self.settings)
        return self.summary

    def report_dict(self) -> dict:
        s = self.summary
        return {
            "objects": [ob.name for ob in self.objects], "vertices": s.vertices, "order": s.order,
            "mode": s.mode, "samples": s.samples, "target_error": s.target_error, "workers": s.workers,
            "rays": s.rays, "skipped_vertices": s.skipped_vertices, "time_s": s.time_s,
            "rays_per_s": s.rays_per_s, "est_rms_rel_error": s.est_rms_rel_error,
            "est_max_rel_error": s.est_max_rel_error, "per_object": s.per_object, "problems": self.problems, "notes": self.notes,
            "phases_s": s.phases, "bounces": s.bounces, "bounce_relative_changes": s.bounce_changes,
            "bounce_tail": s.bounce_tail, "albedo_clamped": s.albedo_clamped,
            "subsurface_objects": self.subsurface_objects,
        }
