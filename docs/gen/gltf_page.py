"""docs/reference/gltf-extras.md: what the glTF export adds to a file, rendered from the JSON Schema the export
tests check every exported file against (gltf_schema), with the profiles and the convention from core.gltf_pack."""

import json
import math

from prt_addon.core import gltf_pack, gltf_probes

from . import gltf_schema
from .markdown import code, page, table

INTRO = f"""\
`prt export FILE --gltf OUT.glb` and **Export glTF** (PRT › Bake) write the visible baked meshes and the scene's
camera as glTF binary through Blender's own glTF exporter, then add what that exporter cannot write: each mesh's
transfer, packed for a profile and rotated into glTF's Y-up frame, the SH lights and the convention in the scene's
`extras.prt`, and each mesh's layout in its `extras.prt`. `COLOR_0` holds the colours under the current SH lights
(16-bit, clipped to 0-1), so any glTF viewer shows the lit scene; a PRT viewer relights it from the extras.

The schema [`{gltf_schema.FILE_NAME}`]({gltf_schema.FILE_NAME}) (JSON Schema, draft 2020-12) describes them
exactly: every object it names is closed, and the export tests check each file they export against it. To check a
file of your own:

```python
import json, struct
import jsonschema  # pip install jsonschema

with open("scene.glb", "rb") as file:
    data = file.read()
length = struct.unpack_from("<I", data, 12)[0]  # the first chunk of a GLB is its JSON
document = json.loads(data[20:20 + length])
with open("{gltf_schema.FILE_NAME}") as file:
    jsonschema.validate(document, json.load(file))
```
"""
PROFILES = """\
## Profiles

A profile decides where the transfer goes: each glTF vertex holds its shading point's transfer, channel after
channel, zero-padded to whole VEC4s.
"""
THREE = """\
## Reading it in three.js

GLTFLoader keeps the custom attributes under lower-cased names (`_prt_sh0`, ..., `_prt_index`). The browser viewer
(`viewer/` in the repository) holds a small shader module with no other dependency than three.js:

```js
import {prtMaterial, setLight} from "./prt_material.js";   // viewer/
import {LightSet} from "./lights.js";
const gltf = await new GLTFLoader().loadAsync("scene.glb");
const lights = new LightSet(gltf.parser.json.scenes[0].extras.prt);
gltf.scene.traverse((mesh) => {
  const layout = mesh.isMesh && gltf.parser.json.meshes[gltf.parser.associations.get(mesh).meshes].extras.prt;
  if (!layout) return;                                         // (texture layout: pass a DataTexture, see main.js)
  mesh.material = prtMaterial(layout, mesh.material.map, null);
  setLight(mesh.material, layout, lights.total(layout.order)); // again whenever a light moves
});
```

`lights.total(order)` sums the lights in glTF's frame as the add-on does; the vertex shader forms
Σ_j dot(T_j, L_c,j) per colour channel c. With the `godot` profile the VEC4s are Godot's custom arrays
(`CUSTOM0` ... `CUSTOM3` in a spatial shader).
"""


def text() -> str:
    schema = gltf_schema.document()
    definitions = schema["$defs"]
    return page(
        "glTF extras", INTRO, PROFILES + "\n" + _profiles(),
        "## The convention\n\n`extras.prt.convention` of the scene says it in words:\n\n"
        + table(["Key", "What it says"], [(code(key), words) for key, words in gltf_pack.CONVENTION.items()]),
        "## The scene\n\n" + _fields(definitions["scene"]),
        "### A sun\n\n" + _fields(definitions["sun"]),
        "### A sky or an environment\n\n" + _fields(definitions["spread_light"]),
        "### Probe volumes\n\n" + _fields(definitions["probe_volume"]),
        _fields(definitions["probe_bake"], "`bake` holds:"),
        "`probe_convention` of the scene says their rules in words:\n\n"
        + table(["Key", "What it says"], [(code(key), words) for key, words in gltf_probes.CONVENTION.items()]),
        "## Each mesh\n\nA mesh's `extras.prt` has one of three layouts, by `layout`.\n",
        *(f"### `layout`: {code(name)}\n\n" + _fields(definitions[f"mesh_{name}"])
          for name in gltf_schema.MESH_LAYOUTS),
        THREE)


def _profiles() -> str:
    rows = []
    for profile in gltf_pack.PROFILES.values():
        names = ", ".join(code(profile.attribute_name.format(j)) for j in range(2)) + ", ..."
        budget = "none" if profile.max_attributes is None else f"{profile.max_attributes} VEC4s"
        beyond = "—" if profile.max_attributes is None else (
            "a float data texture (`layout`: `texture`)" if profile.texture_beyond else "refused, nothing written")
        rows.append((code(profile.name), names, budget, beyond, profile.limit))
    return table(["Profile", "Attributes", "Budget", "Beyond it", "Why"], rows)


LABELS = {"sun": "a sun", "spread_light": "a sky or an environment", "probe_volume": "a probe volume",
          "probe_bake": "an object"}  # how a field's value names the definition it refers to


def _fields(definition: dict, heading: str = "") -> str:
    """A closed object's properties (name, always there or not, what values it takes, what it means), then those
    of each object nested in it; `heading` instead of its description."""
    rows = [(code(name), "yes" if name in definition["required"] else "no", _kind(node),
             node.get("description", ""))
            for name, node in definition["properties"].items()]
    nested = [_fields(node, f"`{name}` holds:") for name, node in definition["properties"].items()
              if "properties" in node]
    return "\n".join([(heading or definition["description"]) + "\n\n"
                      + table(["Field", "Always", "Value", "Meaning"], rows)] + nested)


def _kind(node: dict) -> str:
    if "$ref" in node:
        return LABELS[node["$ref"].rsplit("/", 1)[-1]] + " (below)"
    if "oneOf" in node:
        return " or ".join(_kind(option) for option in node["oneOf"])
    if "const" in node:
        return "an object of text (below)" if isinstance(node["const"], dict) else code(json.dumps(node["const"]))
    if "enum" in node:
        return " or ".join(code(json.dumps(option)) for option in node["enum"])
    kind = node.get("type")
    if kind in ("integer", "number"):
        return ("an integer" if kind == "integer" else "a number") + _range(node)
    if kind == "string":
        return "text" + (f" matching {code(node['pattern'])}" if "pattern" in node else "")
    if kind == "array":
        count = node.get("minItems") if node.get("minItems") == node.get("maxItems") else None
        items = node["items"]
        if items.get("type") in ("integer", "number"):
            return f"{count or 'a list of'} {items['type']}s{_range(items)}"
        return f"{count} lists, each {_kind(items)}" if count else f"a list, each {_kind(items)}"
    if kind == "object":
        if "properties" in node:
            return "an object (below)"
        return "an object: order → a number" + _range(node["additionalProperties"])
    raise ValueError(f"gltf_page cannot describe {node}")


def _range(node: dict) -> str:
    low, high = (_bound(node[key]) if key in node else None for key in ("minimum", "maximum"))
    if low is not None and high is not None:
        return f" {low} to {high}"
    return f" ≥ {low}" if low is not None else f" ≤ {high}" if high is not None else ""


def _bound(number) -> str:
    """A limit as a reader knows it: π and π/2 by name."""
    for fraction, name in ((1, "π"), (0.5, "π/2"), (-1, "−π")):
        if isinstance(number, float) and number == fraction * math.pi:
            return name
    return str(number) if isinstance(number, int) else f"{number:g}"
