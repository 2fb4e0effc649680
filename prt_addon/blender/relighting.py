"""The relighting engine: keeps each baked mesh's PRT colours and the display materials current with the scene's
SH lights and display switches.

One `Relighter` holds what makes a refresh cheap: the lights' projections (a light that did not move comes from
the cache), each mesh's transfer read once per bake, and which light each mesh's colours were written for (a mesh
is shaded again only when its light or its bake changed). The relighting handlers (blender.handlers) own one and
call it; a command may use its own. Its own writes change nothing it watches, and a refresh never starts another.
"""

from contextlib import contextmanager
import math

import bpy
import numpy as np

from ..core import lights as core_lights
from ..core import probe_grid, rotation, sh, shading
from ..core import settings as spec
from ..core.errors import StaleBake
from . import display, heatmaps, layouts, probe_volumes, storage
from .fingerprint import placement_changes
from .lights import environment_image, scene_lights, sync_sun_lamps
from .texel_bake import OBJECT_PREFIX


PAUSED_KEY = "_prt_relighting_paused"  # on a scene while a reference renders it: the display leaves it alone


@contextmanager
def paused(scene):
    """No refresh touches the scene within: Cycles renders it as a reference, with its own world, materials and
    lamps, which the display would otherwise take for its own (wrap the world, show a hidden lamp)."""
    scene[PAUSED_KEY] = True
    try:
        yield
    finally:
        del scene[PAUSED_KEY]


class Relighter:
    def __init__(self):
        self.forget()
        self.busy = False  # re-entrancy guard: nothing a refresh does may start another one

    def forget(self):
        """Caches are by name: a newly loaded file starts afresh."""
        self._light_cache = core_lights.LightCache()
        # mesh name → (bake key, layouts.Shading, or None for a stale bake)
        self._transfers = {}
        self._shaded = {}     # mesh name → (bake key, light bytes) or a heatmap's state: the colours it holds
        self._volumes = {}    # probe volume name → (bake id, blender.probe_volumes.StoredProbes or None if stale)
        self._positions = {}  # mesh name → (bake key, its shading points in its frame): a dynamic one's, per vertex
        self._reported = set()  # messages already printed
        self.legend = None  # heatmaps.Legend of the last heatmap painted, for the panel
        self.auto_window = {}  # order → (strength, negative share left) of the last shading's Auto window

    def refresh(self, scene, depsgraph):
        """Brings colours and display materials up to date with the scene's SH lights and switches.

        Settings are read from the evaluated scene, so animated and driven values are those of the depsgraph's
        frame, also while rendering; the original meshes and objects are written."""
        if self.busy or scene.get(PAUSED_KEY):
            return
        self.busy = True
        try:
            settings = depsgraph.scene_eval
            mode = settings.prt_display.mode
            # without lights, the display or a heatmap nothing is read or written
            in_use = settings.prt_lights or settings.prt_display.show_prt or mode != heatmaps.SHADED
            receivers = list(self._receivers(scene)) if in_use else []
            if mode != heatmaps.SHADED:
                self._paint_heatmaps(receivers, mode)
            elif settings.prt_lights:
                sync_sun_lamps(settings, create=False)  # a split-off sun's lamp turns with its environment
                self._shade(scene, receivers, settings, depsgraph)
            for lost in _sync_display(scene, receivers, settings.prt_display):
                self._report_once(f"PRT: {lost}")
        finally:
            self.busy = False

    def light_relevant(self, scene, depsgraph) -> bool:
        """Whether a depsgraph update may change what is shown: the scene (lights, switches), a World, a followed
        Sun's object or light data, or a mesh whose bake changed since it was read."""
        linked = {entry.sun_object for entry in scene.prt_lights if entry.sun_object is not None}
        followed = {ob.name_full for ob in linked} | {ob.data.name_full for ob in linked}
        for update in depsgraph.updates:
            datablock = update.id.original
            kind = datablock.id_type
            if kind in {"SCENE", "WORLD"} or datablock.name_full in followed and kind in {"OBJECT", "LIGHT"}:
                return True
            mesh = datablock if kind == "MESH" else datablock.data if kind == "OBJECT" else None
            if isinstance(mesh, bpy.types.Mesh) and self._bake_changed(mesh):
                return True
            if kind == "OBJECT" and update.is_updated_transform and isinstance(mesh, bpy.types.Mesh) \
                    and is_dynamic(mesh):
                return True  # a dynamic object moved: its light may turn into its frame
            if kind == "OBJECT" and probe_volumes.is_probe_volume(datablock) \
                    and self._volumes.get(datablock.name_full, (None,))[0] != probe_volumes.bake_id(datablock):
                return True  # a probe volume was baked
        return False

    def _bake_changed(self, mesh) -> bool:
        return self._transfers.get(mesh.name_full, (None,))[0] != _bake_key(mesh)

    def _receivers(self, scene):
        """(object, layouts.Shading) for each mesh object of the scene with a usable bake."""
        for ob in scene.objects:
            if ob.type == "MESH" and not ob.data.is_editmode:
                baked = self._transfer(ob.data)
                if baked is not None:
                    yield ob, baked

    def _transfer(self, mesh):
        """The mesh's transfer as its layout stores it, read once per bake; a stale bake is reported once and never
        applied."""
        key = _bake_key(mesh)
        if key is None:
            self._transfers.pop(mesh.name_full, None)
            return None
        cached = self._transfers.get(mesh.name_full)
        if cached is not None and cached[0] == key:
            return cached[1]
        try:
            baked = layouts.stored(mesh).read(mesh)
        except StaleBake as problem:
            baked = None
            self._report_once(f"PRT: not relighting: {problem}")
        self._transfers[mesh.name_full] = (key, baked)
        return baked

    def _report_once(self, message):
        if message not in self._reported:
            self._reported.add(message)
            print(message)

    def probes(self, scene) -> list:
        """The scene's baked probe volumes (blender.probe_volumes.StoredProbes), each read once per bake; one whose
        stored layout does not fit is reported once and never applied.

        A volume moved, scaled or given another resolution since its bake still lights, from its probes where they
        were baked (their placement is stored), and says so once: those probes are as right there as they were,
        while leaving them out would light the objects inside by the distant light, without the scene's shadows.
        A receiver's stale bake is shown too; whether the static scene changed since, Check tells (it reads every
        mesh: too slow for every update)."""
        found = []
        for ob in scene.objects:
            key = probe_volumes.bake_id(ob) if probe_volumes.is_probe_volume(ob) else None
            if key is None:
                continue
            if self._volumes.get(ob.name_full, (None,))[0] != key:
                try:
                    self._volumes[ob.name_full] = (key, probe_volumes.read(ob))
                except StaleBake as problem:
                    self._volumes[ob.name_full] = (key, None)
                    self._report_once(f"PRT: not lighting from probes: {problem}")
            if self._volumes[ob.name_full][1] is not None:
                found.append(self._volumes[ob.name_full][1])
                moved = placement_changes(ob)
                if moved:
                    self._report_once(f"PRT: probe volume {ob.name!r}: {', '.join(moved)} since its bake; lighting "
                                      f"from its probes where they were baked until Bake Stale rebakes it")
        return found

    def _shade(self, scene, receivers, settings, depsgraph):
        """Sums the lights once per SH order, then writes the colours of each mesh whose light or bake changed."""
        orders = {light_order_of(ob.data) for ob, _ in receivers}
        for entry in settings.prt_lights:
            if entry.use and entry.kind == "ENVIRONMENT" and environment_image(entry, settings) is None:
                self._report_once(f"PRT: SH light {entry.name!r} has no readable image (missing file?); "
                                  f"it does not shine")
        totals = self._light_cache.totals(scene_lights(settings), orders, settings.prt_display.window)
        self.auto_window = ({order: (self._light_cache.auto_strengths[order], core_lights.negative_share(totals[order]))
                             for order in orders} if settings.prt_display.window == "auto" else {})
        self._write_colours(scene, receivers, totals, depsgraph)

    def shade_all(self, scene, totals: dict):
        """Shades every baked mesh of the scene under the given light ({order: (3, order²)}), whatever its SH
        lights: validation shows the light it gives Cycles."""
        self._write_colours(scene, list(self._receivers(scene)), totals)

    def _write_colours(self, scene, receivers, totals, depsgraph=None):
        """The colours of each mesh whose light, placement (a dynamic one) or bake changed: a dynamic object's
        dynamic_radiance where it is lit per vertex, else under its displayed_light."""
        probes = self.probes(scene) if any(is_dynamic(ob.data) for ob, _ in receivers) else []
        for ob, baked in receivers:
            light = totals[light_order_of(ob.data)]
            state = (_bake_key(ob.data), light.tobytes())
            radiance = None
            if is_dynamic(ob.data):
                placed = ob.evaluated_get(depsgraph) if depsgraph is not None else ob
                state += (np.array(placed.matrix_world).tobytes(), probe_light_of(ob),
                          tuple(found.bake_id for found in probes))
                if self._shaded.get(ob.data.name_full) == state:
                    continue
                radiance = dynamic_radiance(ob, placed, baked, self._points(ob.data, baked), light, probes)
            elif self._shaded.get(ob.data.name_full) == state:
                continue
            if radiance is not None:
                baked.layout.shade_points(ob.data, baked, radiance)
            else:
                baked.layout.shade(ob.data, baked, displayed_light(ob, light, probes, depsgraph))
            self._shaded[ob.data.name_full] = state

    def _points(self, mesh, baked):
        """Its shading points' positions in its own frame (layouts), read once per bake; None for texels."""
        key = _bake_key(mesh)
        if self._positions.get(mesh.name_full, (None,))[0] != key:
            self._positions[mesh.name_full] = (key, baked.layout.points(mesh, baked))
        return self._positions[mesh.name_full][1]

    def _paint_heatmaps(self, receivers, mode):
        """Heatmap colours on one scale; a mesh is painted again only when its values, its bake or the scale
        changed (the state differs from any shaded one, so going back to Shaded shades again)."""
        found = heatmaps.read([ob for ob, _ in receivers], mode)
        self.legend = heatmaps.legend(found, mode)
        for ob, _ in receivers:
            rows = found[ob.name_full]
            state = (mode, self.legend.top, _bake_key(ob.data), None if rows is None else hash(rows[0].tobytes()))
            if self._shaded.get(ob.data.name_full) != state:
                heatmaps.paint(ob.data, rows, self.legend)
                self._shaded[ob.data.name_full] = state


def is_dynamic(mesh) -> bool:
    """Whether the mesh's bake is a dynamic object's, its transfer in the object's own frame."""
    meta = mesh.get(storage.METADATA_KEY)
    return bool(meta is not None and meta.get(storage.DYNAMIC_KEY, False))


def light_order_of(mesh) -> int:
    """The order of the distant light the mesh's bake is shaded under (blender.storage.light_order)."""
    return storage.light_order(mesh[storage.METADATA_KEY])


def displayed_light(ob, light, probes=(), depsgraph=None) -> np.ndarray:
    """The SH light the display shades the object's transfer with: the distant light, or a dynamic object's
    dynamic_light as the depsgraph places it (else as it is now), of `probes` (Relighter.probes). Validation shades
    with it too."""
    if not is_dynamic(ob.data):
        return light
    return dynamic_light(probes, ob.evaluated_get(depsgraph) if depsgraph is not None else ob, light)


def dynamic_light(probes: list, ob, light) -> np.ndarray:
    """(3, N²) the light a dynamic object placed as `ob` is shaded with at its centre, in its own frame, to its
    transfer's order N: what arrives at the centre of its bounding box from the distant `light` (3, n²) through the
    probe volumes (blender.probe_volumes.StoredProbes) that hold it, else the distant light itself. Lit per vertex,
    it is shaded from its dynamic_radiance instead."""
    arriving = probe_volumes.light_at(probes, bounds_centre(ob), light) if probes else None
    size = ob.data[storage.METADATA_KEY]["order"] ** 2
    return light_in_frame(sh.fitted(light if arriving is None else arriving, size), ob.matrix_world)


def probe_light_of(ob) -> str:
    """Where a dynamic object takes the probes' light (core.settings.PROBE_LIGHT): "vertex" or "centre"."""
    return getattr(ob, OBJECT_PREFIX + spec.PROBE_LIGHT.name, spec.PROBE_LIGHT.default)


def dynamic_radiance(ob, placed, baked, points, light, probes) -> np.ndarray | None:
    """(P, 3) the radiance of a dynamic object lit per vertex (core.settings.PROBE_LIGHT), placed as `placed` is,
    under the distant light (3, n²) in world space (n its light_order_of), from the baked probe volumes `probes`
    (blender.probe_volumes.StoredProbes); `points` (P, 3): its shading points in its own frame (layouts). None where
    it is lit at its centre (dynamic_light): by its setting, as a texel bake (no points), or without probes of the
    light's order.

    Each point is shaded from the light arriving at it, Σ w_p T_p L, turned into the object's frame; the lights T_p L
    of the probes around the object come at most once per light change (probe_volumes.lights) and are turned before
    they are blended (a rotation is linear), those the points reach only, so a point costs its share of one product
    per cell (core.probe_grid.shade_points). A point outside every volume gets the distant light. Lights are fitted
    to the transfer's order (core.sh.fitted)."""
    probes = [found for found in probes if found.order ** 2 == light.shape[-1]]
    if points is None or probe_light_of(ob) != "vertex" or not probes:
        return None
    which, local = probe_volumes.containing(probes, points, np.array(placed.matrix_world, dtype=np.float64))
    turn = np.array(placed.matrix_world.to_quaternion().to_matrix(), dtype=np.float64).T
    size = baked.transfer.shape[-1]
    through = np.flatnonzero(np.bincount(which + 1, minlength=len(probes) + 1)) - 1
    radiance = np.empty((len(points), 3), dtype=np.float32)
    for index in through:  # −1: outside every volume
        rows = None if len(through) == 1 else np.flatnonzero(which == index)  # the usual case: one volume, no copies
        if index < 0:
            transfer = baked.transfer if rows is None else np.take(baked.transfer, rows, axis=0)
            found = shading.shade(transfer, rotation.rotate(sh.fitted(light, size), turn))
        else:
            mine = local if rows is None else local[rows]
            indices, weights = probe_grid.trilinear_weights(mine, probes[index].resolution, probes[index].valid)
            # The lights of the probes around the object only; fitted, then turned by shade_points on those the
            # points reach: a rotation of SH is block-diagonal by band, so cutting or padding bands before it or
            # after it is the same.
            needed = probe_grid.probes_spanned(mine, probes[index].resolution)
            arriving = sh.fitted(probe_volumes.lights(probes[index], light, needed), size)  # (P, 3, N²)
            found = probe_grid.shade_points(baked.transfer, arriving, indices, weights,
                                            rotation.sh_matrix(math.isqrt(size), turn), rows)
        if rows is None:
            return found
        radiance[rows] = found
    return radiance


def light_in_frame(light, matrix_world) -> np.ndarray:
    """SH light (..., n²) in world space as an object placed by `matrix_world` sees it in its own frame:
    L_object(ω) = L(R·ω), R the matrix's rotation (translation and uniform scale change nothing)."""
    turn = np.array(matrix_world.to_quaternion().to_matrix(), dtype=np.float64)
    return rotation.rotate(light, turn.T)


def bounds_centre(ob) -> np.ndarray:
    """(3,) the centre of the object's bounding box in world space: where a dynamic object takes its probes' light."""
    corners = np.array([corner[:] for corner in ob.bound_box], dtype=np.float64)
    matrix = np.array(ob.matrix_world, dtype=np.float64)
    return matrix[:3, :3] @ corners.mean(axis=0) + matrix[:3, 3]


def _bake_key(mesh):
    """What identifies a bake: its unique id, the vertex counts then and now, and the corner count now."""
    meta = mesh.get(storage.METADATA_KEY)
    if meta is None:
        return None
    return meta.get("bake_id"), meta.get("vertex_count"), len(mesh.vertices), len(mesh.loops)


def _sync_display(scene, receivers, settings) -> list:
    """Display materials on the receivers while the PRT display is on; everything else shows its own. Returns the
    notes on originals that could not be put back (display.restore)."""
    shown = {ob.name_full: baked.layout for ob, baked in receivers} if settings.show_prt else {}
    lost = []
    for ob in scene.objects:
        if ob.name_full in shown:
            display.show(ob, shown[ob.name_full].display_source(ob.data))
        elif display.is_shown(ob) and ob.mode != "EDIT":  # an object being edited keeps what it shows
            lost.append(display.restore(ob))
    display.set_albedo(settings.use_albedo and settings.mode == heatmaps.SHADED)  # a heatmap shows as it is
    lamps = any(entry.sun_lamp is not None and not entry.sun_lamp.hide_render for entry in scene.prt_lights)
    display.set_lamp_light(scene, settings.show_prt and settings.mode == heatmaps.SHADED and lamps)
    return [note for note in lost if note is not None]
