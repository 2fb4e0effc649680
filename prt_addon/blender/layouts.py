"""How a bake lies on a mesh, behind one protocol with an implementation per layout: per vertex (POINT), per face
corner (CORNER: some vertex is split by its corner normals) and per texel (TEXEL: float maps in a lightmap UV map).

Baking, each receiver's layout (chosen by its plan) gives the points the bake solves (`receiver`), the texel lattice
to refine where it has one (`grid`), whether the probes between vertices measure it (`between_vertices`) and whether
its Subsurface Weight applies (`takes_subsurface`), the rows it stores (`stored_rows`), and writes the result
(`write`), replacing any earlier bake of any layout (storage.remove_transfer). Reading back, `stored(mesh)` is the
layout a mesh's bake has, and its `read`, `shade`, `points`, `shade_points`, `display_source` and `describe` are
what the relighting, the display and the Stored Bake panel use; its `gltf` and `npz`, with `npz_side_files`, what
the exports (blender.gltf, `prt export`) write. Nothing outside this module asks which layout a bake has.
"""

from dataclasses import dataclass

import numpy as np

from ..core import bake, gltf_pack, texel_refine, texels
from . import display, mesh_arrays, npz_export, storage, texel_maps


@dataclass
class Shading:
    """A stored bake as the relighting reads it once per bake: rows of transfer (float32) and where they go."""
    transfer: np.ndarray              # (P, n²) or (P, 3, n²) per point, or (N, n²) per texel
    layout: type
    corner_points: np.ndarray | None = None  # per corner: (C,) each face corner's row


@dataclass
class GltfBake:
    """A stored bake as the glTF export writes it: its packing for a profile (core.gltf_pack), and the rows of
    transfer its COLOR_0 is shaded from, with each face corner's row (None: a row per vertex)."""
    packed: object
    transfer: np.ndarray
    meta: dict
    corner_points: np.ndarray | None


class PerVertex:
    """One row per vertex, attributes in the POINT domain."""
    domain = "POINT"
    between_vertices = True   # storage per vertex loses what varies between vertices: the probes measure it
    takes_subsurface = True

    def __init__(self, receiver: bake.Receiver):
        self.receiver = receiver

    @property
    def corner_points(self):
        return None

    @property
    def split_vertices(self) -> int:
        return 0

    def grid(self):
        """The texel lattice the bake refines (core.texel_refine), or None."""
        return None

    def stored_rows(self) -> int:
        """The rows written on the mesh."""
        return len(self.receiver.positions)

    def map_bytes(self, order: int) -> int:
        """What baking its texel maps holds in memory (none per point)."""
        return 0

    def write(self, mesh, result, fields: dict, settings: bake.BakeSettings):
        """Replaces any earlier bake of the mesh with this one: attributes first, metadata last."""
        storage.remove_transfer(mesh)
        storage.write_transfer(mesh, result, fields, settings, self.corner_points, self.split_vertices)

    @staticmethod
    def read(mesh) -> Shading:
        """The stored transfer as the shading reads it; raises StaleBake when it no longer fits the mesh."""
        return Shading(storage.read_transfer(mesh)[0], PerVertex, storage.corner_points_of(mesh))

    @staticmethod
    def shade(mesh, shading: Shading, light: np.ndarray):
        """The display colours under `light` (3, n²)."""
        display.write_display_colours(mesh, shading.transfer, light, shading.corner_points)

    @staticmethod
    def shade_points(mesh, shading: Shading, radiance: np.ndarray):
        """The display colours from radiance (P, 3) formed per shading point (a dynamic object lit per vertex)."""
        display.write_radiance(mesh, radiance, shading.corner_points)

    @staticmethod
    def points(mesh, shading: Shading) -> np.ndarray | None:
        """(P, 3) each shading point's position in the object's frame: its vertex's (a split vertex's corner
        points share it); None where the rows are not points (texels)."""
        positions = mesh_arrays.mesh_positions(mesh)
        if shading.corner_points is None:
            return positions
        vertex_of = np.empty(len(shading.transfer), dtype=np.int64)
        vertex_of[shading.corner_points] = mesh_arrays.mesh_corner_vertices(mesh)
        return positions[vertex_of]

    @staticmethod
    def display_source(mesh):
        """What the display material shows: the colour attribute (None), or a texel bake's (image, UV map)."""
        return None

    @staticmethod
    def describe(meta) -> str:
        """What the Stored Bake panel says of the layout, beyond the bake's figures ("" where nothing)."""
        return ""

    @staticmethod
    def gltf(ob, profile) -> GltfBake:
        """The bake packed as vertex attributes (or a data texture) for the glTF `profile`, in glTF's frame."""
        transfer, meta = storage.read_transfer(ob.data)
        packed = gltf_pack.pack(gltf_pack.to_gltf_frame(transfer).astype(np.float32), profile, ob.name)
        return GltfBake(packed, transfer, meta, storage.corner_points_of(ob.data))

    @staticmethod
    def npz_side_files(mesh, npz: str) -> list[str]:
        """The files `npz` writes beside the .npz."""
        return []

    @staticmethod
    def npz(ob, path: str) -> str:
        """Writes the bake as the .npz `path` (blender.npz_export); returns what it wrote, in words."""
        return npz_export.points_npz(ob, path)


class PerCorner(PerVertex):
    """One row per shading point (the vertices, then the further corner normals of split vertices), attributes
    in the CORNER domain with each corner's point."""
    domain = "CORNER"

    def __init__(self, receiver: bake.Receiver, corner_points: np.ndarray, split_vertices: int):
        super().__init__(receiver)
        self._corner_points, self._split_vertices = corner_points, split_vertices

    @property
    def corner_points(self):
        return self._corner_points

    @property
    def split_vertices(self) -> int:
        return self._split_vertices

    def stored_rows(self) -> int:
        return len(self._corner_points)


class PerTexel:
    """Texel centres in a lightmap UV map (core.texels), stored as packed float maps (blender.texel_maps); `uvs`,
    one (u, v) per face corner, where PRT's own lightmap UV map is to be added when the bake is stored."""
    domain = texel_maps.TEXEL_STORAGE
    corner_points, split_vertices = None, 0
    between_vertices = False  # its estimate holds what interpolating between texels may miss (core.texel_refine)
    takes_subsurface = False

    def __init__(self, receiver: bake.Receiver, layout: texels.TexelLayout, uv_map: str, uvs=None):
        self.receiver, self.layout, self.uv_map, self.uvs = receiver, layout, uv_map, uvs

    def grid(self) -> texel_refine.TexelGrid:
        layout = self.layout
        return texel_refine.TexelGrid(self.receiver, layout.texels % layout.width, layout.texels // layout.width,
                                      layout.width, layout.height)

    def stored_rows(self) -> int:
        return len(self.layout.texels)

    def map_bytes(self, order: int) -> int:
        return texels.texel_bake_bytes(self.layout.width, self.layout.height, order)

    def write(self, mesh, result, fields: dict, settings: bake.BakeSettings):
        """Replaces any earlier bake of the mesh with this one: the lightmap UV map where it is new, the maps, then
        the metadata."""
        storage.remove_transfer(mesh)
        if self.uvs is not None:
            texel_maps.add_lightmap_uv_map(mesh, self.uvs)
        maps = texel_maps.write_maps(mesh, self.layout, result.transfer, result.rel_error, settings.order,
                                     self.uv_map)
        storage.write_metadata(mesh, result, settings, self.domain, 0, {**maps, **fields})

    @staticmethod
    def read(mesh) -> Shading:
        return Shading(np.ascontiguousarray(texel_maps.read_planes(mesh)[0].T), PerTexel)

    @staticmethod
    def shade(mesh, shading: Shading, light: np.ndarray):
        texel_maps.write_shaded(mesh, shading.transfer, light)

    @staticmethod
    def points(mesh, shading: Shading):
        return None

    @staticmethod
    def display_source(mesh):
        return texel_maps.display_source(mesh)

    @staticmethod
    def describe(meta) -> str:
        return f"Per texel: {meta['width']} × {meta['height']} in {meta['uv_map']!r}"

    @staticmethod
    def gltf(ob, profile) -> GltfBake:
        """The maps as RGBA32F buffer views read through the lightmap UV map (which the exporter writes as a
        TEXCOORD like every UV map), under every profile; COLOR_0 is shaded from the maps sampled at each face
        corner's lightmap UV, every corner its own row."""
        mesh = ob.data
        planes, meta = texel_maps.read_planes(mesh)
        image = planes.T.reshape(meta["height"], meta["width"], -1)
        uvs = np.empty(2 * len(mesh.loops), dtype=np.float32)
        mesh.uv_layers[meta["uv_map"]].uv.foreach_get("vector", uvs)
        transfer = texels.sample_bilinear(image, uvs.reshape(-1, 2).astype(np.float64)).astype(np.float32)
        texcoord = f"TEXCOORD_{mesh.uv_layers.find(meta['uv_map'])}"  # the exporter writes every UV map, in order
        packed = gltf_pack.pack_maps(gltf_pack.to_gltf_frame(planes.T).T, meta["width"], meta["height"], texcoord)
        return GltfBake(packed, transfer, meta, np.arange(len(mesh.loops)))

    @staticmethod
    def npz_side_files(mesh, npz: str) -> list[str]:
        return texel_maps.exr_paths(mesh, npz_export.maps_stem(npz))

    @staticmethod
    def npz(ob, path: str) -> str:
        return npz_export.texels_npz(ob, path)


def for_surface(surface) -> PerVertex:
    """The layout of a receiver stored per point (blender.geometry.Surface): per corner where some vertex is split."""
    if surface.corner_points is None:
        return PerVertex(surface.receiver)
    return PerCorner(surface.receiver, surface.corner_points, surface.split_vertices)


def stored(mesh) -> type:
    """The layout of the mesh's stored bake (one with metadata)."""
    return PerTexel if texel_maps.is_texel_bake(mesh) else PerVertex

