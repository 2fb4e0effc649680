"""A stored bake as a .npz for use outside Blender (`prt export --npz`), in its layout's form: per shading point
(the vertices, then the further corner normals of split vertices) with each face corner's point where the bake is
per corner; or a texel bake's maps, as 32-bit EXR files beside the .npz and as one array in it."""

import json
import os

import numpy as np

from ..core.outputs import replacing
from . import geometry, mesh_arrays, storage, texel_maps


def write_npz(path: str, **arrays):
    """The arrays as an .npz at exactly `path` (np.savez would add .npz to a name without it), whole or not at
    all."""
    with replacing(path) as temporary, open(temporary, "wb") as handle:
        np.savez(handle, **arrays)


def maps_stem(npz: str) -> str:
    """Where a texel bake's maps go: beside the .npz, named after it."""
    return os.path.splitext(npz)[0]


def points_npz(ob, path: str) -> str:
    """Writes a bake per point: world and local positions and normals, `transfer` (points, channels, n²),
    `point_vertices`, `matrix_world`, `metadata`, and per corner `corner_points` and `corner_vertices`. Returns
    what it wrote, in words."""
    mesh = ob.data
    transfer, meta = storage.read_transfer(mesh)
    corner_points = storage.corner_points_of(mesh)
    point_vertices = np.arange(len(transfer))
    normals = np.zeros((len(transfer), 3))
    normals[: len(mesh.vertices)] = mesh_arrays.mesh_vertex_normals(mesh)
    per_corner = {}
    if corner_points is not None:
        corner_vertices = mesh_arrays.mesh_corner_vertices(mesh)
        point_vertices[corner_points] = corner_vertices
        normals[corner_points] = mesh_arrays.mesh_corner_normals(mesh)
        per_corner = {"corner_points": corner_points, "corner_vertices": corner_vertices}
    matrix = np.array(ob.matrix_world, dtype=np.float64)
    local = mesh_arrays.mesh_positions(mesh)[point_vertices]
    write_npz(path, positions=geometry.points_to_world(matrix, local),
              normals=geometry.directions_to_world(matrix, normals), local_positions=local, matrix_world=matrix,
              transfer=transfer.reshape(len(local), -1, transfer.shape[-1]), point_vertices=point_vertices,
              metadata=np.array(json.dumps(meta)), **per_corner)
    split = f" ({meta.get('split_vertices', 0)} split: {len(local)} points)" if corner_points is not None else ""
    return f"wrote {path}: {len(mesh.vertices)} vertices{split}, order {meta['order']}, {meta['mode']}"


def texels_npz(ob, path: str) -> str:
    """Writes a texel bake: its maps as EXR files (`<stem>_t00.exr`, ..., `<stem>_error.exr`, laid out as stored),
    and the .npz with `transfer` (height × width × n², float32, gutters included), the UV map's name,
    `matrix_world` and `metadata`. Returns what it wrote, in words."""
    mesh = ob.data
    planes, meta = texel_maps.read_planes(mesh)
    written = texel_maps.save_exr(mesh, maps_stem(path))
    write_npz(path, transfer=planes.T.reshape(meta["height"], meta["width"], -1), uv_map=np.array(meta["uv_map"]),
              matrix_world=np.array(ob.matrix_world, dtype=np.float64), metadata=np.array(json.dumps(meta)))
    return (f"wrote {path} and {len(written)} EXR maps ({', '.join(map(os.path.basename, written))}): "
            f"{meta['width']} × {meta['height']} texels in UV map {meta['uv_map']!r}, order {meta['order']}, "
            f"{meta['mode']}")
