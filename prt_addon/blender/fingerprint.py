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

A probe volume's fingerprint (volume_fingerprints) has its own parts (core.fingerprint.PROBE_CHANGES): transform
(its placement: the cube's matrix, display size included), resolution, occluders (every visible mesh instance but
the dynamic ones, as one set, taken as a receiver's occluders are: its probes see them all) and settings
(core.fingerprint.probe_settings_values and the probes' stored layout). A dynamic object is in none of them: the
probes are baked without it, so it moves freely through them.
"""

from dataclasses import asdict

import numpy as np

from ..core import fingerprint as digests
from . import geometry, materials, probe_volumes, storage, texel_bake
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


def volume_fingerprints(depsgraph, volumes, settings) -> dict[str, dict[str, str]]:
    """Each probe volume's fingerprint (blender.probe_volumes.VolumeInput) under these bake settings, by name."""
    if not volumes:
        return {}
    bouncing = settings.mode == "interreflected"
    casters = digests.set_digest(digest for _, digest in _caster_digests(depsgraph, bouncing))
    values = digests.values_digest(digests.probe_settings_values(settings) | {"layout": probe_volumes.PROBE_LAYOUT})
    return {volume.name: {**_placement_parts(volume), "occluders": casters, "settings": values} for volume in volumes}


def _placement_parts(volume) -> dict[str, str]:
    return {"transform": digests.array_digest(volume.matrix),
            "resolution": digests.array_digest(np.array(volume.resolution))}


def placement_changes(ob) -> list[str]:
    """What of a baked probe volume's placement changed since its bake (moved or scaled, resolution changed), in
    words: the parts of its fingerprint cheap enough for every redraw and display update (the static scene's part
    reads every mesh: Check computes it). [] for a volume without a fingerprinted bake."""
    meta = ob.get(probe_volumes.METADATA_KEY)
    stored = None if meta is None else meta.get(FINGERPRINT_KEY)
    if stored is None:
        return []
    current = _placement_parts(probe_volumes.volume_input(ob))
    return [words for part, words in digests.PROBE_CHANGES.items()
            if part in current and stored.get(part) != current[part]]


def what_changed(ob, current: dict) -> list[str]:
    """What changed since the object's stored bake (a mesh's, or a probe volume's probes), in words; [] when it is
    up to date."""
    volume = probe_volumes.is_probe_volume(ob)
    meta = ob.get(probe_volumes.METADATA_KEY) if volume else ob.data.get(storage.METADATA_KEY)
    if meta is None:
        return ["not baked"]
    stored = meta.get(FINGERPRINT_KEY)
    if stored is None:
        return ["baked without a fingerprint"]
    return digests.changes(stored.to_dict(), current, digests.PROBE_CHANGES if volume else digests.CHANGES)


def stale_receivers(context, settings, names=None) -> dict[str, list[str]]:
    """The receivers a bake would choose (named, else selected, else visible meshes), each with what changed since
    its bake under these settings ([]: up to date)."""
    context.view_layer.update()
    candidates = geometry.receivers_from_selection(context, names)
    meshes = [ob for ob in candidates if ob.type == "MESH"]
    current = fingerprints(context.evaluated_depsgraph_get(), meshes, settings)
    return {ob.name: what_changed(ob, current[ob.name]) if ob.type == "MESH" else ["not a mesh"]
            for ob in candidates}


def stale_volumes(context, settings) -> dict[str, list[str]]:
    """The probe volumes a bake under these settings would bake (the visible ones; none for an unshadowed bake,
    which leaves them as they were), each with what changed since its bake ([]: up to date)."""
    if settings.mode == "unshadowed":
        return {}
    context.view_layer.update()
    volumes = probe_volumes.volumes_to_bake(context, [])
    current = volume_fingerprints(context.evaluated_depsgraph_get(), volumes, settings)
    return {volume.name: what_changed(context.scene.objects[volume.name], current[volume.name]) for volume in volumes}


def stale_line(changed: dict[str, list[str]], volumes: dict[str, list[str]] | None = None) -> str:
    """One line: what Bake Stale rebakes and why (receivers, then probe volumes: stale_volumes), or that everything
    is up to date."""
    counted = [(changed, "objects")] + ([(volumes, "probe volumes")] if volumes else [])
    stale = {name: words for found, _ in counted for name, words in found.items() if words}
    if not stale:
        counts = " and ".join(f"{len(found)} {kind}" for found, kind in counted)
        return f"PRT bake stale: nothing to rebake, {counts} up to date"
    listed = "; ".join(f"{name} ({', '.join(words)})" for name, words in stale.items())
    shares = " and ".join(f"{sum(1 for words in found.values() if words)} of {len(found)} {kind}"
                          for found, kind in counted)
    return f"PRT bake stale: rebaking {shares}: {listed}"


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
