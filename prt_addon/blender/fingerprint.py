"""Each receiver's fingerprint (core.fingerprint) gathered from the scene: what its stored transfer depends on, in
parts, so a check can say what changed and Bake Stale rebakes only the objects whose fingerprint did.

- geometry: the evaluated mesh (modifiers applied) in object space: positions, corner normals, each corner's
  vertex and the triangles' corners.
- transform: matrix_world; nothing for a dynamic object, whose transfer turns with it.
- occluders (shadowed and interreflected bakes): the world-space triangles of every other visible mesh instance but
  the dynamic ones, as one set (none for a dynamic object: it is its own occluder, in its geometry). Any of them
  may shadow the object, so moving one makes every other receiver stale: the simplest rule that is never wrong.
  Interreflected bakes also read their world-space corner normals and albedo, since they reflect light onto the
  object.
- materials: what the object's own materials give the bake: subsurface settings (shadowed and interreflected) and
  albedo per face corner (interreflected).
- settings: the bake settings the mode reads and the stored layout's version (core.fingerprint.settings_values).
"""

from dataclasses import asdict

import numpy as np

from ..core import fingerprint as digests
from . import geometry, materials, storage, texel_bake
from .geometry import directions_to_world, points_to_world
from .mesh_arrays import mesh_corner_normals, mesh_corner_vertices, mesh_positions, mesh_triangles
from .occluders import shadow_caster

FINGERPRINT_KEY = "fingerprint"  # in the bake's metadata: part → hex digest


def fingerprints(depsgraph, objects, settings, storage_options=None) -> dict[str, dict[str, str]]:
    """Each mesh object's fingerprint under these bake settings (and storage options overriding the objects'
    own, as a bake's), by name."""
    casters = _caster_digests(depsgraph, settings.mode == "interreflected") if settings.mode != "unshadowed" else []
    return {ob.name: {
        "geometry": _geometry_digest(ob, depsgraph),
        "transform": digests.array_digest(np.zeros(0) if geometry.is_dynamic(ob) else np.array(ob.matrix_world)),
        "occluders": digests.set_digest(() if geometry.is_dynamic(ob) else
                                        (digest for owner, digest in casters if owner != ob.name)),
        "materials": _materials_digest(ob, depsgraph, settings.mode),
        "settings": _settings_digest(ob, settings, storage_options or {}),
    } for ob in objects}


def _settings_digest(ob, settings, storage_options) -> str:
    """The settings part: the bake's settings, and the object's storage where it is not per vertex (so vertex
    bakes' digests stay those of files saved before objects had a storage choice, which stay up to date)."""
    values = digests.settings_values(settings)
    options = texel_bake.options_for(ob, storage_options)
    if options.storage != "vertex":
        values["storage"] = asdict(options)
    if geometry.is_dynamic(ob):
        values["dynamic"] = True
    return digests.values_digest(values)


def what_changed(ob, current: dict) -> list[str]:
    """What changed since the object's stored bake, in words; [] when it is up to date."""
    meta = ob.data.get(storage.METADATA_KEY)
    if meta is None:
        return ["not baked"]
    stored = meta.get(FINGERPRINT_KEY)
    if stored is None:
        return ["baked without a fingerprint"]
    return digests.changes(stored.to_dict(), current)


def stale_receivers(context, settings, names=None) -> dict[str, list[str]]:
    """The receivers a bake would choose (named, else selected, else visible meshes), each with what changed since
    its bake under these settings ([]: up to date)."""
    context.view_layer.update()
    candidates = geometry.receivers_from_selection(context, names)
    meshes = [ob for ob in candidates if ob.type == "MESH"]
    current = fingerprints(context.evaluated_depsgraph_get(), meshes, settings)
    return {ob.name: what_changed(ob, current[ob.name]) if ob.type == "MESH" else ["not a mesh"]
            for ob in candidates}


def stale_line(changed: dict[str, list[str]]) -> str:
    """One line: what Bake Stale rebakes and why, or that everything is up to date."""
    stale = {name: words for name, words in changed.items() if words}
    if not stale:
        return f"PRT bake stale: nothing to rebake, {len(changed)} objects up to date"
    listed = "; ".join(f"{name} ({', '.join(words)})" for name, words in stale.items())
    return f"PRT bake stale: rebaking {len(stale)} of {len(changed)} objects: {listed}"


def _geometry_digest(ob, depsgraph) -> str:
    evaluated = ob.evaluated_get(depsgraph)
    mesh = evaluated.to_mesh()
    try:
        return digests.array_digest(mesh_positions(mesh), mesh_corner_normals(mesh), mesh_corner_vertices(mesh),
                                    mesh_triangles(mesh, of="loops"))
    finally:
        evaluated.to_mesh_clear()


def _materials_digest(ob, depsgraph, mode: str) -> str:
    if mode == "unshadowed":
        return digests.array_digest()
    subsurface = materials.subsurface_material(ob)
    arrays = [np.hstack(subsurface) if subsurface is not None else np.zeros(0)]
    if mode == "interreflected":
        evaluated = ob.evaluated_get(depsgraph)
        try:
            arrays.append(_corner_albedo(ob, evaluated.to_mesh()))
        finally:
            evaluated.to_mesh_clear()
    return digests.array_digest(*arrays)


def _caster_digests(depsgraph, bouncing: bool) -> list[tuple[str, str]]:
    """(the object's name, or "" for an instance; digest of its world-space triangles, and with `bouncing` its
    world-space corner normals and corner albedo) for every visible mesh instance, as occluders.py gathers them.
    Each mesh is read once."""
    found, meshes = [], {}
    for instance in depsgraph.object_instances:
        owner = shadow_caster(instance)
        if owner is None:
            continue
        ob = instance.object
        key = ob.original.name, instance.is_instance
        if key not in meshes:
            mesh = ob.to_mesh()
            try:
                meshes[key] = (mesh_positions(mesh), mesh_triangles(mesh),
                               (mesh_corner_normals(mesh), _corner_albedo(ob.original, mesh)) if bouncing else None)
            finally:
                ob.to_mesh_clear()
        positions, triangles, reflecting = meshes[key]
        arrays = [points_to_world(instance.matrix_world, positions), triangles]
        if reflecting is not None:
            normals, albedo = reflecting
            arrays += [directions_to_world(instance.matrix_world, normals), albedo]
        found.append(("" if instance.is_instance else owner.name, digests.array_digest(*arrays)))
    return found


def _corner_albedo(ob, mesh) -> np.ndarray:
    """(C, 3) the albedo the bake's one rule gives each face corner (notes are the bake's to make)."""
    corners = len(mesh.loops)
    return materials.vertex_albedo(ob, mesh, [], np.arange(corners), corners)
