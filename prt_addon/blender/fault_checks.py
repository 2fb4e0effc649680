"""The checks of a messy model's faults, before any ray (core.mesh_faults, core.corners): for each receiver, its face
corners whose custom normal points against their face, its zero-area and sliver faces, and its parts whose surfaces
cross another part (of itself or of another visible mesh) or lie inside a closed one. Each is a warning naming the
count, since the bake decides there by rule (docs/cycles_conventions.md, docs/design/contact.md), with the faces at
fault for the checklist's Select button (`fault_faces`, which PRT_OT_select_faults selects). They read the meshes as the
user edits them (not their modifiers' result), so the faces found are the ones Edit Mode shows."""

from dataclasses import dataclass

import numpy as np

from ..core import corners, mesh_faults
from ..core.checks import WARNING, Check
from .mesh_arrays import mesh_corner_normals, mesh_corner_vertices, mesh_positions, mesh_triangles

AGAINST, THIN, CROSSING, INSIDE = "against", "thin", "crossing", "inside"
FAULTS = (AGAINST, THIN, CROSSING, INSIDE)


@dataclass
class Meshes:
    """Objects' triangles in world space, one array for them all: each triangle's object (index into `objects`) and
    face; each object's vertices apart, so no part joins two objects."""
    objects: list
    positions: np.ndarray   # (P, 3)
    triangles: np.ndarray   # (T, 3) into positions
    owner: np.ndarray       # (T,)
    face: np.ndarray        # (T,) the face of its object's mesh

    @staticmethod
    def of(objects) -> "Meshes":
        positions, triangles, owner, faces, offset = [], [], [], [], 0
        for index, ob in enumerate(objects):
            mesh = ob.data
            local = mesh_positions(mesh)
            matrix = np.array(ob.matrix_world, dtype=np.float64)
            triangles.append(mesh_triangles(mesh).astype(np.int64) + offset)
            face = np.empty(len(mesh.loop_triangles), dtype=np.int64)
            mesh.loop_triangles.foreach_get("polygon_index", face)
            positions.append(local @ matrix[:3, :3].T + matrix[:3, 3])
            owner.append(np.full(len(face), index))
            faces.append(face)
            offset += len(local)
        empty = np.zeros((0, 3), dtype=np.int64)
        return Meshes(list(objects), np.concatenate(positions) if positions else np.zeros((0, 3)),
                      np.concatenate(triangles) if triangles else empty,
                      np.concatenate(owner) if owner else np.zeros(0, dtype=np.int64),
                      np.concatenate(faces) if faces else np.zeros(0, dtype=np.int64))

    def faces_of(self, index: int, triangles) -> np.ndarray:
        """The faces of object `index` among `triangles` (indices into self.triangles), each once."""
        triangles = np.asarray(triangles, dtype=np.int64)
        return np.unique(self.face[triangles[self.owner[triangles] == index]])


def fault_faces(ob, fault: str, others=()) -> np.ndarray:
    """The faces of `ob`'s mesh at `fault` (one of FAULTS); crossing and inside are judged against `ob`'s other
    parts and the `others` objects too."""
    mesh = ob.data
    if fault == AGAINST:
        loops = mesh_triangles(mesh, of="loops").astype(np.int64)
        face = np.empty(len(loops), dtype=np.int64)
        mesh.loop_triangles.foreach_get("polygon_index", face)
        face_normals = corners.first_triangle_normals(mesh_positions(mesh)[mesh_corner_vertices(mesh)], loops)
        against = corners.against_faces(mesh_corner_normals(mesh), face_normals)
        corner_face = np.zeros(len(mesh.loops), dtype=np.int64)
        corner_face[loops.ravel()] = np.repeat(face, 3)
        return np.unique(corner_face[against])
    meshes = Meshes.of([ob, *[other for other in others if other is not ob]])
    if fault == THIN:
        degenerate, sliver = mesh_faults.thin_triangles(meshes.positions, meshes.triangles)
        return meshes.faces_of(0, np.flatnonzero(degenerate | sliver))
    parts = mesh_faults.parts_of(meshes.triangles, len(meshes.positions))
    if fault == CROSSING:
        return meshes.faces_of(0, mesh_faults.crossing_pairs(meshes.positions, meshes.triangles, parts).ravel())
    if fault == INSIDE:
        inner = mesh_faults.inside_parts(meshes.positions, meshes.triangles, parts)[:, 0]
        return meshes.faces_of(0, np.flatnonzero(np.isin(parts, inner)))
    raise ValueError(f"no fault {fault!r}: the faults are {', '.join(FAULTS)}")


def fault_checks(receivers, others) -> list[Check]:
    """A warning per receiver and fault found, with its count and the faces to select; crossing and inside are
    judged over the receivers and the `others` (the other visible meshes) together."""
    meshes = Meshes.of([*receivers, *others])
    degenerate, sliver = mesh_faults.thin_triangles(meshes.positions, meshes.triangles)
    parts = mesh_faults.parts_of(meshes.triangles, len(meshes.positions))
    crossing = mesh_faults.crossing_pairs(meshes.positions, meshes.triangles, parts)
    inner = mesh_faults.inside_parts(meshes.positions, meshes.triangles, parts)
    found = []
    for index, ob in enumerate(receivers):
        name = repr(ob.name)
        against = len(fault_faces(ob, AGAINST))
        if against:
            found.append(Check(WARNING, name, f"{against} faces with corners whose custom normal points against the "
                                              f"face (wound the other way): those corners are black, as Cycles bakes "
                                              f"them; flip the faces or recalculate the normals", (ob.name, AGAINST)))
        zero, thin = (len(meshes.faces_of(index, np.flatnonzero(mask))) for mask in (degenerate, sliver))
        if zero or thin:
            found.append(Check(WARNING, name, f"{zero} zero-area and {thin} sliver faces (thinner than "
                                              f"{mesh_faults.SLIVER_RATIO:g} of their longest edge): no normal or a "
                                              f"wild one, where Cycles' answer follows its rounding (Mesh > Clean Up "
                                              f"> Degenerate Dissolve)", (ob.name, THIN)))
        crossed = meshes.faces_of(index, crossing.ravel())
        if len(crossed):
            owners = meshes.owner[crossing]
            mine = (owners == index).any(axis=1)
            partners = set(owners[mine].ravel().tolist()) - {index}
            what = ["another of its parts"] * bool((owners[mine] == index).all(axis=1).any()) + [
                repr(meshes.objects[owner].name) for owner in sorted(partners)]
            found.append(Check(WARNING, name, f"{len(crossed)} faces cross {' and '.join(what)}: rays start inside "
                                              f"the other surface there, and the bake decides by rule",
                                              (ob.name, CROSSING)))
        inside = meshes.faces_of(index, np.flatnonzero(np.isin(parts, inner[:, 0])))
        if len(inside):
            found.append(Check(WARNING, name, f"{len(inside)} faces of parts inside another closed part: no light "
                                              f"reaches them, and they are black", (ob.name, INSIDE)))
    return found
