"""Persistent handlers that keep the PRT colours and display materials current as lights change.

depsgraph_update_post refreshes only for light-relevant updates: the scene (where the lights and switches live),
a World (the default environment), a linked Sun's object or light data, and meshes whose bake changed since it was
last read. Its own writes change none of these, so they are filtered out. frame_change_post always refreshes:
animated and driven settings change with the frame. A refresh is cheap when little changed: lights that did not
move come from the cache, and a mesh is shaded again only when its light or its bake changed.
No bpy.ops here: handlers run inside Blender's evaluation.
"""

import math

import bpy
from bpy.app.handlers import persistent

from .. import display, mesh_data
from ..core import lights
from .lights import scene_lights

_light_cache = lights.LightCache()
_transfers = {}  # mesh name → (bake key, (V, n²) float32 transfer, None for a stale bake)
_shaded = {}  # mesh name → (bake key, light bytes) of the colours it holds
_reported = set()  # stale-bake messages already printed
_busy = False  # re-entrancy guard: nothing a refresh does may start another one


@persistent
def on_depsgraph_update(scene, depsgraph):
    if not _busy and _light_relevant(scene, depsgraph):
        refresh(scene, depsgraph)


@persistent
def on_frame_change(scene, depsgraph):
    if not _busy:
        refresh(scene, depsgraph)


@persistent
def on_load_post(_filepath):
    forget()


def forget():
    """Caches are by name: a newly loaded file starts afresh."""
    global _light_cache
    _light_cache = lights.LightCache()
    for cache in (_transfers, _shaded, _reported):
        cache.clear()


def refresh(scene, depsgraph):
    """Brings colours and display materials up to date with the scene's SH lights and switches.

    Settings are read from the evaluated scene, so animated and driven values are those of the depsgraph's
    frame, also while rendering; the original meshes and objects are written."""
    global _busy
    _busy = True
    try:
        settings = depsgraph.scene_eval
        in_use = settings.prt_lights or settings.prt_display.show_prt  # else no transfer is read, no colour written
        receivers = list(_receivers(scene)) if in_use else []
        if settings.prt_lights:
            _shade(receivers, settings)
        _sync_display(scene, receivers, settings.prt_display)
    finally:
        _busy = False


def _light_relevant(scene, depsgraph) -> bool:
    linked = {light.sun_object for light in scene.prt_lights if light.sun_object is not None}
    followed = {ob.name_full for ob in linked} | {ob.data.name_full for ob in linked}
    for update in depsgraph.updates:
        datablock = update.id.original
        kind = datablock.id_type
        if kind in {"SCENE", "WORLD"} or datablock.name_full in followed and kind in {"OBJECT", "LIGHT"}:
            return True
        mesh = datablock if kind == "MESH" else datablock.data if kind == "OBJECT" else None
        if isinstance(mesh, bpy.types.Mesh) and _bake_changed(mesh):
            return True
    return False


def _bake_key(mesh):
    """What identifies a bake: its unique id, and the vertex counts then and now."""
    meta = mesh.get(mesh_data.METADATA_KEY)
    if meta is None:
        return None
    return meta.get("bake_id"), meta.get("vertex_count"), len(mesh.vertices)


def _bake_changed(mesh) -> bool:
    return _transfers.get(mesh.name_full, (None,))[0] != _bake_key(mesh)


def _receivers(scene):
    """(object, transfer) for each mesh object of the scene with a usable bake."""
    for ob in scene.objects:
        if ob.type == "MESH" and not ob.data.is_editmode:
            transfer = _transfer(ob.data)
            if transfer is not None:
                yield ob, transfer


def _transfer(mesh):
    """The mesh's transfer, read once per bake; a stale bake is reported once and never applied."""
    key = _bake_key(mesh)
    if key is None:
        _transfers.pop(mesh.name_full, None)
        return None
    cached = _transfers.get(mesh.name_full)
    if cached is not None and cached[0] == key:
        return cached[1]
    try:
        transfer, _ = mesh_data.read_transfer(mesh)
    except mesh_data.StaleBake as problem:
        transfer = None
        _report_once(f"PRT: not relighting: {problem}")
    _transfers[mesh.name_full] = (key, transfer)
    return transfer


def _report_once(message):
    if message not in _reported:
        _reported.add(message)
        print(message)


def _shade(receivers, settings):
    """Sums the lights once per SH order, then writes the colours of each mesh whose light or bake changed."""
    orders = {math.isqrt(transfer.shape[-1]) for _, transfer in receivers}
    for entry in settings.prt_lights:
        if entry.use and entry.kind == "ENVIRONMENT" and entry.environment_image(settings) is None:
            _report_once(f"PRT: SH light {entry.name!r} has no readable image (missing file?); it does not shine")
    totals = _light_cache.totals(scene_lights(settings), orders, settings.prt_display.window)
    for ob, transfer in receivers:
        light = totals[math.isqrt(transfer.shape[-1])]
        state = (_bake_key(ob.data), light.tobytes())
        if _shaded.get(ob.data.name_full) != state:
            display.write_display_colours(ob.data, transfer, light)
            _shaded[ob.data.name_full] = state


def _sync_display(scene, receivers, settings):
    """Display materials on the receivers while the PRT display is on; everything else shows its own."""
    shown = {ob.name_full for ob, _ in receivers} if settings.show_prt else set()
    for ob in scene.objects:
        if ob.name_full in shown:
            display.show(ob)
        elif display.is_shown(ob) and ob.mode != "EDIT":  # an object being edited keeps what it shows
            display.restore(ob)
    display.set_albedo(settings.use_albedo)


HANDLERS = (
    (bpy.app.handlers.depsgraph_update_post, on_depsgraph_update),
    (bpy.app.handlers.frame_change_post, on_frame_change),
    (bpy.app.handlers.load_post, on_load_post),
)


def register():
    for handlers, function in HANDLERS:
        if function not in handlers:
            handlers.append(function)


def unregister():
    for handlers, function in HANDLERS:
        if function in handlers:
            handlers.remove(function)
    display.restore_all()
    forget()
