"""docs/reference/gltf-extras.schema.json: a JSON Schema (draft 2020-12) of what the glTF export adds to a file,
the `extras.prt` of its scene and of each mesh, built from the constants the export writes (core.gltf_pack,
core.gltf_probes, blender.schema's windows, core.settings' limits). Every object is closed (no property it does not
name), so tests/test_gltf.py and tests/test_gltf_probes.py, which check each exported file against it, fail when the
export writes something this schema, and so the manual, does not describe. gltf_page renders it as the page."""

import json
import math
import re
import tomllib

from prt_addon.blender import schema as saved
from prt_addon.core import gltf_pack, gltf_probes, probe_transfer, settings as spec

from . import ROOT

FILE_NAME = "gltf-extras.schema.json"
FORMAT = "RGBA32F"  # the float textures' texels: four float32 each
ROWS = "top first (v = 0)"  # texel maps' row order: glTF's v runs down the image


def _integer(minimum=0, maximum=None, description=""):
    return {"type": "integer", "minimum": minimum, **({"maximum": maximum} if maximum is not None else {}),
            "description": description}


def _numbers(count=None, description="", **items):
    sized = {"minItems": count, "maxItems": count} if count else {"minItems": 1}
    return {"type": "array", "items": {"type": "number", **items}, **sized, "description": description}


def _closed(required, properties, description, optional=()):
    """An object with exactly these properties: `required` and `optional` are lists of their names."""
    missing = (set(required) | set(optional)) ^ set(properties)
    if missing:
        raise ValueError(f"properties {missing} are neither required nor optional")
    return {"type": "object", "description": description, "required": list(required), "properties": properties,
            "additionalProperties": False}


MESH_ORDER = _integer(1, probe_transfer.received_order(spec.MAX_ORDER),
                      "SH order n: bands l < n, n² coefficients per channel (a dynamic object's: its probes' "
                      "received_order)")
LIGHT_ORDER = _integer(1, spec.MAX_ORDER, "on a dynamic object's mesh: the order of the distant light it is lit by, "
                                          "below its transfer's; its coefficients above it are lit only through "
                                          "the probes")
CHANNELS = {"enum": [1, 3], "description": "1: grey transfer, one set for every colour; 3: coloured "
                                           "(interreflected) transfer, red's, then green's, then blue's"}
VEC4S = _integer(1, None, "VEC4s per shading point: channels × n² floats, zero-padded to whole VEC4s")
DYNAMIC = {"const": True, "description": "present on a dynamic object's mesh: its transfer is in its node's own "
                                         "frame (see the convention's `dynamic`)"}
PROBE_LIGHT = {"enum": ["vertex", "centre"], "description": "on a dynamic object's mesh: where it takes the probes' "
                                                           "light, at each vertex or at its bounding box's centre "
                                                           "(see the convention's `dynamic`)"}
ATTRIBUTE_NAME = "^(" + "|".join(sorted({re.escape(profile.attribute_name.replace("{}", ""))
                                         for profile in gltf_pack.PROFILES.values()})) + ")(0|[1-9][0-9]*)$"
WINDOWS = [identifier for identifier, _, _ in saved.WINDOWS if identifier != "auto"] + ["tapered"]


def _mesh(layout, description, required, properties, optional=()):
    common = {"order": MESH_ORDER, "channels": CHANNELS, "vec4s": VEC4S,
              "layout": {"const": layout, "description": "how the transfer is stored: " + description},
              "dynamic": DYNAMIC, "probe_light": PROBE_LIGHT, "light_order": LIGHT_ORDER}
    return _closed(["order", "channels", "vec4s", "layout", *required], {**common, **properties},
                   f"A mesh whose transfer is {description}.", ["dynamic", "probe_light", "light_order", *optional])


MESH_LAYOUTS = {
    "attributes": _mesh("attributes", "in VEC4 vertex attributes", ["attributes"], {
        "attributes": {"type": "array", "minItems": 1, "items": {"type": "string", "pattern": ATTRIBUTE_NAME},
                       "description": "the glTF attributes that hold it, in order: VEC4 j holds floats 4j to 4j + 3 "
                                      "of the vertex's shading point"}}),
    "texture": _mesh("texture", "in a float data texture indexed by shading point", ["index_attribute", "texture"], {
        "index_attribute": {"const": gltf_pack.INDEX_ATTRIBUTE,
                            "description": "the scalar float attribute giving each vertex its shading point p"},
        "texture": _closed(["width", "height", "format", "bufferView"], {
            "width": {"const": gltf_pack.TEXTURE_WIDTH, "description": "texels per row"},
            "height": _integer(1, None, "rows"),
            "format": {"const": FORMAT, "description": "four float32 per texel"},
            "bufferView": _integer(0, None, "the buffer view of the GLB's binary chunk holding the texels, row "
                                            "after row")},
            "The data texture: texel p·vec4s + j holds VEC4 j of shading point p.")}),
    "texel_maps": _mesh("texel_maps", "in texel maps read through a lightmap UV map", ["texcoord", "maps"], {
        "channels": {"const": 1, "description": "texel bakes are grey"},
        "texcoord": {"type": "string", "pattern": "^TEXCOORD_(0|[1-9][0-9]*)$",
                     "description": "the glTF attribute of the lightmap UV map the maps follow"},
        "maps": _closed(["width", "height", "format", "rows", "bufferViews"], {
            "width": _integer(1, None, "texels per row"),
            "height": _integer(1, None, "rows"),
            "format": {"const": FORMAT, "description": "four float32 per texel"},
            "rows": {"const": ROWS, "description": "the rows run down the image, as glTF's v does"},
            "bufferViews": {"type": "array", "minItems": 1, "items": {"type": "integer", "minimum": 0},
                            "description": "one buffer view per map: map j holds coefficients 4j to 4j + 3 of "
                                           "each texel, in glTF's frame"}},
            "The texel maps, sampled at each fragment's TEXCOORD like any texture.")}),
}
SUN = _closed(["kind", "direction", "theta", "phi", "angular_radius", "rgb", "zonal"], {
    "kind": {"const": "sun", "description": "a disc of light from one direction"},
    "direction": _numbers(3, "unit vector towards the sun, in glTF's frame"),
    "theta": {"type": "number", "minimum": 0, "maximum": math.pi,
              "description": "Blender's angle of the sun from the zenith (+Z), radians: what a viewer turns"},
    "phi": {"type": "number", "minimum": -math.pi, "maximum": math.pi,
            "description": "Blender's azimuth from +X towards +Y, radians"},
    "angular_radius": {"type": "number", "minimum": 0, "maximum": math.pi / 2,
                       "description": "the disc's angular radius, radians"},
    "rgb": _numbers(3, "irradiance on a surface facing the sun, per colour", minimum=0),
    "zonal": _numbers(None, "z_l of the disc for unit irradiance, l < order: its SH is "
                            "rgb · sqrt(4π/(2l+1)) · z_l · Y_lm(direction)")},
    "A sun.")
SPREAD = _closed(["kind", "rgb", "coefficients"], {
    "kind": {"enum": ["sky", "environment"], "description": "sky: the same light from every direction; "
                                                            "environment: an equirectangular image"},
    "rgb": _numbers(3, "the light's colour × strength", minimum=0),
    "coefficients": {"type": "array", "minItems": 3, "maxItems": 3, "items": _numbers(None),
                     "description": "3 × n² radiance SH coefficients, one row per colour, in glTF's frame, colour "
                                    "and rotation applied"}},
    "A sky or an environment.")
BAKE = _closed(["layout", "mode", "samples", "rays", "seed", "est_max_error", "date", "bake_id"], {
    "layout": _integer(1, None, "the stored probe layout's version"),
    "mode": {"enum": [identifier for identifier, _, _ in spec.MODE.choices], "description": "the bake's mode"},
    "samples": _integer(1, None, "rays per probe asked for"),
    "rays": _integer(0, None, "rays cast per probe"),
    "seed": _integer(0, spec.MAX_SEED, "the bake's random seed"),
    "est_max_error": {"type": "number", "minimum": 0, "description": "the largest estimated error of a probe"},
    "date": {"type": "string", "description": "when it was baked (ISO 8601, UTC)"},
    "bake_id": {"type": "string", "pattern": "^[0-9a-f]{32}$", "description": "tells two bakes apart"}},
    "A probe volume's `bake`.")
PROBE_VOLUME = _closed(["name", "layout", "order", "received_order", "channels", "resolution", "probes", "placement",
                        "valid", "bufferView", "format", "bake"], {
    "name": {"type": "string", "description": "the Empty's name"},
    "layout": {"const": gltf_probes.LAYOUT, "description": "this layout's version"},
    "order": _integer(1, spec.MAX_ORDER, "the distant light's SH order n: each matrix has n² columns"),
    "received_order": _integer(probe_transfer.received_order(1), probe_transfer.received_order(spec.MAX_ORDER),
                               "the arriving light's SH order N, above n: each matrix has N² rows"),
    "channels": {"enum": [1, 3], "description": "1: one matrix for every colour; 3: one per colour"},
    "resolution": {"type": "array", "minItems": 3, "maxItems": 3, "description": "probes along the cube's x, y, z",
                   "items": {"type": "integer", "minimum": 1, "maximum": spec.PROBE_RESOLUTION.maximum}},
    "probes": _integer(1, None, "P = nx · ny · nz"),
    "placement": _numbers(16, gltf_probes.CONVENTION["placement"]),
    "valid": {"type": "array", "items": {"enum": [0, 1]},
              "description": "P flags, probe by probe: 0 for a probe inside static geometry, left out"},
    "bufferView": _integer(0, None, "the buffer view of the matrices: " + gltf_probes.CONVENTION["matrices"]),
    "format": {"const": "float32", "description": "the matrices' numbers"},
    "bake": {"$ref": "#/$defs/probe_bake", "description": "what its stored bake says of itself"}},
    "A baked probe volume: transfer matrices at a grid of probes that light the dynamic objects inside it.")
SCENE = _closed(["profile", "convention", "order", "window", "light_source", "active_light", "lights"], {
    "profile": {"enum": list(gltf_pack.PROFILES), "description": "the export profile the meshes are packed for"},
    "convention": {"const": gltf_pack.CONVENTION, "description": "the SH convention, in words"},
    "order": _integer(1, spec.MAX_ORDER, "the highest order of the meshes: the lights' order"),
    "window": {"enum": WINDOWS, "description": "the taper of high bands a viewer applies to the summed light, per "
                                               "mesh order; tapered: Hanning's factors to the power "
                                               "`window_strengths[order]`"},
    "window_strengths": {"type": "object", "propertyNames": {"pattern": "^[1-9][0-9]*$"},
                         "additionalProperties": {"type": "number", "minimum": 0, "maximum": 1},
                         "description": "with window tapered: the strength the Auto window found for each order "
                                        "under the exported lights, kept while a viewer turns them"},
    "light_source": {"type": "string", "description": "what the lights are: the scene's SH lights, or the default "
                                                      "light when the scene has none"},
    "active_light": _integer(0, None, "the index of the scene's active SH light"),
    "lights": {"type": "array", "items": {"oneOf": [{"$ref": "#/$defs/sun"}, {"$ref": "#/$defs/spread_light"}]},
               "description": "the lights, in glTF's frame"},
    "probe_convention": {"const": gltf_probes.CONVENTION, "description": "the probe volumes' rules, in words"},
    "probe_volumes": {"type": "array", "minItems": 1, "items": {"$ref": "#/$defs/probe_volume"},
                      "description": "every baked probe volume of the scene"}},
    "The scene's `extras.prt`: the convention, the profile, the window and the lights.",
    ["window_strengths", "probe_convention", "probe_volumes"])
SCENE["dependentRequired"] = {"probe_volumes": ["probe_convention"], "probe_convention": ["probe_volumes"]}
SCENE["if"] = {"properties": {"window": {"const": "tapered"}}}
SCENE["then"], SCENE["else"] = {"required": ["window_strengths"]}, {"not": {"required": ["window_strengths"]}}


def _with(key, definition):
    """An array of objects whose `extras.prt` is `definition`; `contains`: at least one has it."""
    holds = {"type": "object", "required": ["extras"], "properties": {"extras": {
        "type": "object", "required": ["prt"], "properties": {"prt": {"$ref": f"#/$defs/{definition}"}}}}}
    return {"type": "array", "minItems": 1, "items": holds} if key == "meshes" else \
        {"type": "array", "contains": holds}


def document() -> dict:
    website = tomllib.loads((ROOT / "blender_manifest.toml").read_text())["website"]
    return {
        "$schema": "https://json-schema.org/draft/2020-12/schema",
        "$id": f"{website}reference/{FILE_NAME}",
        "title": "PRT glTF extras",
        "description": "The JSON chunk of a GLB written by PRT's glTF export (`prt export --gltf`, Export glTF): "
                       "the `extras.prt` of its scene and of every mesh. Other glTF properties are glTF's own.",
        "type": "object",
        "required": ["scenes", "meshes"],
        "properties": {"scenes": _with("scenes", "scene"), "meshes": _with("meshes", "mesh")},
        "$defs": {"scene": SCENE, "mesh": {"oneOf": [{"$ref": f"#/$defs/mesh_{name}"} for name in MESH_LAYOUTS],
                                           "description": "A mesh's `extras.prt`: its transfer's layout."},
                  **{f"mesh_{name}": layout for name, layout in MESH_LAYOUTS.items()},
                  "sun": SUN, "spread_light": SPREAD, "probe_volume": PROBE_VOLUME, "probe_bake": BAKE},
    }


def text() -> str:
    return json.dumps(document(), indent=2, ensure_ascii=False) + "\n"
