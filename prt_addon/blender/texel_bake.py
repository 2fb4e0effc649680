"""What a bake reads from Blender for texel storage: each object's Storage choice (Vertex, Texel, Auto), and for a
texel or Auto receiver its evaluated triangles and the lightmap UV map its texels follow: the map chosen, PRT's
own, the render UV map where it serves as a lightmap as it is, or the UVs Blender's Lightmap Pack would give PRT's
own map (found on a temporary copy: the bake's storing adds the map). Reading changes nothing; what the plan makes
of it is blender.texel_plan's.
"""

from dataclasses import dataclass, fields

import numpy as np

from ..core import texels
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


def refuse_on_farm(objects, overrides: dict):
    """Farm shards and their merge bake per vertex only: a texel bake refines lattice by lattice, each step deciding
    from the whole previous lattice, and Auto decides from probes baked before the bake."""
    chosen = [ob.name for ob in objects if options_for(ob, overrides).storage != "vertex"]
    if chosen:
        raise InputError(f"{', '.join(map(repr, chosen))}: Storage Texel or Auto bakes on one machine; farm shards "
                         f"store per vertex: bake without --shard or --dask, or set Storage Vertex")


@dataclass
class TriangleGeometry:
    """An object's evaluated triangles in world space."""
    corner_positions: np.ndarray  # (T, 3, 3)
    corner_normals: np.ndarray    # (T, 3, 3)
    loop_triangles: np.ndarray    # (T, 3) face corners
    faces: np.ndarray             # (T,) each triangle's face
    areas: np.ndarray             # (T,) world area

    @staticmethod
    def of(ob, surface, depsgraph) -> "TriangleGeometry":
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
        return TriangleGeometry(positions, surface.receiver.normals[surface.triangles], loops, faces, areas)


@dataclass
class TexelInput:
    """A texel or Auto receiver as read: its choice, triangles, and its lightmap UV map (or why it has none)."""
    options: TexelOptions
    geometry: TriangleGeometry
    uv_map: str = ""
    uvs: np.ndarray | None = None      # (T, 3, 2) each triangle's corners' UVs
    new_uvs: np.ndarray | None = None  # (C, 2) float32: PRT's own map, added when the bake is stored
    problem: str = ""                  # why its texels have no UV map


def texel_input(ob, surface, depsgraph, options: TexelOptions) -> TexelInput:
    """Reads what the plan needs of a texel or Auto receiver (blender.geometry.Surface `surface`)."""
    geometry = TriangleGeometry.of(ob, surface, depsgraph)
    resolution = options.resolution or PROVISIONAL_RESOLUTION
    try:
        uv_map, new_uvs = _own_lightmap(ob.data, options, geometry, resolution), None
        if uv_map is None:
            uv_map, new_uvs = texel_maps.lightmap_uv_map(ob, options.uv_map, options.new_uv_map,
                                                         margin_texels=texels.PACK_MARGIN_TEXELS,
                                                         resolution=resolution)
    except InputError as problem:
        return TexelInput(options, geometry, problem=str(problem))
    uvs = (texel_maps.triangle_uvs(ob.data, uv_map, geometry.loop_triangles) if new_uvs is None
           else new_uvs.astype(np.float64)[geometry.loop_triangles])
    return TexelInput(options, geometry, uv_map, uvs, new_uvs)


def _own_lightmap(mesh, options: TexelOptions, geometry: TriangleGeometry, resolution) -> str | None:
    """Without a chosen map or PRT's own, the object's render UV map where it serves as a lightmap as it is
    (within the unit square, no overlaps, no zero-area faces): one island per piece of surface, rather than
    Lightmap Pack's one per face, so smooth stretches interpolate and fewer borders show."""
    if options.uv_map or texel_maps.PRT_UV_MAP in mesh.uv_layers:
        return None
    name = next((layer.name for layer in mesh.uv_layers if layer.active_render), None)
    if name is None:
        return None
    uvs = texel_maps.triangle_uvs(mesh, name, geometry.loop_triangles)
    if uvs.min() < 0.0 or uvs.max() > 1.0:
        return None
    layout = texels.rasterise(uvs, resolution, resolution)
    return name if not layout.overlapping and not (layout.zero_area & (geometry.areas > 0)).any() else None
