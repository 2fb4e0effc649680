"""The stored layout: a bake's transfer attributes and metadata on a mesh, written, read back and removed.

Stored layout (documented in the README; bump core.bake.CONVENTION_VERSION when it changes):
- POINT-domain FLOAT_VECTOR attributes `_prt_t00`, `_prt_t01`, ... each holding 3 consecutive SH
  coefficients (k = 3j, 3j+1, 3j+2; the last one zero-padded). The leading `_` lets glTF export them.
  Coloured (interreflected) transfer has one such set per channel: `_prt_r00`..., `_prt_g00`..., `_prt_b00`....
- POINT-domain FLOAT attribute `_prt_error`: per-vertex estimated relative standard error.
- Mesh custom property `prt` (a group): order, mode, samples, rays, convention, vertex_count,
  est_rms_rel_error, est_max_rel_error, time_s, date, bake_id, seed, target_error, skipped_vertices, channels
  (and bounces for interreflected bakes).
"""

from datetime import datetime, timezone
import uuid

import numpy as np

from ..core import bake
from ..core.statistics import rms
from ..core.errors import StaleBake

ATTRIBUTE_PREFIX = "_prt_"
ERROR_ATTRIBUTE = "_prt_error"
METADATA_KEY = "prt"


CHANNEL_LETTERS = {1: "t", 3: "rgb"}


def coefficient_attribute_names(order: int, channel: str = "t") -> list[str]:
    return [f"{ATTRIBUTE_PREFIX}{channel}{j:02d}" for j in range(-(-order * order // 3))]


def _channel_planes(transfer: np.ndarray) -> list[tuple[str, np.ndarray]]:
    """(letter, (V, n²)) per stored channel: 't' for grey transfer, 'r', 'g', 'b' for coloured."""
    if transfer.ndim == 2:
        return [("t", transfer)]
    return list(zip(CHANNEL_LETTERS[transfer.shape[1]], transfer.transpose(1, 0, 2)))


def write_transfer(ob, result, summary_fields: dict, settings: bake.BakeSettings):
    """Replaces any previous bake on the object's mesh: attributes first, metadata last."""
    mesh = ob.data
    remove_transfer(mesh)
    order = settings.order
    planes = _channel_planes(result.transfer)
    for letter, plane in planes:
        names = coefficient_attribute_names(order, letter)
        padded = np.zeros((len(mesh.vertices), 3 * len(names)), dtype=np.float32)
        padded[:, : order * order] = plane
        for j, name in enumerate(names):
            mesh.attributes.new(name, "FLOAT_VECTOR", "POINT")
            # Look the attribute up by name again: adding attributes can invalidate earlier references.
            mesh.attributes[name].data.foreach_set("vector", np.ascontiguousarray(padded[:, 3 * j: 3 * j + 3]).ravel())
    mesh.attributes.new(ERROR_ATTRIBUTE, "FLOAT", "POINT")
    mesh.attributes[ERROR_ATTRIBUTE].data.foreach_set("value", result.rel_error.astype(np.float32))
    mesh[METADATA_KEY] = {
        "order": order,
        "mode": settings.mode,
        "channels": len(planes),
        "samples": settings.samples,
        "target_error": settings.target_error,
        "seed": settings.seed,
        "convention": bake.CONVENTION_VERSION,
        "vertex_count": len(mesh.vertices),
        "rays": int(result.rays.sum()),
        "skipped_vertices": int(result.skipped.sum()),
        "est_rms_rel_error": rms(result.rel_error),
        "est_max_rel_error": float(result.rel_error.max(initial=0.0)),
        "date": datetime.now(timezone.utc).isoformat(timespec="seconds"),
        "bake_id": uuid.uuid4().hex,  # tells two bakes apart even within the same second
        **summary_fields,
    }
    mesh.update()


def remove_transfer(mesh):
    for name in [a.name for a in mesh.attributes if a.name.startswith(ATTRIBUTE_PREFIX)]:
        mesh.attributes.remove(mesh.attributes[name])
    if METADATA_KEY in mesh:
        del mesh[METADATA_KEY]


def read_transfer(mesh) -> tuple[np.ndarray, dict]:
    """(V, n²) grey or (V, 3, n²) coloured float32 transfer and the metadata; raises StaleBake when it no
    longer fits the mesh."""
    if METADATA_KEY not in mesh:
        raise StaleBake(f"mesh {mesh.name!r} has no PRT bake")
    meta = mesh[METADATA_KEY].to_dict()
    if meta.get("convention") != bake.CONVENTION_VERSION:
        raise StaleBake(f"mesh {mesh.name!r} was baked with layout version {meta.get('convention')}; rebake it")
    if meta["vertex_count"] != len(mesh.vertices):
        raise StaleBake(f"mesh {mesh.name!r} was baked with {meta['vertex_count']} vertices but now has "
                        f"{len(mesh.vertices)}; rebake it")
    order, letters = meta["order"], CHANNEL_LETTERS[meta.get("channels", 1)]
    planes = [_read_plane(mesh, order, letter) for letter in letters]
    return (planes[0] if len(planes) == 1 else np.ascontiguousarray(np.stack(planes, axis=1))), meta


def _read_plane(mesh, order, letter) -> np.ndarray:
    names = coefficient_attribute_names(order, letter)
    missing = [n for n in names if n not in mesh.attributes]
    if missing:
        raise StaleBake(f"mesh {mesh.name!r} lost its PRT attributes {', '.join(missing)}; rebake it")
    columns = np.empty((len(names), len(mesh.vertices) * 3), dtype=np.float32)
    for j, name in enumerate(names):
        mesh.attributes[name].data.foreach_get("vector", columns[j])
    transfer = columns.reshape(len(names), -1, 3).transpose(1, 0, 2).reshape(len(mesh.vertices), -1)
    return np.ascontiguousarray(transfer[:, : order * order])
