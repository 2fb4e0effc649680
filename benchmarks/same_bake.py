"""Same bake: every stored array of four fixed bakes in one .npz, and a bit-for-bit comparison of two such files.

    .venv/bin/python benchmarks/same_bake.py OUT.npz [--scenes demo,cow,texel,farm] [--quick] [--assets FOLDER]
                                             [--ray-engine auto|embree|bvhtree]
    .venv/bin/python benchmarks/same_bake.py --compare A.npz B.npz

A change that must not change what a bake stores (a restructuring, a faster engine) is checked by capturing on the
commit before it and on the change, then comparing: one line per array, `equal` or `DIFFERS`, exit 1 if any differ
or is missing from one side. The scenes, each built afresh in an empty file, saved, and baked by the command line
as a user bakes (`python -m prt_addon bake`, `merge`) with a fixed seed and one BLAS thread (README: Baking on a
farm, bit for bit):

- demo: the demo scene (sample_scenes.build_demo_scene), shadowed, every mesh per vertex, 2 workers;
- cow: cow.obj of ../shared/assets (or --assets) imported as a user imports it (flat-shaded: stored per corner) on a floor of 3 × 3
  quads, baked shadowed and, in another file, interreflected (the floor red, so the bounce is coloured);
- texel: a floor quad stored per texel (48 × 48 in its own UV map) under a sphere stored per vertex;
- farm: the cow scene interreflected as two shards (`--shard K/2`) merged by `prt merge`.

For each baked mesh the .npz holds every attribute of the mesh (the bake's `_prt_*` and the mesh's own: a bake must
not change them), its metadata without what differs between any two bakes (date, bake id, seconds) as a JSON string,
and the pixels of every `_prt_*` image (the texel maps). Names are `scene/object/attribute`,
`scene/object/metadata` and `scene/image/NAME`. `--quick` bakes fewer samples: its files only compare with other
`--quick` files.
"""

import argparse
import functools
import json
import os
import subprocess
import sys
import tempfile
import time

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
sys.path.insert(0, ROOT)

import numpy as np  # noqa: E402

ASSETS = os.path.join(os.path.dirname(ROOT), "shared", "assets")  # the public test meshes beside the checkout
SCENES = ("demo", "cow", "texel", "farm")
SEED = 7
SAMPLES, QUICK_SAMPLES = 64, 16
VOLATILE = {"time_s", "date", "bake_id"}  # metadata that differs between any two bakes of the same scene
IMAGE_PREFIX = "_prt_"
FIELDS = {  # attribute data type: (foreach field, values per element, dtype)
    "FLOAT": ("value", 1, np.float32), "INT": ("value", 1, np.int32), "BOOLEAN": ("value", 1, np.bool_),
    "FLOAT_VECTOR": ("vector", 3, np.float32), "FLOAT2": ("vector", 2, np.float32),
    "FLOAT_COLOR": ("color", 4, np.float32), "BYTE_COLOR": ("color", 4, np.float32),
    "INT8": ("value", 1, np.int8), "INT32_2D": ("value", 2, np.int32), "QUATERNION": ("value", 4, np.float32),
    "FLOAT4X4": ("value", 16, np.float32),
}


# -- the scenes --------------------------------------------------------------------------------------------------
def principled(name, rgb):
    """A material whose Principled BSDF's Base Color is `rgb`: the albedo the bake reads."""
    from prt_addon.blender.compat import new_node_material
    material = new_node_material(name)
    nodes = material.node_tree.nodes
    shader, output = nodes.new("ShaderNodeBsdfPrincipled"), nodes.new("ShaderNodeOutputMaterial")
    shader.inputs["Base Color"].default_value = (*rgb, 1.0)
    material.node_tree.links.new(shader.outputs["BSDF"], output.inputs["Surface"])
    return material


def floor(size, cuts, name="Floor"):
    """A square floor at z = 0 of cuts × cuts quads, with Blender's own UV map over [0, 1]."""
    import bpy
    bpy.ops.mesh.primitive_grid_add(x_subdivisions=cuts, y_subdivisions=cuts, size=size)
    ob = bpy.context.object
    ob.name = ob.data.name = name
    return ob


def demo_scene():
    from prt_addon.blender import sample_scenes
    sample_scenes.build_demo_scene()


def cow_scene(cow: str):
    """The cow as imported (flat-shaded), 2 units long, resting on a red 6 × 6 floor of 3 × 3 quads."""
    import bpy
    bpy.ops.wm.obj_import(filepath=cow)
    (cow,) = bpy.context.selected_objects
    cow.name = "Cow"
    points = np.array([vertex.co for vertex in cow.data.vertices]) @ np.array(cow.matrix_world)[:3, :3].T
    low, high = points.min(axis=0), points.max(axis=0)
    factor = 2.0 / float((high - low).max())
    cow.scale = [factor * s for s in cow.scale]
    cow.location = (-factor * (low[0] + high[0]) / 2, -factor * (low[1] + high[1]) / 2, -factor * low[2])
    floor(6.0, 3).data.materials.append(principled("Red", (0.8, 0.1, 0.1)))
    cow.data.materials.append(principled("Grey", (0.7, 0.7, 0.7)))


def texel_scene():
    """A one-quad 4 × 4 floor (its UV map spans it) under a smooth 32 × 16 UV sphere of radius 0.5 at height 1.5,
    built in a fixed corner order (benchmarks/assets.py's uv_sphere)."""
    from benchmarks.assets import uv_sphere
    floor(4.0, 1)
    ball = uv_sphere("Ball", segments=32, rings=16)
    ball.data.shade_smooth()
    ball.scale, ball.location = (0.5, 0.5, 0.5), (0.0, 0.0, 1.5)


def bakes(quick: bool, cow: str, ray_engine: str | None = None) -> dict:
    """bake name: (scene builder, [command lines, each a list of `prt` arguments with the paths {scene}, {step},
    {part_1}, {part_2} and {out} filled in per bake]); the last command writes {out}. `ray_engine`: the Ray Engine
    every bake casts with (None: the command line's default)."""
    common = ["--order", "4", "--seed", str(SEED), "--samples", str(QUICK_SAMPLES if quick else SAMPLES),
              *(["--ray-engine", ray_engine] if ray_engine else [])]
    cow_shadowed = [*common, "--mode", "shadowed", "--objects", "Cow,Floor"]
    interreflected = [*common, "--mode", "interreflected", "--bounces", "2", "--objects", "Cow,Floor"]
    cow_scene_ = functools.partial(cow_scene, cow)
    return {
        "demo": (demo_scene, [["bake", "{scene}", *common, "--mode", "shadowed", "--workers", "2",
                               "--output", "{out}"]]),
        "cow_shadowed": (cow_scene_, [["bake", "{scene}", *cow_shadowed, "--workers", "2", "--output", "{out}"]]),
        "cow_interreflected": (cow_scene_, [["bake", "{scene}", *interreflected, "--workers", "2",
                                            "--output", "{out}"]]),
        "texel": (texel_scene, [["bake", "{scene}", *common, "--mode", "shadowed", "--objects", "Floor",
                                 "--storage", "texel", "--resolution", "48", "--uv-map", "UVMap", "--output",
                                 "{step}"],
                                ["bake", "{step}", *common, "--mode", "shadowed", "--objects", "Ball",
                                 "--output", "{out}"]]),
        "farm": (cow_scene_, [["bake", "{scene}", *interreflected, "--workers", "1", "--shard", "1/2",
                              "--out", "{part_1}"],
                             ["bake", "{scene}", *interreflected, "--workers", "1", "--shard", "2/2",
                              "--out", "{part_2}"],
                             ["merge", "{scene}", "{part_1}", "{part_2}", "--output", "{out}"]]),
    }


def of_scene(name: str, chosen: list[str]) -> bool:
    """Whether bake `name` (cow_shadowed, ...) belongs to one of the `chosen` scenes (cow, ...)."""
    return name.split("_")[0] in chosen


# -- baking and reading ------------------------------------------------------------------------------------------
def save_scene(build, path):
    import bpy
    bpy.ops.wm.read_homefile(use_empty=True)
    build()
    bpy.ops.wm.save_as_mainfile(filepath=path)


def prt(arguments):
    """`python -m prt_addon ARGUMENTS` in a fresh process, one BLAS thread; exits with its error if it fails."""
    env = dict(os.environ, PYTHONPATH=ROOT, OPENBLAS_NUM_THREADS="1")
    done = subprocess.run([sys.executable, "-m", "prt_addon", *arguments], cwd=ROOT, env=env, capture_output=True,
                          text=True, timeout=600)
    if done.returncode != 0:
        raise SystemExit(f"same_bake: prt {' '.join(arguments)} failed:\n{done.stdout}{done.stderr}")


def attribute_values(attribute) -> np.ndarray:
    """The attribute's values, one row per element, in their stored type."""
    field, width, dtype = FIELDS[attribute.data_type]
    values = np.empty(len(attribute.data) * width, dtype=dtype)
    attribute.data.foreach_get(field, values)
    return values.reshape(len(attribute.data), width)


def read_baked(path, scene: str) -> dict:
    """Every baked mesh's attributes and metadata and every _prt_ image's pixels in the saved file at `path`."""
    import bpy
    bpy.ops.wm.open_mainfile(filepath=path, load_ui=False)
    arrays = {}
    for ob in sorted(bpy.data.objects, key=lambda ob: ob.name):
        if ob.type != "MESH" or "prt" not in ob.data:
            continue
        for attribute in ob.data.attributes:
            if not attribute.name.startswith("."):
                arrays[f"{scene}/{ob.name}/{attribute.name}"] = attribute_values(attribute)
        meta = {key: value for key, value in ob.data["prt"].to_dict().items() if key not in VOLATILE}
        for row in meta.get("error_curve", []):
            del row["seconds"]  # as time_s: differs between any two bakes
        arrays[f"{scene}/{ob.name}/metadata"] = np.array(json.dumps(meta, sort_keys=True, default=list))
    for image in sorted(bpy.data.images, key=lambda image: image.name):
        if image.name.startswith(IMAGE_PREFIX):
            pixels = np.empty(len(image.pixels), dtype=np.float32)
            image.pixels.foreach_get(pixels)
            arrays[f"{scene}/image/{image.name}"] = pixels.reshape(image.size[1], image.size[0], -1)
    if not arrays:
        raise SystemExit(f"same_bake: {path} holds no baked mesh")
    return arrays


def capture(out: str, chosen: list[str], quick: bool, cow: str, ray_engine: str | None = None) -> dict:
    """Builds, bakes and reads every chosen scene; writes all arrays to `out` (whole: a temporary file renamed)."""
    import bpy  # noqa: F401  (before anything that imports mathutils)
    arrays = {}
    with tempfile.TemporaryDirectory(prefix="same_bake_") as folder:
        for name, (build, commands) in bakes(quick, cow, ray_engine).items():
            if not of_scene(name, chosen):
                continue
            start = time.perf_counter()
            paths = {key: os.path.join(folder, f"{name}_{key}.{'npz' if key.startswith('part') else 'blend'}")
                     for key in ("scene", "step", "part_1", "part_2", "out")}
            save_scene(build, paths["scene"])
            for command in commands:
                prt([argument.format(**paths) for argument in command])
            found = read_baked(paths["out"], name)
            arrays.update(found)
            print(f"same_bake: {name}: {len(found)} arrays in {time.perf_counter() - start:.1f} s", flush=True)
    partial = out + ".partial.npz"
    np.savez(partial, **arrays)
    os.replace(partial, out)
    print(f"same_bake: wrote {len(arrays)} arrays to {out}")
    return arrays


# -- comparing ---------------------------------------------------------------------------------------------------
def difference(a: np.ndarray, b: np.ndarray) -> str:
    """`equal` when the arrays are bit for bit the same (shape, type and bytes), else what differs: for texts (the
    metadata), which keys."""
    if a.dtype.kind in "US" and b.dtype.kind in "US" and a.shape == b.shape == ():
        return "equal" if str(a) == str(b) else "DIFFERS: " + text_difference(str(a), str(b))
    if a.dtype != b.dtype or a.shape != b.shape:
        return f"DIFFERS: {a.dtype}{list(a.shape)} against {b.dtype}{list(b.shape)}"
    if a.tobytes() == b.tobytes():
        return "equal"
    if a.dtype.kind == "f":
        unequal = a.view(f"u{a.itemsize}") != b.view(f"u{b.itemsize}")
        largest = float(np.nanmax(np.abs(a.astype(np.float64) - b.astype(np.float64)))) if a.size else 0.0
        return f"DIFFERS: {int(unequal.sum())} of {a.size} values, largest difference {largest:.3g}"
    return f"DIFFERS: {int((a != b).sum())} of {a.size} values"


def text_difference(a: str, b: str) -> str:
    """The metadata keys whose values differ, where both are JSON objects."""
    try:
        first, second = json.loads(a), json.loads(b)
    except ValueError:
        return "the texts differ"
    keys = sorted(key for key in set(first) | set(second) if first.get(key) != second.get(key))
    return "keys " + ", ".join(keys)


def compare(first: str, second: str) -> int:
    """Prints one line per array of either file; 0 when every array is in both and bit for bit equal, else 1."""
    with np.load(first) as a, np.load(second) as b:
        names = sorted(set(a.files) | set(b.files))
        differing = 0
        for name in names:
            if name not in a.files or name not in b.files:
                line = f"only in {first if name in a.files else second}"
            else:
                line = difference(a[name], b[name])
            differing += line != "equal"
            print(f"{name}: {line}")
    print(f"same_bake: {len(names) - differing} of {len(names)} arrays equal; "
          + ("SAME bake" if not differing else f"{differing} DIFFER"))
    return 1 if differing else 0


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("out", nargs="?", help="the .npz to write")
    parser.add_argument("--compare", nargs=2, metavar=("A.npz", "B.npz"), help="compare two captures bit for bit")
    parser.add_argument("--scenes", default=",".join(SCENES), help=f"comma-separated, of {', '.join(SCENES)}")
    parser.add_argument("--quick", action="store_true", help=f"{QUICK_SAMPLES} samples instead of {SAMPLES}")
    parser.add_argument("--assets", default=ASSETS, help="the folder holding cow.obj (default: %(default)s)")
    parser.add_argument("--ray-engine", choices=("auto", "embree", "bvhtree"),
                        help="the Ray Engine every bake casts with (default: the command line's)")
    args = parser.parse_args(argv)
    if args.compare:
        missing = [path for path in args.compare if not os.path.isfile(path)]
        if missing:
            parser.error(f"no such file: {missing[0]}")
        return compare(*args.compare)
    chosen = [name.strip() for name in args.scenes.split(",")]
    unknown = [name for name in chosen if name not in SCENES]
    if not args.out or unknown:
        parser.error(f"unknown scene {unknown[0]!r}" if unknown else "give the .npz to write, or --compare A B")
    cow = os.path.join(args.assets, "cow.obj")
    if any(of_scene(name, chosen) for name in ("cow", "farm")) and not os.path.isfile(cow):
        parser.error(f"{cow} is missing (give the folder of the public test meshes with --assets)")
    capture(args.out, chosen, args.quick, cow, args.ray_engine)
    return 0


if __name__ == "__main__":
    sys.exit(main())
