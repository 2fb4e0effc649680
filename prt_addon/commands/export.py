"""`prt export`: one object's bake as a .npz for use outside Blender: per shading point (the vertices, then the
further corner normals of split vertices), with each face corner's point where the bake is per corner; or the
scene's baked meshes as a glTF binary packed for a profile (blender.gltf)."""

import json
import os

import bpy
import numpy as np

from ..blender import geometry, gltf, mesh_arrays, storage, texel_maps
from ..core.errors import InputError
from ..core.gltf_pack import PROFILES, PackedMaps
from ..core.outputs import check_suffix, replacing
from .common import check_outputs, open_file, warn


def add_parser(commands):
    parser = commands.add_parser("export", help="write one object's bake to a .npz, or the baked meshes to a .glb, "
                                 "for use outside Blender")
    parser.add_argument("file", help=".blend file")
    parser.add_argument("--object", help="object name (with --npz)")
    parser.add_argument("--npz", help="output .npz path (written at exactly this path)")
    parser.add_argument("--gltf", metavar="OUT.glb", help="the visible baked meshes and the camera as glTF binary")
    parser.add_argument("--profile", choices=list(PROFILES), default="web",
                        help="how the transfer is packed (--gltf): web (WebGL's attribute budget, beyond it a data "
                        "texture), godot (CUSTOM0-3 only), generic (no limit)")


def run(args, in_blender: bool) -> int:
    if (args.npz is None) == (args.gltf is None):
        raise InputError("give one of --npz OUT.npz (with --object) or --gltf OUT.glb")
    if args.gltf:
        check_suffix(args.gltf, "--gltf", gltf.SUFFIXES)
    elif args.object is None:
        raise InputError("--npz needs --object NAME")
    open_file(args.file, required=True)
    if args.gltf:
        check_outputs([("--gltf", args.gltf)])
        return _run_gltf(bpy.context.scene, args.gltf, args.profile)
    ob = bpy.data.objects.get(args.object)
    if ob is None or ob.type != "MESH":
        raise InputError(f"no mesh object named {args.object!r} in {args.file}")
    mesh = ob.data
    texel_bake = texel_maps.is_texel_bake(mesh)
    maps = texel_maps.exr_paths(mesh, _stem(args.npz)) if texel_bake else []
    check_outputs([("--npz", args.npz), *(("--npz's map", path) for path in maps)])
    if texel_bake:
        return _export_texels(ob, args.npz)
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
    write_npz(args.npz, positions=geometry.points_to_world(matrix, local),
              normals=geometry.directions_to_world(matrix, normals), local_positions=local, matrix_world=matrix,
              transfer=transfer.reshape(len(local), -1, transfer.shape[-1]), point_vertices=point_vertices,
              metadata=np.array(json.dumps(meta)), **per_corner)
    split = f" ({meta.get('split_vertices', 0)} split: {len(local)} points)" if corner_points is not None else ""
    print(f"prt: wrote {args.npz}: {len(mesh.vertices)} vertices{split}, order {meta['order']}, {meta['mode']}")
    return 0


def _run_gltf(scene, path, profile) -> int:
    done = gltf.export(scene, path, profile)
    print(f"prt: {gltf_summary(done)}")
    warn(done["notes"])
    return 0


def gltf_summary(done: dict) -> str:
    """One line: where, which profile, how each mesh was packed, under which light COLOR_0 was shaded."""
    packs = "; ".join(f"{name}: {_packing(p)}" for name, p in done["packs"].items())
    return f"wrote {done['path']} ({done['profile']} profile): {packs}; COLOR_0 under {done['light_source']}"


def _packing(packed) -> str:
    if isinstance(packed, PackedMaps):
        height, width = packed.maps[0].shape[:2]
        return f"order {packed.order} in {len(packed.maps)} RGBA32F texel maps of {width} × {height} ({packed.texcoord})"
    return (f"order {packed.order} × {packed.channels} in {packed.vec4s} VEC4 "
            f"{'attributes' if packed.texture is None else 'texels of a data texture'}")


def _stem(npz: str) -> str:
    """Where a texel bake's maps go: beside the .npz, named after it."""
    return os.path.splitext(npz)[0]


def write_npz(path: str, **arrays):
    """The arrays as an .npz at exactly `path` (np.savez would add .npz to a name without it), whole or not at
    all."""
    with replacing(path) as temporary, open(temporary, "wb") as handle:
        np.savez(handle, **arrays)


def _export_texels(ob, npz: str) -> int:
    """A texel bake: its maps as 32-bit EXR files beside the .npz (`<stem>_t00.exr`, ..., `<stem>_error.exr`, laid
    out as stored), and the .npz with `transfer` (height × width × n², float32, gutters included), the UV map's
    name, `matrix_world` and `metadata`."""
    mesh = ob.data
    planes, meta = texel_maps.read_planes(mesh)
    written = texel_maps.save_exr(mesh, _stem(npz))
    write_npz(npz, transfer=planes.T.reshape(meta["height"], meta["width"], -1), uv_map=np.array(meta["uv_map"]),
              matrix_world=np.array(ob.matrix_world, dtype=np.float64), metadata=np.array(json.dumps(meta)))
    print(f"prt: wrote {npz} and {len(written)} EXR maps ({', '.join(map(os.path.basename, written))}): "
          f"{meta['width']} × {meta['height']} texels in UV map {meta['uv_map']!r}, order {meta['order']}, "
          f"{meta['mode']}")
    return 0
