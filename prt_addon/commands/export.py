"""`prt export`: one object's bake as a .npz for use outside Blender: per shading point (the vertices, then the
further corner normals of split vertices), with each face corner's point where the bake is per corner; or the
scene's baked meshes as a glTF binary packed for a profile (blender.gltf)."""

import bpy

from ..blender import gltf, layouts
from ..core.errors import InputError
from ..core.gltf_pack import PROFILES
from ..core.outputs import check_suffix
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
    layout = layouts.stored(ob.data)
    maps = layout.npz_side_files(ob.data, args.npz)
    check_outputs([("--npz", args.npz), *(("--npz's map", path) for path in maps)])
    print(f"prt: {layout.npz(ob, args.npz)}")
    return 0


def _run_gltf(scene, path, profile) -> int:
    done = gltf.export(scene, path, profile)
    print(f"prt: {gltf_summary(done)}")
    warn(done["notes"])
    return 0


def gltf_summary(done: dict) -> str:
    """One line: where, which profile, how each mesh was packed, under which light COLOR_0 was shaded."""
    packs = "; ".join(f"{name}: {p.describe()}" for name, p in done["packs"].items())
    moving = "".join(f"; {label}: {', '.join(done[key])}" for key, label in
                     (("dynamic", "dynamic"), ("lit_per_vertex", "lit per vertex"), ("probe_volumes", "probe volumes"))
                     if done[key])
    return (f"wrote {done['path']} ({done['profile']} profile): {packs}{moving}; "
            f"COLOR_0 under {done['light_source']}")
