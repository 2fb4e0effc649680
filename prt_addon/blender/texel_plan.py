"""Which texel and Auto receivers store per texel, and at what resolution, from what the request read
(blender.texel_bake): the checks on the lightmap UV map before any ray (no UV map and no permission to add one,
faces outside the unit square, zero-area UV faces, overlaps, a resolution that would not fit in memory), Auto's
probes of the interpolation error (placed here, baked first by the bake's execution), the resolution, and the
texels as receiver points.

A texel bake is a vertex bake's receiver made of texel centres: placed on the evaluated mesh's triangles with the
corner normals Blender shades with (core.texels), baked by the same job with the same ray offsets, contact rule,
exact skips and closed-form flat occluders.
"""

from dataclasses import dataclass, field, replace

import numpy as np

from ..core import bake, checks as core_checks, interpolation, lobes, texels
from ..core.errors import InputError
from . import layouts
from .texel_bake import PROVISIONAL_RESOLUTION, TexelInput


@dataclass
class Candidate:
    """A receiver whose Storage is Texel or Auto: its vertex surface and what the request read of it."""
    name: str
    surface: object  # blender.geometry.Surface
    read: TexelInput
    probes: interpolation.Probes | None = None   # Auto's probes inside its faces, corners local to `corners`
    corners: np.ndarray | None = None            # the vertex rows the probes' corners are
    errors: np.ndarray | None = None  # (S,) squared interpolation errors at the probes, once baked
    layouts: dict = field(default_factory=dict)  # {resolution: the UV map rasterised}

    @property
    def needs_probe(self) -> bool:
        options = self.read.options
        return options.storage == "auto" or not (options.resolution or options.texel_size)

    def check(self, order: int):
        """Before any ray: whether a given resolution fits in memory, the UV map, and its layout."""
        options = self.read.options
        if options.resolution:
            _fits_in_memory(self.name, options.resolution, order)
        if self.read.problem:
            raise InputError(self.read.problem)
        self._check_layout(self._layout(options.resolution or PROVISIONAL_RESOLUTION))

    def _layout(self, resolution) -> texels.TexelLayout:
        """The UV map rasterised at this resolution, once (the checks and the choice may ask for the same)."""
        if self.layouts.get(resolution) is None:
            self.layouts[resolution] = texels.rasterise(self.read.uvs, resolution, resolution)
        return self.layouts[resolution]

    def _check_layout(self, layout: texels.TexelLayout):
        name, uv_map, geometry, uvs = self.name, self.read.uv_map, self.read.geometry, self.read.uvs
        outside = np.unique(geometry.faces[((uvs < 0.0) | (uvs > 1.0)).any(axis=(1, 2))])
        if len(outside):
            raise InputError(f"{name!r}: {len(outside)} faces reach outside the unit square in UV map {uv_map!r}, so "
                             f"parts of them would get no texels; a lightmap lies within 0-1 (UV > Lightmap Pack, "
                             f"or let PRT make its own lightmap UV map)")
        flat = geometry.faces[layout.zero_area & (geometry.areas > 0)]
        if len(flat):
            raise InputError(f"{name!r}: {len(np.unique(flat))} faces have zero area in UV map {uv_map!r}, so they "
                             f"would get no texels; unwrap them, or let PRT make its own lightmap UV map")
        if layout.overlapping:
            raise InputError(f"{name!r}: UV map {uv_map!r} overlaps itself: {100 * layout.overlap_share:.1f} % of its "
                             f"texels ({layout.overlapping}) lie on more than one face; a lightmap needs every face "
                             f"its own texels (UV > Lightmap Pack, or let PRT make its own lightmap UV map)")

    def choose(self, order, target) -> tuple[object, str]:
        """Its layout (blender.layouts): per vertex (Auto where interpolating meets the target) or per texel; and
        what was chosen and why, in a sentence."""
        name, options = self.name, self.read.options
        rms, worst = interpolation.summarise(self.errors) if self.errors is not None else (0.0, 0.0)
        said = (f"interpolating between vertices errs {100 * rms:.2f} % RMS (max {100 * worst:.1f} %, "
                f"{len(self.errors)} probes)" if self.errors is not None else "")
        if options.storage == "auto" and rms <= target:
            return (layouts.for_surface(self.surface),
                    f"{name!r}: Auto keeps vertex storage: {said}, within the target {100 * target:g} %")
        resolution = self._resolution(target, order)
        layout = self._layout(resolution)
        self._check_layout(layout)
        why = {"auto": f"Auto stores per texel: {said}, above the target {100 * target:g} %",
               "texel": "Storage Texel"}[options.storage]
        geometry = self.read.geometry
        positions, normals, inward = texels.surface_points(layout.triangles, layout.barycentric,
                                                           geometry.corner_positions, geometry.corner_normals)
        receiver = bake.Receiver(name, positions, normals, bake.Receiver.key_for(name), inward)
        return (layouts.PerTexel(receiver, layout, self.read.uv_map, self.read.new_uvs),
                f"{name!r}: {why}; {resolution} × {resolution} texels in UV map {self.read.uv_map!r}, "
                f"{len(layout.texels)} covered")

    def _resolution(self, target, order) -> int:
        options, geometry = self.read.options, self.read.geometry
        if options.resolution:
            return options.resolution
        world_area = float(geometry.areas.sum())
        uv_area = texels.uv_area(self.read.uvs)
        if options.texel_size:
            resolution = texels.resolution_for_texel_size(world_area, uv_area, options.texel_size)
        else:
            spacing = np.sqrt(2.0 * world_area / max(1, len(geometry.areas)))
            rms = interpolation.summarise(self.errors)[0]
            resolution = max(texels.resolution_for_target(spacing, rms, target, world_area, uv_area),
                             texels.resolution_for_triangles(len(geometry.areas), uv_area))
        _fits_in_memory(self.name, resolution, order)
        return resolution



def place_probes(candidates: list[Candidate], settings: bake.BakeSettings) -> list[bake.Receiver]:
    """Auto's probes (core.interpolation) inside each candidate's faces and the corners of their triangles, one
    receiver each, in the candidates' order: baked first, so Auto can decide."""
    receivers = []
    for candidate in candidates:
        vertex = candidate.surface.receiver
        probes = interpolation.face_probes(candidate.surface.triangles, vertex.positions, vertex.normals,
                                           interpolation.AUTO_PROBES, settings.seed)
        used, local = np.unique(probes.corners, return_inverse=True)
        inward = vertex.inward[used] if vertex.inward is not None else np.zeros((len(used), 3))
        receivers.append(bake.Receiver(candidate.name, np.concatenate([vertex.positions[used], probes.positions]),
                                       np.concatenate([vertex.normals[used], probes.normals]),
                                       bake.Receiver.key_for(candidate.name + " probes"),
                                       np.concatenate([inward, np.zeros_like(probes.positions)])))
        candidate.corners, candidate.probes = used, replace(probes, corners=local.reshape(-1, 3))
    return receivers


def probe_settings(settings: bake.BakeSettings) -> bake.BakeSettings:
    """Probes measure what storing per vertex loses of the direct transfer: an interreflected bake's probes are
    shadowed."""
    return replace(settings, mode="shadowed") if settings.mode == "interreflected" else settings


def measure(candidates: list[Candidate], results, order: int):
    """Each candidate's squared interpolation errors at its probes, from their baked results (place_probes' order)."""
    scale = lobes.unshadowed_norm(order)
    for candidate, result in zip(candidates, results):
        corners = len(candidate.corners)
        transfer = result.transfer.astype(np.float64)
        candidate.errors = interpolation.interpolation_errors(
            candidate.probes, transfer[corners:], result.std_error[corners:], transfer[:corners],
            result.std_error[:corners], scale)


def _fits_in_memory(name, resolution, order):
    available = core_checks.available_memory()
    needed = texels.texel_bake_bytes(resolution, resolution, order)
    if available is not None and needed > available:
        raise InputError(f"{name!r}: {resolution} × {resolution} texels need about "
                         f"{core_checks.format_bytes(needed)}, more than the {core_checks.format_bytes(available)} "
                         f"available; choose a lower resolution or a larger texel size")


def check_memory(chosen, order):
    """All texel receivers together (`chosen`: each receiver's layout), before any ray of the bake itself."""
    available = core_checks.available_memory()
    needed = sum(layout.map_bytes(order) for layout in chosen)
    if available is not None and needed > available:
        raise InputError(f"the texel maps need about {core_checks.format_bytes(needed)}, more than the "
                         f"{core_checks.format_bytes(available)} available; choose lower resolutions")
