"""The first step of a bake: what it needs of the scene, read from Blender once, as plain values (dataclasses and
numpy arrays; objects by name). The plan, the execution and the checks read this, never the scene, so objects may
move while a modal bake runs; only storing writes, to the receivers named here.
"""

from dataclasses import dataclass, field, replace

import bpy

from ..core import bake, engines, probe_transfer
from ..core.errors import InputError
from ..core.progress import old_objects_frozen
from . import fingerprint, geometry, materials, probe_volumes, texel_bake
from .occluders import occluders_from_depsgraph


@dataclass
class ReceiverInput:
    """One object to bake and store."""
    name: str
    surface: geometry.Surface          # its evaluated surface in world space, per shading point
    vertices: int                      # its mesh's vertices
    options: texel_bake.TexelOptions   # its storage choice
    texels: texel_bake.TexelInput | None = None  # Storage Texel or Auto: its triangles and lightmap UV map
    subsurface: tuple | None = None    # materials.subsurface_material's (weight, mean free path, albedo, ior)


@dataclass
class BakeRequest:
    """A bake of these receivers under these settings, in a scene whose other visible meshes are `bouncers`
    (interreflected bakes: they reflect light onto the receivers) and whose occluders begin with the receivers'
    and bouncers' points, in that order."""
    settings: bake.BakeSettings
    receivers: list[ReceiverInput]
    bouncers: list = field(default_factory=list)   # blender.geometry.Surface
    occluders: bake.Occluders | None = None        # None: unshadowed, no rays
    fingerprints: dict = field(default_factory=dict)  # receiver → part → digest (blender.fingerprint)
    problems: list = field(default_factory=list)   # one sentence per object that will not be baked
    notes: list = field(default_factory=list)      # baked, but the user should know
    farm: bool = False                             # farm shards bake it (every receiver per vertex)
    ray_engine: str = ""                           # the engine its settings name, with its version, as reported
    dynamic: bool = False                          # its one receiver is dynamic: baked in its own frame, alone
    light_order: int = 0                           # a dynamic receiver's: the light's (its own, received_order)
    parts: list = field(default_factory=list)      # BakeRequest of each further dynamic receiver, baked after it
    probe_volumes: list = field(default_factory=list)  # blender.probe_volumes.VolumeInput: baked with the scene

    @property
    def names(self) -> list[str]:
        return [receiver.name for receiver in self.receivers]


@old_objects_frozen()  # reading makes many lists for Blender and numpy, as a job's steps do
def read_request(context, settings: bake.BakeSettings, object_names=None, storage_options=None,
                 farm: bool = False, casts: bool = True, volume_names=None) -> BakeRequest:
    """The bake of `object_names` (else the selected meshes, else every visible mesh) as the scene is now, its
    settings naming the ray engine that casts its rays here (core.engines.choose), which its occluders then carry.
    storage_options: texel_bake.TexelOptions fields that override every receiver's own (the command line's).
    `farm`: shards bake it and a merge stores it, so every receiver must be stored per vertex. `casts`: False for a
    merge of farm parts, whose engine (the parts') need not be installed here. `volume_names`: the probe volumes to
    bake (a stale-only bake's), which also makes `object_names` exactly the receivers, none where it is empty;
    None: every visible probe volume. Raises InputError, naming the problem, where nothing can be baked."""
    problems = settings.problems()
    if problems:
        raise InputError("; ".join(problems))
    engine, note = (settings.ray_engine, None) if not casts else engines.choose(settings.ray_engine)
    settings = replace(settings, ray_engine=engine)
    overrides = storage_options or {}
    context.view_layer.update()  # objects linked by scripts join the view layer only on update
    depsgraph = context.evaluated_depsgraph_get()
    request = BakeRequest(settings, [], farm=farm, ray_engine=ray_engine_label(engine) if casts else "")
    request.notes += [note] if note else []
    bouncing = settings.mode == "interreflected"
    objects, meshes = [], {}
    only_volumes = volume_names is not None and not object_names
    for ob in [] if only_volumes else geometry.receivers_from_selection(context, object_names):
        try:
            if ob.type == "MESH" and ob.data.name in meshes:
                raise InputError(
                    f"{ob.name!r} shares its mesh with {meshes[ob.data.name]!r}, and the bake depends on "
                    f"where each object is; make it single-user (Object > Relations) to bake both")
            surface = geometry.surface_from_object(ob, depsgraph, request.notes, albedo=bouncing,
                                                   own_frame=geometry.is_dynamic(ob))
            meshes[ob.data.name] = ob.name
        except InputError as problem:
            request.problems.append(str(problem))
            continue
        objects.append(ob)
        request.receivers.append(ReceiverInput(ob.name, surface, len(ob.data.vertices),
                                               texel_bake.options_for(ob, overrides)))
    if not request.receivers and not only_volumes:
        raise InputError("nothing to bake: " + ("; ".join(request.problems) or "no mesh objects"))
    if farm:  # before the occluders are gathered
        texel_bake.refuse_on_farm(objects, overrides)
        _refuse_dynamic_on_farm(objects)
    request.fingerprints = fingerprint.fingerprints(depsgraph, objects, settings, storage_options)
    everyone = request.receivers
    dynamic = [geometry.is_dynamic(ob) for ob in objects]
    request.receivers = [receiver for receiver, own in zip(everyone, dynamic) if not own]
    if request.receivers or volume_names:  # a stale-only bake's volumes are baked with the static scene
        _gather_scene(request, context, depsgraph)
        _gather_probe_volumes(request, context, depsgraph, volume_names)
    if not (request.receivers or request.probe_volumes or any(dynamic)):
        raise InputError("nothing to bake: " + ("; ".join(request.problems + request.notes)
                                                or "no visible probe volume"))
    for ob, receiver in zip(objects, everyone):
        if receiver.options.storage != "vertex":
            receiver.texels = texel_bake.texel_input(ob, receiver.surface, depsgraph, receiver.options)
        if settings.mode != "unshadowed":
            receiver.subsurface = materials.subsurface_material(ob)
    parts = [_alone(request, receiver) for receiver, own in zip(everyone, dynamic) if own]
    if not request.receivers and not request.probe_volumes:  # dynamic receivers only: the first, then the others
        return replace(parts[0], problems=request.problems, notes=request.notes, parts=parts[1:])
    request.parts = parts
    return request


def _gather_scene(request: BakeRequest, context, depsgraph):
    """The static receivers' bouncers and occluders: every visible mesh but the dynamic ones."""
    settings = request.settings
    if settings.mode == "interreflected":  # every visible mesh reflects light onto the receivers: solved too
        request.bouncers = _bouncing_surfaces(context, depsgraph, set(request.names), request.notes)
    if settings.mode != "unshadowed":
        solved = [receiver.surface for receiver in request.receivers] + request.bouncers
        request.occluders, sources = occluders_from_depsgraph(depsgraph, solved)
        request.occluders.engine = settings.ray_engine
        if sources <= set(request.names):
            request.notes.append("no visible mesh besides the receivers casts shadows; "
                                 "each receiver is shadowed by the receivers only")


def _gather_probe_volumes(request: BakeRequest, context, depsgraph, names=None):
    """The visible probe volumes (those `names`, else all), baked with the static scene's shadows, in this process
    (a farm's shards share out the receivers only), with their fingerprints."""
    volumes = [volume for volume in probe_volumes.volumes_to_bake(context, request.problems)
               if names is None or volume.name in names]
    if volumes and request.occluders is None:
        request.notes.append("probe volumes hold the scene's shadows: an unshadowed bake leaves them as they were")
    elif volumes and request.farm:
        request.notes.append("probe volumes bake on one machine: a farm bake leaves them as they were")
    else:
        request.probe_volumes = volumes
        current = fingerprint.volume_fingerprints(depsgraph, volumes, request.settings)
        for volume in volumes:
            volume.fingerprint = current[volume.name]


def _alone(request: BakeRequest, receiver: ReceiverInput) -> BakeRequest:
    """A dynamic receiver's own bake: its surface (in its own frame) is its only occluder and bouncer. Its transfer
    goes to the order of the light the probes carry to it (core.probe_transfer.received_order), lit by the scene's
    distant light of the bake's order."""
    order = request.settings.order
    alone = BakeRequest(replace(request.settings, order=probe_transfer.received_order(order)), [receiver],
                        ray_engine=request.ray_engine, dynamic=True, light_order=order,
                        fingerprints={receiver.name: request.fingerprints[receiver.name]})
    if request.settings.mode != "unshadowed":
        alone.occluders, _ = occluders_from_depsgraph(None, [receiver.surface])
        alone.occluders.engine = request.settings.ray_engine
    return alone


def _refuse_dynamic_on_farm(objects):
    chosen = [ob.name for ob in objects if geometry.is_dynamic(ob)]
    if chosen:
        raise InputError(f"{', '.join(map(repr, chosen))}: a dynamic object bakes on one machine, alone; farm "
                         f"shards bake the static scene: bake it without --shard or --dask")


def ray_engine_label(name: str) -> str:
    """The engine `name` as reports name it, with its version: BVHTree's is this Blender's."""
    return engines.label(name, f"Blender {bpy.app.version_string}")


def _bouncing_surfaces(context, depsgraph, receiver_names, notes) -> list:
    """The other visible meshes' surfaces, which only reflect light onto the receivers."""
    found = []
    for ob in geometry.visible_mesh_objects(context):
        if ob.name in receiver_names or geometry.is_dynamic(ob):
            continue
        try:
            found.append(geometry.surface_from_object(ob, depsgraph, notes, for_storage=False, albedo=True))
        except InputError as problem:
            notes.append(f"{problem}; it casts shadows but reflects no light")
    return found
