"""PRT probe volumes in Blender: an Empty shown as a cube (its display size the half side), marked `prt_probe_volume`,
that the user scales over the scene, with its probes per axis in `prt_probe_resolution` (blender.schema; the grid is
core.probe_grid's). A bake of the static scene bakes every visible one (blender.request, blender.execute) and stores
each probe's transfer matrix on its Empty (blender.store); the display lights each dynamic object from the volume
around each of its vertices, or around its centre (blender.relighting).

Stored on the Empty, as custom properties saved in the .blend with it:
- `_prt_probe_transfer`: float32 array, the matrices (P, C, N², n²) in C order, probes numbered as core.probe_grid;
- `_prt_probe_valid`: int array (P,), 0 for a probe inside static geometry (left out of the interpolation);
- `prt_probes` (a group): layout (PROBE_LAYOUT), order (n, the distant light's), received_order (N, the arriving
  light's: core.probe_transfer.received_order), channels, resolution, placement (where the probes were
  baked: the matrix taking core.probe_grid's cube [−1, 1]³ to world space, the display size included, 16 floats by
  rows; moving the Empty afterwards does not move them, but makes them stale), mode, samples, rays, seed,
  inside_probes, est_max_error (the largest probe's standard error, Frobenius norm), date, bake_id, fingerprint
  (what the probes depend on, a group of digests: blender.fingerprint.volume_fingerprints, so a check can tell
  stale probes).
An Empty has no mesh whose attributes could hold them; ID property arrays are saved, duplicated and deleted with the
object, and read back through the buffer protocol at once (a million floats in milliseconds).
"""

from dataclasses import dataclass, field
from datetime import datetime, timezone
import math
import uuid

import bpy
import numpy as np

from ..core import probe_grid
from ..core import settings as spec
from ..core.errors import StaleBake
from .texel_bake import OBJECT_PREFIX

TRANSFER_KEY = "_prt_probe_transfer"
VALID_KEY = "_prt_probe_valid"
METADATA_KEY = "prt_probes"
PROBE_LAYOUT = 2  # bump when the stored layout or its conventions change


@dataclass
class VolumeInput:
    """A probe volume to bake: its name, placement (4, 4: core.probe_grid's cube to world space), probes per axis
    and, once the request has read the scene, its fingerprint (blender.fingerprint.volume_fingerprints)."""
    name: str
    matrix: np.ndarray
    resolution: tuple
    fingerprint: dict = field(default_factory=dict)

    @property
    def positions(self) -> np.ndarray:
        return probe_grid.probe_positions(self.matrix, self.resolution)


@dataclass
class StoredProbes:
    """A probe volume's bake as stored: its matrices (P, C, N², n²), which probes are valid (P,), the inverse of
    the placement they were baked at (4, 4), its probes per axis, and the SH orders of the distant light (n) and of
    the light arriving at its probes (N)."""
    matrices: np.ndarray
    valid: np.ndarray
    to_volume: np.ndarray
    resolution: tuple
    order: int
    received_order: int
    bake_id: str = ""
    last_light: tuple | None = None  # (light bytes, its probes' lights, which are formed): see lights()


def is_probe_volume(ob) -> bool:
    return ob.type == "EMPTY" and bool(getattr(ob, OBJECT_PREFIX + spec.PROBE_VOLUME.name, False))


def volumes_to_bake(context, problems: list) -> list[VolumeInput]:
    """The visible probe volumes of the view layer; one flat on an axis (zero scale) is left out with its reason in
    `problems`."""
    found = []
    for ob in context.view_layer.objects:
        if not (is_probe_volume(ob) and ob.visible_get()):
            continue
        volume = volume_input(ob)
        if abs(np.linalg.det(volume.matrix[:3, :3])) < 1e-12:
            problems.append(f"{ob.name!r}: a probe volume flat on an axis (zero scale) holds no probes; scale it")
            continue
        found.append(volume)
    return found


def volume_input(ob) -> VolumeInput:
    """The probe volume as it stands now: its placement (the cube drawn, [−size, size]³ in the Empty's frame, which
    core.probe_grid takes as [−1, 1]³) and its probes per axis."""
    matrix = np.array(ob.matrix_world, dtype=np.float64) @ np.diag([ob.empty_display_size] * 3 + [1.0])
    return VolumeInput(ob.name, matrix, tuple(getattr(ob, OBJECT_PREFIX + spec.PROBE_RESOLUTION.name)))


def write(volumes: list[VolumeInput], probes, settings) -> list[str]:
    """Each volume's share of `probes` (core.probe_transfer.ProbeTransfer, the volumes' probes in order) on its
    Empty; one line per volume for the bake's notes."""
    lines, first = [], 0
    for volume in volumes:
        rows = slice(first, first + int(np.prod(volume.resolution)))
        first = rows.stop
        ob = bpy.data.objects[volume.name]
        matrices = probes.matrices[rows]
        for key in (TRANSFER_KEY, VALID_KEY):
            # Assigning an array of another size over an existing one corrupts Blender's heap (bpy 5.3: a crash a
            # few allocations later), so a new resolution's arrays are always new properties.
            if key in ob:
                del ob[key]
        ob[TRANSFER_KEY] = np.ascontiguousarray(matrices, dtype=np.float32).ravel()
        ob[VALID_KEY] = (~probes.inside[rows]).astype(np.int32)
        inside = int(probes.inside[rows].sum())
        ob[METADATA_KEY] = {
            "layout": PROBE_LAYOUT, "order": settings.order, "received_order": math.isqrt(matrices.shape[2]),
            "channels": matrices.shape[1],
            "resolution": list(volume.resolution), "placement": volume.matrix.ravel().tolist(),
            "mode": settings.mode, "samples": settings.samples, "rays": probes.rays, "seed": settings.seed,
            "inside_probes": inside, "est_max_error": float(probes.std_error[rows].max(initial=0.0)),
            "date": datetime.now(timezone.utc).isoformat(timespec="seconds"), "bake_id": uuid.uuid4().hex,
            "fingerprint": volume.fingerprint,
        }
        ob.update_tag()  # the display reads the new probes (blender.relighting)
        lines.append(f"probe volume {volume.name!r}: {len(matrices)} probes, {inside} inside geometry and left out")
    return lines


def bake_id(ob):
    """The stored bake's id, None without one."""
    meta = ob.get(METADATA_KEY)
    return None if meta is None else meta.get("bake_id")


def read(ob) -> StoredProbes:
    """The Empty's stored probes; raises StaleBake where they are missing or of another layout."""
    meta = ob.get(METADATA_KEY)
    if meta is None or TRANSFER_KEY not in ob or VALID_KEY not in ob:
        raise StaleBake(f"probe volume {ob.name!r} has no PRT bake")
    if meta.get("layout") != PROBE_LAYOUT:
        raise StaleBake(f"probe volume {ob.name!r} was baked with layout version {meta.get('layout')}; rebake it")
    resolution, order, channels = tuple(meta["resolution"]), meta["order"], meta["channels"]
    shape = (int(np.prod(resolution)), channels, meta["received_order"] ** 2, order * order)
    matrices = np.frombuffer(ob[TRANSFER_KEY], dtype=np.float32)
    count = shape[0]
    if matrices.size != math.prod(shape):
        raise StaleBake(f"probe volume {ob.name!r} holds {matrices.size} values, not its {count} probes'; rebake it")
    placement = np.array(meta["placement"], dtype=np.float64).reshape(4, 4)
    # A copy: the buffer is the property's own memory, freed when a file is loaded or the property replaced.
    return StoredProbes(matrices.reshape(shape).copy(), np.frombuffer(ob[VALID_KEY], dtype=np.int32) != 0,
                        np.linalg.inv(placement), resolution, order, meta["received_order"], meta.get("bake_id", ""))


def lights(probes: StoredProbes, light, needed=None) -> np.ndarray:
    """(P, 3, N²) each probe's incoming light under the distant light (3, n²) (core.probe_grid.probe_lights), those
    of the probes `needed` (indices; None: all) at least, the others' rows left unfilled. Kept with the probes for
    the last light: a light change costs one product per probe at most, and a moving object only those of the
    probes it reaches that were not yet formed."""
    key = light.tobytes()
    if probes.last_light is None or probes.last_light[0] != key:
        rows = (len(probes.valid), 3, probes.matrices.shape[2])
        probes.last_light = key, np.empty(rows, dtype=probes.matrices.dtype), np.zeros(len(probes.valid), dtype=bool)
    _, found, formed = probes.last_light
    missing = np.flatnonzero(~formed) if needed is None else needed[~formed[needed]]
    if len(missing) == len(formed):
        found[:] = probe_grid.probe_lights(probes.matrices, light)
    elif len(missing):
        found[missing] = probe_grid.probe_lights(probes.matrices[missing], light)
    formed[missing] = True
    return found


def containing(stored: list[StoredProbes], points, matrix=None) -> tuple[np.ndarray, np.ndarray]:
    """(which volume holds each of `points` (N, 3), placed in world space by `matrix` (4, 4): the index in `stored` of
    the smallest whose cube holds it, −1 for none; the points in that volume's frame (N, 3) float32, as
    core.probe_grid.placed_points gives them).

    A moving object inside a single volume (the usual case, and every frame of it) costs one product and one look
    at its largest coordinate."""
    placed = [found.to_volume @ (np.eye(4) if matrix is None else matrix) for found in stored]
    known = {}
    if len(stored) == 1:
        local = probe_grid.placed_points(points, placed[0])
        if np.abs(local).max(initial=0.0) <= 1.0:
            return np.zeros(len(local), dtype=np.int64), local
        known[0] = local
    count = len(np.asarray(points).reshape(-1, 3))
    # Column by column, in placed_points' layout (each axis contiguous): numpy works (N, 3) rows with a loop of 3.
    which, local = np.full(count, -1), np.zeros((3, count), dtype=np.float32).T
    # Largest first, so that a smaller volume inside it takes its points over.
    for index in sorted(range(len(stored)), key=lambda k: abs(np.linalg.det(stored[k].to_volume[:3, :3]))):
        mine = known[index] if index in known else probe_grid.placed_points(points, placed[index])
        inside = (np.abs(mine[:, 0]) <= 1.0) & (np.abs(mine[:, 1]) <= 1.0) & (np.abs(mine[:, 2]) <= 1.0)
        which[inside] = index
        for axis in range(3):
            np.copyto(local[:, axis], mine[:, axis], where=inside)
    return which, local


def light_at(stored: list[StoredProbes], point, light) -> np.ndarray | None:
    """(3, N²) the SH light arriving at `point` (3,) in world space from the distant light (3, n²) through the
    smallest of `stored` of the light's order that holds it (core.probe_grid), or None where none does."""
    stored = [probes for probes in stored if probes.order ** 2 == light.shape[-1]]
    which, local = containing(stored, point)
    if which[0] < 0:
        return None
    probes = stored[which[0]]
    indices, weights = probe_grid.trilinear_weights(local[0], probes.resolution, probes.valid)
    return probe_grid.blend(lights(probes, light, indices), indices, weights)
