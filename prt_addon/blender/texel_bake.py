"""Which receivers store per texel, and their texels as receiver points: the per-object Storage choice (Vertex,
Texel, Auto), the lightmap UV map, the checks on it before any ray (no UV map and no permission to add one,
overlapping UVs, zero-area UV faces, a resolution that would not fit in memory), Auto's probe of the interpolation
error, the resolution, and writing a texel bake.

A texel bake is a vertex bake's receiver made of texel centres: placed on the evaluated mesh's triangles with the
corner normals Blender shades with (core.texels), baked by the same job with the same ray offsets, contact rule,
exact skips and closed-form flat occluders.
"""

from dataclasses import dataclass, field, fields, replace

import numpy as np

from ..core import bake, checks as core_checks, interpolation, job, lobes, texel_gather, texel_refine, texels
from ..core.errors import InputError
from . import texel_maps
from .mesh_arrays import mesh_triangles

PROVISIONAL_RESOLUTION = 256  # overlaps are looked for at this resolution before the probe decides the real one
OBJECT_PREFIX = "prt_"        # the Object properties (blender.schema) holding each object's choice: prt_storage, ...


@dataclass
class TexelOptions:
    """One object's storage choice (core.settings.TEXEL, and the lightmap UV map)."""
    storage: str = "vertex"
    resolution: int = 0
    texel_size: float = 0.0
    uv_map: str = ""          # empty: PRT's own lightmap UV map
    new_uv_map: bool = True   # may PRT add its own UV map where there is none


def options_for(ob, overrides: dict) -> TexelOptions:
    """The object's own choice (its prt_* properties), overridden by `overrides` (the command line's options)."""
    values = {f.name: getattr(ob, OBJECT_PREFIX + f.name) for f in fields(TexelOptions)}
    values.update(overrides)
    return TexelOptions(**values)


@dataclass
class TexelSurface:
    """A receiver made of texel centres; `mesh_surface` is the object's vertex surface it was placed on."""
    receiver: bake.Receiver
    layout: texels.TexelLayout
    uv_map: str
    mesh_surface: object
    corner_points: None = None
    split_vertices: int = 0

    @property
    def albedo(self):
        """Its vertices' albedo: an interreflected bake solves the bounces on them."""
        return self.mesh_surface.albedo


@dataclass
class Planned:
    objects: list
    surfaces: list
    decisions: list = field(default_factory=list)  # one sentence per texel or Auto object: what and why
    # {name: (S,) squared interpolation errors} of the objects Auto kept per vertex: the bake reports them rather
    # than probing those objects again
    measured: dict = field(default_factory=dict)
    probe_rays: int = 0       # what Auto's probes cost
    probe_s: float = 0.0


def refuse_on_farm(objects, overrides: dict):
    """Farm shards and their merge bake per vertex only: a texel bake refines lattice by lattice, each step deciding
    from the whole previous lattice, and Auto decides from probes baked before the bake."""
    chosen = [ob.name for ob in objects if options_for(ob, overrides).storage != "vertex"]
    if chosen:
        raise InputError(f"{', '.join(map(repr, chosen))}: Storage Texel or Auto bakes on one machine; farm shards "
                         f"store per vertex: bake without --shard or --dask, or set Storage Vertex")


def plan(objects, surfaces, occluders, settings: bake.BakeSettings, overrides: dict, depsgraph, problems,
         coloured: bool = False) -> Planned:
    """Each receiver's storage: its vertex surface kept, or a TexelSurface. An object whose texels cannot be
    baked is dropped with its reason in `problems` (nothing of its earlier bake is touched); what Auto chose, and
    why, goes to the decisions."""
    candidates = []
    for ob, surface in zip(objects, surfaces):
        options = options_for(ob, overrides)
        if options.storage == "vertex":
            continue
        try:
            if settings.mode == "interreflected" and coloured:
                raise InputError(f"{ob.name!r}: texel maps hold one channel, and coloured albedo makes interreflected "
                                 f"transfer RGB: bake it with Storage Vertex, or with grey albedo")
            candidate = _Candidate(ob, surface, options, _TriangleGeometry.of(ob, surface, depsgraph))
            candidate.check_uvs(settings.order)
        except InputError as problem:
            problems.append(str(problem))
            candidate = _Candidate(ob, surface, options, None, failed=True)
        candidates.append(candidate)
    probed = [c for c in candidates if not c.failed and c.needs_probe]
    probe_job = _probe(probed, occluders, settings)
    target = settings.target_error or interpolation.AUTO_TARGET
    result = Planned([], [])
    if probe_job is not None:
        result.probe_rays, result.probe_s = probe_job.rays, probe_job.progress.elapsed
    decided = {c.ob.name: c for c in candidates}
    for ob, surface in zip(objects, surfaces):
        candidate = decided.get(ob.name)
        if candidate is None:
            result.objects.append(ob)
            result.surfaces.append(surface)
            continue
        if candidate.failed:
            continue
        try:
            chosen = candidate.choose(settings.order, target, result.decisions)
        except InputError as problem:
            problems.append(str(problem))
            continue
        result.objects.append(ob)
        result.surfaces.append(chosen)
        if chosen is surface:
            result.measured[ob.name] = candidate.probe
    _check_memory(result.surfaces, settings.order)
    return result


@dataclass
class _TriangleGeometry:
    """An object's evaluated triangles in world space with their lightmap UVs (filled in once the map is known)."""
    corner_positions: np.ndarray  # (T, 3, 3)
    corner_normals: np.ndarray    # (T, 3, 3)
    loop_triangles: np.ndarray    # (T, 3) face corners
    faces: np.ndarray             # (T,) each triangle's face
    areas: np.ndarray             # (T,) world area

    @staticmethod
    def of(ob, surface, depsgraph) -> "_TriangleGeometry":
        evaluated = ob.evaluated_get(depsgraph)
        mesh = evaluated.to_mesh()
        try:
            loops = mesh_triangles(mesh, of="loops")  # the order surface.triangles was built in
            faces = np.empty(len(mesh.loop_triangles), dtype=np.int64)
            mesh.loop_triangles.foreach_get("polygon_index", faces)
        finally:
            evaluated.to_mesh_clear()
        positions = surface.receiver.positions[surface.triangles]
        areas = 0.5 * np.linalg.norm(np.cross(positions[:, 1] - positions[:, 0], positions[:, 2] - positions[:, 0]),
                                     axis=1)
        return _TriangleGeometry(positions, surface.receiver.normals[surface.triangles], loops, faces, areas)


@dataclass
class _Candidate:
    ob: object
    surface: object
    options: TexelOptions
    geometry: _TriangleGeometry | None
    failed: bool = False
    uv_map: str = ""
    uvs: np.ndarray | None = None
    probe: np.ndarray | None = None  # (S,) squared interpolation errors at the probes (core.interpolation)
    layouts: dict = field(default_factory=dict)  # {resolution: the UV map rasterised}

    @property
    def needs_probe(self) -> bool:
        return self.options.storage == "auto" or not (self.options.resolution or self.options.texel_size)

    def check_uvs(self, order: int):
        """Before any ray: the UV map (made if allowed), its zero-area faces, its overlaps, and whether a given
        resolution fits in memory."""
        if self.options.resolution:
            _fits_in_memory(self.ob.name, self.options.resolution, order)
        resolution = self.options.resolution or PROVISIONAL_RESOLUTION
        self.uv_map = self._own_lightmap(resolution) or texel_maps.lightmap_uv_map(
            self.ob, self.options.uv_map, self.options.new_uv_map, margin_texels=texels.PACK_MARGIN_TEXELS,
            resolution=resolution)
        self.uvs = texel_maps.triangle_uvs(self.ob.data, self.uv_map, self.geometry.loop_triangles)
        self._check_layout(self._layout(resolution))

    def _layout(self, resolution) -> texels.TexelLayout:
        """The UV map rasterised at this resolution, once (the checks and the choice may ask for the same)."""
        if self.layouts.get(resolution) is None:
            self.layouts[resolution] = texels.rasterise(self.uvs, resolution, resolution)
        return self.layouts[resolution]

    def _own_lightmap(self, resolution) -> str | None:
        """Without a chosen map or PRT's own, the object's render UV map where it serves as a lightmap as it is
        (within the unit square, no overlaps, no zero-area faces): one island per piece of surface, rather than
        Lightmap Pack's one per face, so smooth stretches interpolate and fewer borders show."""
        mesh = self.ob.data
        if self.options.uv_map or texel_maps.PRT_UV_MAP in mesh.uv_layers:
            return None
        name = next((layer.name for layer in mesh.uv_layers if layer.active_render), None)
        if name is None:
            return None
        uvs = texel_maps.triangle_uvs(mesh, name, self.geometry.loop_triangles)
        if uvs.min() < 0.0 or uvs.max() > 1.0:
            return None
        layout = texels.rasterise(uvs, resolution, resolution)
        return name if not layout.overlapping and not (layout.zero_area & (self.geometry.areas > 0)).any() else None

    def _check_layout(self, layout: texels.TexelLayout):
        name, uv_map = self.ob.name, self.uv_map
        outside = np.unique(self.geometry.faces[((self.uvs < 0.0) | (self.uvs > 1.0)).any(axis=(1, 2))])
        if len(outside):
            raise InputError(f"{name!r}: {len(outside)} faces reach outside the unit square in UV map {uv_map!r}, so "
                             f"parts of them would get no texels; a lightmap lies within 0-1 (UV > Lightmap Pack, "
                             f"or let PRT make its own lightmap UV map)")
        flat = self.geometry.faces[layout.zero_area & (self.geometry.areas > 0)]
        if len(flat):
            raise InputError(f"{name!r}: {len(np.unique(flat))} faces have zero area in UV map {uv_map!r}, so they "
                             f"would get no texels; unwrap them, or let PRT make its own lightmap UV map")
        if layout.overlapping:
            raise InputError(f"{name!r}: UV map {uv_map!r} overlaps itself: {100 * layout.overlap_share:.1f} % of its "
                             f"texels ({layout.overlapping}) lie on more than one face; a lightmap needs every face "
                             f"its own texels (UV > Lightmap Pack, or let PRT make its own lightmap UV map)")

    def choose(self, order, target, decisions):
        """The vertex surface (Auto where interpolating meets the target) or this object's texels."""
        name = self.ob.name
        rms, worst = interpolation.summarise(self.probe) if self.probe is not None else (0.0, 0.0)
        said = (f"interpolating between vertices errs {100 * rms:.2f} % RMS (max {100 * worst:.1f} %, "
                f"{len(self.probe)} probes)" if self.probe is not None else "")
        if self.options.storage == "auto" and rms <= target:
            decisions.append(f"{name!r}: Auto keeps vertex storage: {said}, within the target {100 * target:g} %")
            return self.surface
        resolution = self._resolution(target, order)
        layout = self._layout(resolution)
        self._check_layout(layout)
        why = {"auto": f"Auto stores per texel: {said}, above the target {100 * target:g} %",
               "texel": "Storage Texel"}[self.options.storage]
        decisions.append(f"{name!r}: {why}; {resolution} × {resolution} texels in UV map {self.uv_map!r}, "
                         f"{len(layout.texels)} covered")
        positions, normals, inward = texels.surface_points(layout.triangles, layout.barycentric,
                                                           self.geometry.corner_positions,
                                                           self.geometry.corner_normals)
        receiver = bake.Receiver(name, positions, normals, bake.Receiver.key_for(name), inward)
        return TexelSurface(receiver, layout, self.uv_map, self.surface)

    def _resolution(self, target, order) -> int:
        options = self.options
        if options.resolution:
            return options.resolution
        world_area = float(self.geometry.areas.sum())
        uv_area = texels.uv_area(self.uvs)
        if options.texel_size:
            resolution = texels.resolution_for_texel_size(world_area, uv_area, options.texel_size)
        else:
            spacing = np.sqrt(2.0 * world_area / max(1, len(self.geometry.areas)))
            rms = interpolation.summarise(self.probe)[0]
            resolution = max(texels.resolution_for_target(spacing, rms, target, world_area, uv_area),
                             texels.resolution_for_triangles(len(self.geometry.areas), uv_area))
        _fits_in_memory(self.ob.name, resolution, order)
        return resolution


def _probe(candidates, occluders, settings: bake.BakeSettings):
    """Bakes each candidate's interpolation probes (core.interpolation) and the corners of their triangles in one
    job, before the bake, so Auto can decide; each candidate's `probe` gets the squared errors. Returns the job
    (None without candidates)."""
    if not candidates:
        return None
    receivers, parts = [], []
    for candidate in candidates:
        vertex = candidate.surface.receiver
        probes = interpolation.face_probes(candidate.surface.triangles, vertex.positions, vertex.normals,
                                           interpolation.AUTO_PROBES, settings.seed)
        used, local = np.unique(probes.corners, return_inverse=True)
        inward = vertex.inward[used] if vertex.inward is not None else np.zeros((len(used), 3))
        name = candidate.ob.name
        receivers.append(bake.Receiver(name, np.concatenate([vertex.positions[used], probes.positions]),
                                       np.concatenate([vertex.normals[used], probes.normals]),
                                       bake.Receiver.key_for(name + " probes"),
                                       np.concatenate([inward, np.zeros_like(probes.positions)])))
        parts.append((len(used), replace(probes, corners=local.reshape(-1, 3))))
    settings = replace(settings, mode="shadowed") if settings.mode == "interreflected" else settings
    scale = lobes.unshadowed_norm(settings.order)
    probe_job = job.TransferJob(receivers, occluders, settings)
    for candidate, result, (corners, probes) in zip(candidates, probe_job.run(), parts):
        transfer = result.transfer.astype(np.float64)
        candidate.probe = interpolation.interpolation_errors(probes, transfer[corners:], result.std_error[corners:],
                                                             transfer[:corners], result.std_error[:corners], scale)
    return probe_job


def _fits_in_memory(name, resolution, order):
    available = core_checks.available_memory()
    needed = texels.texel_bake_bytes(resolution, resolution, order)
    if available is not None and needed > available:
        raise InputError(f"{name!r}: {resolution} × {resolution} texels need about "
                         f"{core_checks.format_bytes(needed)}, more than the {core_checks.format_bytes(available)} "
                         f"available; choose a lower resolution or a larger texel size")


def _check_memory(surfaces, order):
    """All texel objects together, before any ray of the bake itself."""
    available = core_checks.available_memory()
    needed = sum(texels.texel_bake_bytes(s.layout.width, s.layout.height, order) for s in surfaces
                 if isinstance(s, TexelSurface))
    if available is not None and needed > available:
        raise InputError(f"the texel maps need about {core_checks.format_bytes(needed)}, more than the "
                         f"{core_checks.format_bytes(available)} available; choose lower resolutions")


def vertex_surface(surface):
    """The surface an interreflected bake solves the bounces on: a texel receiver's vertices."""
    return surface.mesh_surface if isinstance(surface, TexelSurface) else surface


def refining_job(surfaces, settings: bake.BakeSettings, transfer_job) -> texel_refine.RefiningJob:
    """The bake's job over the solved surfaces in order, the texel ones lattice by lattice (core.texel_refine) to the
    bake's target error (or Auto's, without one). transfer_job(receivers, gather_only=False) makes a TransferJob.
    Interreflected, the vertices of every surface solve the bounces first, then each texel gathers from them
    (core.texel_gather)."""
    grids = {position: texel_refine.TexelGrid(surface.receiver, surface.layout.texels % surface.layout.width,
                                              surface.layout.texels // surface.layout.width, surface.layout.width,
                                              surface.layout.height)
             for position, surface in enumerate(surfaces) if isinstance(surface, TexelSurface)}
    target = settings.target_error or interpolation.AUTO_TARGET
    receivers = [surface.receiver for surface in surfaces]
    if settings.mode != "interreflected" or not grids:
        return texel_refine.RefiningJob(receivers, grids, settings, target, transfer_job)
    solve = transfer_job([vertex_surface(surface).receiver for surface in surfaces])
    albedo = np.concatenate(solve.albedo)

    def gathering_job(texel_receivers):
        solved = np.concatenate([result.transfer for result in solve.results()])
        return texel_gather.GatheringJob(transfer_job(texel_receivers, gather_only=True), solved, albedo)
    return texel_refine.RefiningJob(receivers, grids, settings, target, gathering_job, first_job=solve)
