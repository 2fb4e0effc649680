"""Reading a GLB in the tests as a viewer reads it: its document and binary chunk (its extras checked against the
manual's JSON Schema), an accessor's values, the SH lights of its scene's extras; and Khronos' glTF validator's
verdict on it."""

import json
import subprocess

import jsonschema
import numpy as np

from conftest import ROOT, run_cli

from prt_addon.commands.view import VIEWER
from prt_addon.core import glb, lobes, rotation

VALIDATE = VIEWER.parent / "tests" / "js" / "validate_glb.mjs"
# What the manual says the export writes (docs/gen_reference.py builds it from the export's constants).
EXTRAS_SCHEMA = jsonschema.Draft202012Validator(
    json.loads((ROOT / "docs" / "reference" / "gltf-extras.schema.json").read_text(encoding="utf-8")))


def baked_and_saved(settings, path, then=lambda: None):
    """Bakes the scene as it is with `settings` (core.bake.BakeSettings), runs `then`, saves it at `path` and
    empties the session: the path."""
    import bpy
    from prt_addon.blender.scene_bake import SceneBake
    SceneBake(bpy.context, settings).run(log=lambda line: None)
    then()
    bpy.ops.wm.save_as_mainfile(filepath=str(path))
    bpy.ops.wm.read_homefile(use_empty=True)
    return path


def exported(blend, *said):
    """`prt export BLEND --gltf` beside it: the GLB's path, once the command has exited 0 saying each of `said`."""
    path = blend.with_suffix(".glb")
    done = run_cli("export", blend, "--gltf", path)
    assert done.returncode == 0, done.stderr
    for words in said:
        assert words in done.stdout, done.stdout
    return path


def read_glb(path):
    """(document, binary chunk) of an exported GLB, once its extras are found to be what the manual describes."""
    with open(path, "rb") as file:
        document, binary = glb.read(file.read())
    assert_extras_as_described(document)
    return document, binary


def extras_problems(document) -> list[str]:
    """Where the document's PRT extras differ from docs/reference/gltf-extras.schema.json, one line each."""
    return [f"{error.json_path}: {error.message[:300]}" for error in EXTRAS_SCHEMA.iter_errors(document)]


def assert_extras_as_described(document):
    problems = extras_problems(document)
    assert not problems, "the export wrote extras the manual does not describe (docs/gen/gltf_schema.py):\n" + \
        "\n".join(problems)


def accessor(document, binary, index) -> np.ndarray:
    """A float or normalised unsigned short accessor's values as floats, (count, components)."""
    spec = document["accessors"][index]
    kind = {5126: np.float32, 5123: np.uint16}[spec["componentType"]]
    size = np.dtype(kind).itemsize
    view = document["bufferViews"][spec["bufferView"]]
    components = {"SCALAR": 1, "VEC2": 2, "VEC3": 3, "VEC4": 4}[spec["type"]]
    start = view.get("byteOffset", 0) + spec.get("byteOffset", 0)
    stride = view.get("byteStride", size * components) // size
    values = np.frombuffer(bytes(binary[start: start + size * stride * spec["count"]]), dtype=kind)
    values = values.reshape(spec["count"], stride)[:, :components].astype(np.float64)
    return values / 65535 if spec.get("normalized") else values


def light_from_extras(extras, order) -> np.ndarray:
    """(3, n²) in glTF's frame, built as a viewer builds it: suns' zonal lobes along their directions, the rest
    as given, then the window."""
    light = np.zeros((3, order * order))
    for entry in extras["lights"]:
        if entry["kind"] == "sun":
            lobe = rotation.zonal_to_sh(np.array(entry["zonal"][:order]), entry["direction"])
            light += np.outer(entry["rgb"], lobe)
        else:
            light += np.array(entry["coefficients"])[:, : order * order]
    strength = extras.get("window_strengths", {}).get(str(order), 1.0)
    return lobes.apply_window(light, lobes.window(order, extras["window"], strength))


def validator_issues(path) -> dict:
    """The `issues` of gltf-validator's report on the GLB (numErrors, numWarnings, ..., messages), printed."""
    done = subprocess.run(["node", str(VALIDATE), str(path)], capture_output=True, text=True, timeout=120,
                          check=True, cwd=VIEWER)
    issues = json.loads(done.stdout)["issues"]
    print(f"gltf-validator on {path.name}: {issues['numErrors']} errors, {issues['numWarnings']} warnings, "
          f"{issues['numInfos']} infos, {issues['numHints']} hints")
    return issues
