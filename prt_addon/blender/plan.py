"""The second step of a bake: what it will do, planned from the request alone. Planning writes nothing and casts no
ray: each receiver's layout (blender.layouts) where the request decides it, or its Auto or texel candidate whose
probes the execution bakes first (blender.texel_plan); the probes between vertices; the albedo the bounces read.
The checks (blender.checks) run on the plan.
"""

from dataclasses import dataclass, field

import numpy as np

from ..core import bake, corners, interpolation
from ..core.errors import InputError
from . import layouts, texel_plan
from .request import BakeRequest


@dataclass
class PlannedReceiver:
    """A receiver and how it is stored: its layout, or, until its probes decide it, its Auto or texel candidate."""
    name: str
    surface: object                   # blender.geometry.Surface: its vertices, which the bounces are solved on
    layout: object | None = None      # blender.layouts: PerVertex, PerCorner or PerTexel
    candidate: texel_plan.Candidate | None = None
    decision: str = ""                # what its storage is and why, for texel and Auto receivers


@dataclass
class BetweenProbes:
    """Points inside the faces of the receivers stored per point, baked after them to measure what storage per
    vertex loses between vertices (core.interpolation)."""
    probes: dict = field(default_factory=dict)     # receiver name → interpolation.Probes
    receivers: list = field(default_factory=list)  # bake.Receiver per entry of `probes`, in order


@dataclass
class BakePlan:
    request: BakeRequest
    receivers: list[PlannedReceiver]
    problems: list                    # the request's, and the objects the plan drops, one sentence each
    albedo: list | None = None        # interreflected: (V, C) per solved surface, one channel where all are grey
    between: BetweenProbes = field(default_factory=BetweenProbes)
    parts: list = field(default_factory=list)  # BakePlan of each further dynamic receiver (request.parts)

    @property
    def settings(self) -> bake.BakeSettings:
        return self.request.settings

    @property
    def occluders(self) -> bake.Occluders | None:
        return self.request.occluders

    @property
    def names(self) -> list[str]:
        """Every receiver's, the parts' too."""
        return [receiver.name for receiver in self.receivers] + [name for part in self.parts for name in part.names]

    @property
    def pending(self) -> list[texel_plan.Candidate]:
        """The candidates whose probes decide their storage, in order."""
        return [receiver.candidate for receiver in self.receivers if receiver.layout is None]

    def notes(self) -> list:
        """What the user should know before the bake: the request's notes, and the storage decided so far."""
        return (self.request.notes + [receiver.decision for receiver in self.receivers if receiver.decision]
                + [note for part in self.parts for note in part.notes()])

    def solved_surfaces(self) -> list:
        """The surfaces whose transfer the bake solves, in the order of the job, its results and the occluders'
        first points: the receivers, then the bouncers."""
        return [receiver.surface for receiver in self.receivers] + self.request.bouncers

    def layouts(self) -> list:
        """Each receiver's layout, per vertex (or corner) where its probes are still to decide it: what the checks
        size."""
        return [receiver.layout or layouts.for_surface(receiver.surface) for receiver in self.receivers]


def plan_bake(request: BakeRequest) -> BakePlan:
    """The bake of the request. Objects whose texels cannot be baked are dropped with their reason in `problems`
    (nothing of their earlier bake is touched); raises InputError when nothing is left to bake, or the texel maps
    would not fit in memory."""
    settings = request.settings
    bouncing = settings.mode == "interreflected"
    coloured = bouncing and albedo_channels([s.albedo for s in _surfaces(request)])[0].shape[1] > 1
    target = settings.target_error or interpolation.AUTO_TARGET
    plan = BakePlan(request, [], list(request.problems))
    for receiver in request.receivers:
        planned = PlannedReceiver(receiver.name, receiver.surface)
        if receiver.options.storage == "vertex":
            planned.layout = layouts.for_surface(receiver.surface)
        else:
            try:
                if bouncing and coloured:
                    raise InputError(f"{receiver.name!r}: texel maps hold one channel, and coloured albedo makes "
                                     f"interreflected transfer RGB: bake it with Storage Vertex, or with grey albedo")
                candidate = texel_plan.Candidate(receiver.name, receiver.surface, receiver.texels)
                candidate.check(settings.order)
                if candidate.needs_probe:
                    planned.candidate = candidate
                else:
                    planned.layout, planned.decision = candidate.choose(settings.order, target)
            except InputError as problem:
                plan.problems.append(str(problem))
                continue
        plan.receivers.append(planned)
    if not plan.receivers and not request.probe_volumes:
        raise InputError("nothing to bake: " + "; ".join(plan.problems))
    texel_plan.check_memory([receiver.layout for receiver in plan.receivers if receiver.layout], settings.order)
    plan.albedo = albedo_channels([s.albedo for s in plan.solved_surfaces()]) if bouncing else None
    plan.between = between_probes(plan)
    for part in request.parts:
        try:
            plan.parts.append(plan_bake(part))
        except InputError as problem:
            plan.problems.append(str(problem))
    return plan


def _surfaces(request: BakeRequest) -> list:
    return [receiver.surface for receiver in request.receivers] + request.bouncers


def albedo_channels(albedos):
    """One channel when every surface is grey (transfer stays single-channel), else RGB."""
    grey = all(np.allclose(a, a[:, :1]) for a in albedos)
    return [a[:, :1] if grey else a for a in albedos]


def between_probes(plan: BakePlan) -> BetweenProbes:
    """The probes between vertices of the receivers stored per point whatever their probes say (Vertex storage;
    Auto's own probes measure the others); an interreflected bake's probes measure its direct transfer. A farm
    shard bakes its share of their chunks too, so the merge casts no ray."""
    found = BetweenProbes()
    for receiver in plan.receivers:
        if receiver.layout is None or not receiver.layout.between_vertices:
            continue
        surface = receiver.surface
        probes = interpolation.face_probes(surface.triangles, surface.receiver.positions, surface.receiver.normals,
                                           interpolation.probe_count(_vertex_count(surface)), plan.settings.seed)
        if len(probes.positions):
            found.probes[receiver.name] = probes
            found.receivers.append(bake.Receiver(receiver.name, probes.positions, probes.normals,
                                                 bake.Receiver.key_for(receiver.name + " probes")))
    return found


def _vertex_count(surface) -> int:
    """The surface's vertices (a split vertex's points share its position): probes follow the surface, not how
    finely its normals split it."""
    return len(corners.unique_rows(surface.vertex_positions)[0])
