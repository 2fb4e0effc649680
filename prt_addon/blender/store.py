"""The last step of a bake: every receiver's results written through its layout (blender.layouts), replacing its
earlier bake, with the figures its metadata keeps; and the bake's report. Only this step writes to the scene, and
only once the whole bake is done."""

from dataclasses import asdict, dataclass, field

import bpy
import numpy as np

from ..core import job, subsurface
from . import fingerprint, probe_volumes, storage
from .execute import INTERPOLATION_KEYS, BakeResults
from .plan import BakePlan


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


def store(plan: BakePlan, results: BakeResults) -> BakeReport:
    """Writes every receiver's transfer, with its Subsurface Weight mixed in where its layout takes it, and returns
    the bake's report (its dynamic parts' too)."""
    report = _store_one(plan, results)
    for part, outcome in zip(plan.parts, results.parts):
        done = _store_one(part, outcome)
        report.objects += done.objects
        report.problems += done.problems
        report.notes += [note for note in done.notes if note not in report.notes]
        report.subsurface_objects += done.subsurface_objects
        report.storage += done.storage
    report.summary = results.summary
    return report


def _store_one(plan: BakePlan, results: BakeResults) -> BakeReport:
    settings, summary = plan.settings, results.summary
    inputs = {receiver.name: receiver for receiver in plan.request.receivers}
    notes = plan.request.notes + results.decisions
    mixed = []
    for name, layout, result in zip(results.names, results.layouts, results.results):
        material = inputs[name].subsurface
        if material is not None and not layout.takes_subsurface:
            notes.append(f"{name!r}: its Subsurface Weight is left out of its texel bake")
        elif material is not None:
            result.transfer = with_subsurface(inputs[name].surface, result.transfer, *material)
            mixed.append(name)
    for name, layout, result in zip(results.names, results.layouts, results.results):
        fields = {"time_s": summary.time_s, fingerprint.FINGERPRINT_KEY: plan.request.fingerprints[name],
                  "inside_another_part": summary.per_object[name].get("inside_another_part", 0),
                  **{key: summary.per_object[name][key] for key in INTERPOLATION_KEYS
                     if key in summary.per_object[name]}}
        fields["error_curve"] = [asdict(row) for row in summary.per_object[name]["error_curve"]]
        if summary.bounces is not None:
            fields["bounces"] = summary.bounces
        if summary.ray_engine:
            fields["ray_engine"] = summary.ray_engine
        if plan.request.dynamic:
            fields[storage.DYNAMIC_KEY] = True
            fields[storage.LIGHT_ORDER_KEY] = plan.request.light_order
        layout.write(bpy.data.objects[(name, None)].data, result, fields, settings)
    if results.probes is not None:
        notes += probe_volumes.write(plan.request.probe_volumes, results.probes, settings)
    lattices = [f"texel lattices: {results.lattices}"] if results.lattices else []
    return BakeReport(summary, results.names, results.problems, notes, mixed, results.decisions + lattices)


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
