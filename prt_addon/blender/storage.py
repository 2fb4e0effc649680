"""The stored layout: a bake's transfer attributes and metadata on a mesh, written, read back and removed.

Stored layout (docs/reference/stored-layout.md is generated from what this writes; bump core.bake.CONVENTION_VERSION
when it changes):
- FLOAT_VECTOR attributes `_prt_t00`, `_prt_t01`, ... each holding 3 consecutive SH coefficients (k = 3j, 3j+1,
  3j+2; the last one zero-padded). The leading `_` lets glTF export them. Coloured (interreflected) transfer has
  one such set per channel: `_prt_r00`..., `_prt_g00`..., `_prt_b00`....
- FLOAT attribute `_prt_error`: the estimated relative standard error.
- INT attribute `_prt_rule`: the rule that decided each point instead of rays (core.rules; 0: measured).
- FLOAT attribute `_prt_validation_error` (optional, written by the panel's validation): the last validation's
  per-vertex (per-corner) error against Cycles, in the same domain. It goes with the bake it judged.
- Their domain: POINT, one row per vertex, where every vertex is one shading point (core.corners), as in
  convention 2; CORNER, one row per face corner, where some vertex is split by its corner normals, with the INT
  CORNER attribute `_prt_point` giving each corner's shading point (corners of one point hold equal rows).
- Mesh custom property `prt` (a group): order, mode, samples, rays, convention, domain, vertex_count,
  corner_count, points, split_vertices, est_rms_rel_error, est_max_rel_error (noise and the rules' doubt),
  est_rule_rms_rel_error (the rules' part, core.rules.estimate), time_s, date, bake_id, seed,
  target_error, skipped_vertices, decided_by_rule (a group: points per rule, core.rules.counts),
  inside_another_part (points measured black inside another part, core.job.TransferJob), channels (and
  bounces for interreflected bakes), est_interp_rms_rel_error, est_interp_max_rel_error, interp_points,
  ray_engine (the engine that cast the rays, with its version; none for an unshadowed bake), error_curve (a list of
  groups: after, seconds, rays, squared, points, est_rms_rel_error; core.error_curve) (written by blender.store),
  fingerprint (a group, written by blender.fingerprint).
Convention 2 files (POINT only, no domain) still read.
"""

from datetime import datetime, timezone
import uuid

import bpy
import numpy as np

from ..core import bake, rules
from ..core.errors import InputError, StaleBake

ATTRIBUTE_PREFIX = "_prt_"
ERROR_ATTRIBUTE = "_prt_error"
RULE_ATTRIBUTE = "_prt_rule"
VALIDATION_ERROR_ATTRIBUTE = "_prt_validation_error"
POINT_ATTRIBUTE = "_prt_point"
METADATA_KEY = "prt"
DYNAMIC_KEY = "dynamic"  # in a dynamic object's metadata: its transfer is in its own frame (blender.relighting)
LIGHT_ORDER_KEY = "light_order"  # and the order of the light it is lit by, below its transfer's (light_order)
MAP_OF_KEY = "_prt_texel_map_of"  # on each image stored for a bake (texel maps, their shaded image): its mesh
READABLE_CONVENTIONS = (2, bake.CONVENTION_VERSION)  # 2: POINT domain only, no `domain` key


CHANNEL_LETTERS = {1: "t", 3: "rgb"}


def coefficient_attribute_names(order: int, channel: str = "t") -> list[str]:
    return [f"{ATTRIBUTE_PREFIX}{channel}{j:02d}" for j in range(-(-order * order // 3))]


def _channel_planes(transfer: np.ndarray) -> list[tuple[str, np.ndarray]]:
    """(letter, (V, n²)) per stored channel: 't' for grey transfer, 'r', 'g', 'b' for coloured."""
    if transfer.ndim == 2:
        return [("t", transfer)]
    return list(zip(CHANNEL_LETTERS[transfer.shape[1]], transfer.transpose(1, 0, 2)))


def write_transfer(mesh, result, summary_fields: dict, settings: bake.BakeSettings, corner_points=None,
                   split_vertices: int = 0):
    """Writes the bake's attributes, then its metadata, on a mesh without a bake (blender.layouts removes an
    earlier one). `result` holds one row per shading point; `corner_points` (C,) each corner's point where
    vertices are split (CORNER domain), else None."""
    order = settings.order
    domain = "POINT" if corner_points is None else "CORNER"
    rows = slice(None) if corner_points is None else corner_points
    planes = _channel_planes(result.transfer)
    for letter, plane in planes:
        names = coefficient_attribute_names(order, letter)
        padded = np.zeros((len(plane), 3 * len(names)), dtype=np.float32)
        padded[:, : order * order] = plane
        padded = padded[rows]
        for j, name in enumerate(names):
            mesh.attributes.new(name, "FLOAT_VECTOR", domain)
            # Look the attribute up by name again: adding attributes can invalidate earlier references.
            mesh.attributes[name].data.foreach_set("vector", np.ascontiguousarray(padded[:, 3 * j: 3 * j + 3]).ravel())
    mesh.attributes.new(ERROR_ATTRIBUTE, "FLOAT", domain)
    mesh.attributes[ERROR_ATTRIBUTE].data.foreach_set("value", result.rel_error[rows].astype(np.float32))
    mesh.attributes.new(RULE_ATTRIBUTE, "INT", domain)
    mesh.attributes[RULE_ATTRIBUTE].data.foreach_set("value", result.rules[rows].astype(np.int32))
    if corner_points is not None:
        mesh.attributes.new(POINT_ATTRIBUTE, "INT", "CORNER")
        mesh.attributes[POINT_ATTRIBUTE].data.foreach_set("value", corner_points.astype(np.int32))
    write_metadata(mesh, result, settings, domain, split_vertices, summary_fields)


def write_metadata(mesh, result, settings: bake.BakeSettings, domain: str, split_vertices: int, fields: dict):
    """The bake's metadata, written last: its layout's `domain` (blender.layouts) and its figures."""
    mesh[METADATA_KEY] = {
        "order": settings.order,
        "mode": settings.mode,
        "channels": 1 if result.transfer.ndim == 2 else result.transfer.shape[1],
        "samples": settings.samples,
        "target_error": settings.target_error,
        "seed": settings.seed,
        "convention": bake.CONVENTION_VERSION,
        "domain": domain,
        "vertex_count": len(mesh.vertices),
        "corner_count": len(mesh.loops),
        "points": len(result.rel_error),
        "split_vertices": split_vertices,
        "rays": int(result.rays.sum()),
        "skipped_vertices": int(result.skipped.sum()),
        "decided_by_rule": rules.counts(result.rules),
        **rules.estimate(result.rel_error, result.rel_rule_error),
        "date": datetime.now(timezone.utc).isoformat(timespec="seconds"),
        "bake_id": uuid.uuid4().hex,  # tells two bakes apart even within the same second
        **fields,
    }
    mesh.update()


def light_order(meta: dict) -> int:
    """The SH order of the distant light a bake is shaded under: its own order, but for a dynamic object's, which
    bakes to the order of the light its probes carry to it (core.probe_transfer.received_order) and is lit by the
    distant light of the scene's order, its higher coefficients left unlit where no probe reaches it."""
    return meta.get(LIGHT_ORDER_KEY) or meta["order"]


def baked_objects(objects) -> list:
    """The visible meshes with a PRT bake among `objects`."""
    return [ob for ob in objects if ob.type == "MESH" and ob.visible_get() and METADATA_KEY in ob.data]


def remove_transfer(mesh):
    remove_images(mesh)
    for name in [a.name for a in mesh.attributes if a.name.startswith(ATTRIBUTE_PREFIX)]:
        mesh.attributes.remove(mesh.attributes[name])
    if METADATA_KEY in mesh:
        del mesh[METADATA_KEY]


def remove_images(mesh):
    """Every image stored for the mesh's bake: a texel bake's maps and their shaded image."""
    for image in [image for image in bpy.data.images if image.get(MAP_OF_KEY) == mesh.name]:
        bpy.data.images.remove(image)


def read_values(mesh, name) -> tuple[np.ndarray, str] | None:
    """A FLOAT or integer attribute of the bake (ERROR_ATTRIBUTE, VALIDATION_ERROR_ATTRIBUTE, RULE_ATTRIBUTE) as
    float32 or int32 rows and their domain (POINT: per vertex, CORNER: per face corner); None where the mesh does
    not have it."""
    attribute = mesh.attributes.get(name)
    if attribute is None:
        return None
    values = np.empty(len(attribute.data), dtype=np.float32 if attribute.data_type == "FLOAT" else np.int32)
    attribute.data.foreach_get("value", values)
    return values, attribute.domain


def write_validation_error(mesh, errors: np.ndarray):
    """The last validation's errors, one per row it compared: per vertex, or per face corner for a per-corner
    bake (the bake's domain)."""
    domain = _metadata(mesh).get("domain", "POINT")
    if VALIDATION_ERROR_ATTRIBUTE in mesh.attributes:
        mesh.attributes.remove(mesh.attributes[VALIDATION_ERROR_ATTRIBUTE])
    mesh.attributes.new(VALIDATION_ERROR_ATTRIBUTE, "FLOAT", domain)
    mesh.attributes[VALIDATION_ERROR_ATTRIBUTE].data.foreach_set("value", np.asarray(errors, dtype=np.float32))


def read_transfer(mesh) -> tuple[np.ndarray, dict]:
    """(P, n²) grey or (P, 3, n²) coloured float32 transfer per shading point (the vertices, unless the bake is
    per corner: see corner_points) and the metadata; raises StaleBake when it no longer fits the mesh."""
    meta = _metadata(mesh)
    if meta.get("domain", "POINT") not in ("POINT", "CORNER"):  # attributes per point hold it, nothing else
        raise InputError(f"mesh {mesh.name!r} is baked per {meta['domain'].lower()}, not per vertex: compare it "
                         f"with `prt validate --image`")
    order, letters = meta["order"], CHANNEL_LETTERS[meta.get("channels", 1)]
    corner_points = corner_points_of(mesh)
    planes = [_read_plane(mesh, order, letter, corner_points, meta.get("points")) for letter in letters]
    return (planes[0] if len(planes) == 1 else np.ascontiguousarray(np.stack(planes, axis=1))), meta


def corner_points_of(mesh) -> np.ndarray | None:
    """(C,) each face corner's shading point where the bake is per corner, else None (one point per vertex)."""
    meta = _metadata(mesh)
    if meta.get("domain", "POINT") == "POINT":
        return None
    if POINT_ATTRIBUTE not in mesh.attributes:
        raise StaleBake(f"mesh {mesh.name!r} lost its PRT attribute {POINT_ATTRIBUTE}; rebake it")
    corner_points = np.empty(len(mesh.loops), dtype=np.int32)
    mesh.attributes[POINT_ATTRIBUTE].data.foreach_get("value", corner_points)
    return corner_points


def _metadata(mesh) -> dict:
    if METADATA_KEY not in mesh:
        raise StaleBake(f"mesh {mesh.name!r} has no PRT bake")
    meta = mesh[METADATA_KEY].to_dict()
    if meta.get("convention") not in READABLE_CONVENTIONS:
        raise StaleBake(f"mesh {mesh.name!r} was baked with layout version {meta.get('convention')}; rebake it")
    if meta["vertex_count"] != len(mesh.vertices):
        raise StaleBake(f"mesh {mesh.name!r} was baked with {meta['vertex_count']} vertices but now has "
                        f"{len(mesh.vertices)}; rebake it")
    if meta.get("domain") == "CORNER" and meta["corner_count"] != len(mesh.loops):
        raise StaleBake(f"mesh {mesh.name!r} was baked with {meta['corner_count']} face corners but now has "
                        f"{len(mesh.loops)}; rebake it")
    return meta


def _read_plane(mesh, order, letter, corner_points, point_count) -> np.ndarray:
    """(rows, n²): per vertex, or per point from the first corner of each (zero for a loose vertex's point)."""
    names = coefficient_attribute_names(order, letter)
    missing = [n for n in names if n not in mesh.attributes]
    if missing:
        raise StaleBake(f"mesh {mesh.name!r} lost its PRT attributes {', '.join(missing)}; rebake it")
    count = len(mesh.vertices) if corner_points is None else len(mesh.loops)
    columns = np.empty((len(names), count * 3), dtype=np.float32)
    for j, name in enumerate(names):
        mesh.attributes[name].data.foreach_get("vector", columns[j])
    transfer = columns.reshape(len(names), -1, 3).transpose(1, 0, 2).reshape(count, -1)[:, : order * order]
    if corner_points is None:
        return np.ascontiguousarray(transfer)
    points, first_corner = np.unique(corner_points, return_index=True)
    rows = np.zeros((point_count, order * order), dtype=np.float32)
    rows[points] = transfer[first_corner]
    return rows
