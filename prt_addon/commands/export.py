"""`prt export`: one object's bake as a .npz for use outside Blender."""

import json

import bpy
import numpy as np

from ..blender import geometry, storage
from ..core.errors import InputError
from .common import open_file


def add_parser(commands):
    parser = commands.add_parser("export", help="write one object's bake to a .npz for use outside Blender")
    parser.add_argument("file", help=".blend file")
    parser.add_argument("--object", required=True, help="object name")
    parser.add_argument("--npz", required=True, help="output .npz path")


def run(args, in_blender: bool) -> int:
    open_file(args.file, required=True)
    ob = bpy.data.objects.get(args.object)
    if ob is None or ob.type != "MESH":
        raise InputError(f"no mesh object named {args.object!r} in {args.file}")
    transfer, meta = storage.read_transfer(ob.data)
    matrix = np.array(ob.matrix_world, dtype=np.float64)
    local = geometry.mesh_positions(ob.data)
    normals = geometry.directions_to_world(matrix, geometry.mesh_vertex_normals(ob.data))
    np.savez(args.npz, positions=geometry.points_to_world(matrix, local), normals=normals, local_positions=local,
             matrix_world=matrix, transfer=transfer.reshape(len(local), -1, transfer.shape[-1]),
             metadata=np.array(json.dumps(meta)))
    print(f"prt: wrote {args.npz}: {len(local)} vertices, order {meta['order']}, {meta['mode']}")
    return 0
