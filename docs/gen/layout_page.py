"""docs/reference/stored-layout.md: what a bake stores in the .blend file, as the bakes of layout_probe left it
(attribute names, types and domains, images, metadata keys and their values' kinds), with the meaning of each from
the tables below. A name the bakes store without a meaning here, or a meaning of a name they no longer store, stops
the generator, so the page and the code cannot part."""

import re

from prt_addon.blender import probe_volumes, storage, texel_maps
from prt_addon.core import bake, rules

from . import layout_probe
from .markdown import code, page, table

COEFFICIENTS = re.compile(rf"^{storage.ATTRIBUTE_PREFIX}([a-z])\d\d$")
RULES = "; ".join([f"{rules.MEASURED} measured by rays"] + [f"{code} {words}" for code, words in rules.WORDS.items()])
ATTRIBUTES = {
    "t": "SH transfer: attribute j holds coefficients k = 3j, 3j+1, 3j+2 (k = l(l+1)+m), the last one zero-padded; "
         "order n needs n²/3 of them rounded up (order 4: six). The leading `_` lets Blender's glTF exporter carry "
         "them (*Include > Attributes*)",
    "r": "red's SH transfer, laid out as `_prt_t..`", "g": "green's, the same", "b": "blue's, the same",
    storage.ERROR_ATTRIBUTE: "each point's estimated relative error (standard error of its transfer)",
    storage.RULE_ATTRIBUTE: f"the rule that decided each point instead of rays: {RULES}",
    storage.POINT_ATTRIBUTE: "each face corner's shading point: 0 to V−1 are the vertices, V on the further normals "
                             "of split vertices; the corners of one point hold equal rows",
}
METADATA = {
    "order": "SH order n", "mode": "unshadowed, shadowed or interreflected", "samples": "rays per point asked for",
    "target_error": "the target error (0: none)", "seed": "the random seed",
    "channels": "1 (grey transfer) or 3 (coloured: a set of attributes per colour)",
    "bounces": "interreflection bounces made", "convention": "the layout version (see above)",
    "domain": "POINT, CORNER or TEXEL: where the rows are", "storage": f"{texel_maps.TEXEL_STORAGE} for a texel bake",
    "vertex_count": "the mesh's vertices when baked: a mesh with another count is stale, never shaded",
    "corner_count": "the mesh's face corners when baked (per corner: another count is stale)",
    "points": "shading points (texels, for a texel bake)", "split_vertices": "vertices split by corner normals",
    "rays": "rays cast", "skipped_vertices": "points left out (no area, no normal)",
    "decided_by_rule": "points per rule that decided them instead of rays: " + ", ".join(rules.KEYS.values()),
    "inside_another_part": "points measured black inside another part (misplaced or hidden geometry)",
    "est_rms_rel_error": "estimated relative error, RMS over the points (noise and the rules' doubt)",
    "est_max_rel_error": "the largest estimated relative error of a point",
    "est_rule_rms_rel_error": "the rules' part of the RMS",
    "est_interp_rms_rel_error": "estimated error between vertices (what per-vertex storage misses), RMS",
    "est_interp_max_rel_error": "the same, the largest", "interp_points": "points between vertices measured for it",
    "ray_engine": "the engine that cast the rays, with its version (no rays: absent)",
    "error_curve": "the bake's error after each round of rays, then the bounces and texel lattices: rows of "
                   "after, seconds, rays, squared (the points' squared errors summed), points, est_rms_rel_error",
    "time_s": "the bake's seconds", "date": "when it was baked (ISO 8601, UTC)",
    "bake_id": "32 hex digits telling two bakes apart",
    "fingerprint": "32-digit hex digests of what the bake depended on: a `--stale-only` rebake compares them",
    storage.DYNAMIC_KEY: "on: the transfer is in the object's own frame, against itself only",
    storage.LIGHT_ORDER_KEY: "a dynamic object's: the order of the distant light it is lit by; its own `order` is "
                             "the probes' `received_order`, above it",
    "uv_map": "the lightmap UV map the texels follow", "width": "the maps' width in texels",
    "height": "their height", "texels": "texels covered by the mesh",
    "gutter": "texels dilated around each UV island", "images": "the maps' image names, in order",
    "error_image": "the error map's image name",
}
PROBES = {
    "layout": "this layout's version", "order": "SH order n of the distant light: the matrices' n² columns",
    "received_order": "SH order N of the light arriving at the probes: the matrices' N² rows",
    "channels": "1 or 3 (one per colour)",
    "resolution": "probes along the cube's X, Y, Z", "placement": "the matrix taking the cube [−1, 1]³ to world "
    "space as baked (the Empty's display size included), 16 floats by rows", "mode": "the bake's mode",
    "samples": "rays per probe asked for", "rays": "rays cast per probe", "seed": "the random seed",
    "inside_probes": "probes inside geometry, left out", "est_max_error": "the largest estimated error of a probe",
    "date": "when it was baked (ISO 8601, UTC)", "bake_id": "32 hex digits telling two bakes apart",
    "fingerprint": "32-digit hex digests of what the probes depended on: a `--stale-only` rebake compares them",
}
INTRO = f"""\
A bake is stored in the `.blend` file itself, on each receiver's mesh: Blender attributes that hold the transfer,
and a custom property `{storage.METADATA_KEY}` that says how it was baked. A texel bake stores images, a probe volume
custom properties of its Empty. Everything on this page is read from bakes the generator makes, so it lists exactly
what the add-on writes.

The layout's version is **{bake.CONVENTION_VERSION}** (`convention` in the metadata); files of version
{", ".join(str(version) for version in storage.READABLE_CONVENTIONS if version != bake.CONVENTION_VERSION)} (per
vertex only, no `domain`) still read. A bake of another version, or one whose mesh no longer has the vertices (or,
per corner, the face corners) it was baked with, is reported as stale and never shaded: rebake it.

SH convention: real SH with the Condon-Shortley phase (`Y_1,-1 = -√(3/4π) y`, `Y_1,0 = √(3/4π) z`,
`Y_1,1 = -√(3/4π) x`), index `k = l(l+1)+m`, directions in world space (in the object's own frame for a dynamic
object). The transfer holds 1/π: outgoing radiance = albedo · Σ L_k T_k. Coefficients are float32.
"""
TEXEL_NOTE = f"""\
The maps are float RGBA images in the lightmap UV map's space: map j holds coefficients k = 4j to 4j + 3 in R, G, B,
A (the last one zero-padded), one texel per covered texel centre, gutters dilated, Non-Color, **packed in the
.blend** as lossless 32-bit OpenEXR so that the file travels whole (File › External Data › Unpack writes them out).
The error map holds the error in R, G and B. Each image's custom property `{storage.MAP_OF_KEY}` names its mesh;
Blender may append `.001` to a taken name, so read the names from `images` and `error_image`. The relighting's
shaded image `_prt_<mesh>{texel_maps.SHADED_SUFFIX}` is not packed: it is shaded again whenever the file opens.
"""


def text() -> str:
    found = layout_probe.bake_and_read()
    cases = list(found.metadata)
    return page("Stored layout", INTRO,
                "## Attributes\n\nOn each mesh baked per point, in the domain of its rows: POINT (one row per "
                "vertex) where no vertex is split by its corner normals, else CORNER (one row per face corner).\n\n"
                + _attributes(found, cases),
                f"## Metadata\n\nThe mesh's custom property `{storage.METADATA_KEY}`, a group:\n\n"
                + _keys(found.metadata, METADATA, cases),
                "## Texel bakes\n\n" + table(["Image", "Holds"], _images(found)) + "\n" + TEXEL_NOTE,
                "## Probe volumes\n\nOn the probe volume's Empty:\n\n" + _probe_volume(found))


def _attributes(found, cases) -> str:
    """A row per attribute, or per set of coefficient attributes, in the order of ATTRIBUTES (Blender's order of
    a mesh's attributes varies by version)."""
    by_name = {}
    for case in cases:
        for name, (kind, domain) in found.attributes[case].items():
            match = COEFFICIENTS.match(name)
            key = match.group(1) if match else name
            shown = f"{storage.ATTRIBUTE_PREFIX}{key}00, {storage.ATTRIBUTE_PREFIX}{key}01, ..." if match else name
            entry = by_name.setdefault(key, {"name": shown, "kinds": set(), "domains": set(), "cases": []})
            entry["kinds"].add(kind)
            entry["domains"].add(domain)
            if case not in entry["cases"]:
                entry["cases"].append(case)
    _same_names(set(by_name), set(ATTRIBUTES), "attributes")
    per_point = [case for case in cases if found.attributes[case]]
    rows = [(code(entry["name"]), " or ".join(sorted(entry["kinds"])), " or ".join(sorted(entry["domains"])),
             _cases(entry["cases"], per_point, "every bake per point"), ATTRIBUTES[key])
            for key, entry in sorted(by_name.items(), key=lambda item: list(ATTRIBUTES).index(item[0]))]
    rows.append((code(storage.VALIDATION_ERROR_ATTRIBUTE), "FLOAT", "the bake's", "a validation (optional)",
                 "the last validation's error of each vertex (corner) against Cycles, relative to the object's "
                 "Cycles RMS, written by **Validate with Cycles**; removed with the bake it judged"))
    return table(["Attribute", "Type", "Domain", "Written for", "What it holds"], rows)


def _keys(metadata: dict, meanings: dict, cases: list) -> str:
    keys = list(meanings)  # in the order of the meanings: Blender's own order of a group's keys varies by version
    _same_names({key for case in cases for key in metadata[case]}, set(keys), "metadata keys")
    rows = []
    for key in keys:
        having = [case for case in cases if key in metadata[case]]
        rows.append((code(key), _kind(metadata[having[0]][key]), _cases(having, cases, "every bake"),
                     meanings[key]))
    return table(["Key", "Value", "Written for", "Meaning"], rows)


def _images(found) -> list:
    names = sorted({name for case in found.images for name in found.images[case]})
    holds = {"_t00": "map 0: coefficients 0-3 (then `_t01`: 4-7, ...)", "_error": "the estimated relative error"}
    rows = []
    for name in names:
        meaning = next((words for suffix, words in holds.items() if name.endswith(suffix)), None)
        if meaning is None:
            raise ValueError(f"a texel bake stores image {name}, which docs/gen/layout_page.py does not describe")
        rows.append((code(name), meaning))
    return rows


def _probe_volume(found) -> str:
    meta = found.probe_volume[probe_volumes.METADATA_KEY]
    _same_names(set(meta), set(PROBES), "probe volume metadata keys")
    properties = table(["Custom property", "Value", "What it holds"], [
        (code(probe_volumes.TRANSFER_KEY), "float array",
         "the transfer matrices, P × channels × N² × n² in C order, probes numbered X slowest, Z fastest: each maps "
         "the distant light's SH (order n) to the SH of the light arriving at the probe (order N)"),
        (code(probe_volumes.VALID_KEY), "integer array", "P flags: 0 for a probe inside geometry, left out"),
        (code(probe_volumes.METADATA_KEY), "group", "the keys below")])
    keys = table(["Key", "Value", "Meaning"], [(code(key), _kind(meta[key]), meaning) for key, meaning in PROBES.items()])
    return properties + f"\n`{probe_volumes.METADATA_KEY}` holds:\n\n" + keys


def _kind(value) -> str:
    if isinstance(value, bool):
        return "on or off"
    if isinstance(value, int):
        return "integer"
    if isinstance(value, float):
        return "number"
    if isinstance(value, str):
        return "text"
    if isinstance(value, dict):
        return "group" + (": " + ", ".join(value) if value else "")
    if isinstance(value, list):
        return "list of groups" if value and isinstance(value[0], dict) else "list"
    raise ValueError(f"stored-layout page cannot describe {value!r}")


def _cases(having: list, every: list, words: str) -> str:
    """Where a name is stored: `words` for every case, else the cases, or every case but the few without it."""
    if having == every:
        return words
    missing = [case for case in every if case not in having]
    return f"{words} but {', '.join(missing)}" if len(missing) < len(having) else ", ".join(having)


def _same_names(stored: set, described: set, what: str):
    if stored != described:
        raise ValueError(f"the bakes store {what} {sorted(stored - described)} that docs/gen/layout_page.py does not "
                         f"describe, and it describes {sorted(described - stored)} that they do not store")
