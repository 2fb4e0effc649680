"""Texel storage: a bake's transfer as float images in a lightmap UV map's space, packed in the .blend, written,
read back and removed; and the lightmap UV map itself (the artist's, or one made for PRT by Blender's Lightmap
Pack).

Stored layout (docs/reference/stored-layout.md; the mesh's `prt` metadata has `storage` "TEXEL"):
- float RGBA images `_prt_<mesh>_t00`, `_prt_<mesh>_t01`, ...: image j holds coefficients k = 4j..4j+3 in R, G, B, A
  (k = l(l+1)+m; the last one zero-padded), Non-Color, packed into the .blend as lossless 32-bit OpenEXR;
- a float RGBA image `_prt_<mesh>_error`: the estimated relative error in R, G and B, alpha 1;
- their names in `images` and `error_image`, and `uv_map`, `width`, `height`, `texels` (covered), `gutter` in
  the metadata; Blender may append .001 to a name that is taken, so the metadata's names are the ones to read.
Packed, the maps travel with the file and survive saving and reloading; `prt export` writes them as EXR files.
"""

import contextlib
import io

import bpy
import numpy as np

from ..core import texels
from ..core.errors import InputError, StaleBake
from . import outputs, storage

PRT_UV_MAP = "PRT Lightmap"
STORAGE_KEY = "storage"  # in the metadata: "TEXEL"; vertex bakes have none (or "VERTEX")
TEXEL_STORAGE = "TEXEL"
SHADED_SUFFIX = "_shaded"
MAX_UV_MAPS = 8  # Blender's limit per mesh


# -- the lightmap UV map ----------------------------------------------------------------------------------------
def lightmap_uv_map(ob, chosen: str, may_create: bool, margin_texels: float,
                    resolution: int) -> tuple[str, np.ndarray | None]:
    """The UV map the texels follow, and None, or PRT's own map and the (C, 2) UVs it is to get: `chosen` (which
    must exist), else the PRT Lightmap map, else, where `may_create`, the UVs of Blender's Lightmap Pack, for the
    bake's storing to add (add_lightmap_uv_map). Nothing of the mesh changes here."""
    mesh = ob.data
    if chosen:
        if chosen not in mesh.uv_layers:
            raise InputError(f"{ob.name!r} has no UV map named {chosen!r} for its texels")
        return chosen, None
    if PRT_UV_MAP in mesh.uv_layers:
        return PRT_UV_MAP, None
    if not may_create:
        owned = ", ".join(repr(layer.name) for layer in mesh.uv_layers) or "none"
        raise InputError(f"{ob.name!r}: texel storage needs a lightmap UV map; choose one of its UV maps ({owned}) "
                         f"or allow PRT to add its own {PRT_UV_MAP!r}")
    if len(mesh.uv_layers) >= MAX_UV_MAPS:
        raise InputError(f"{ob.name!r} already has {MAX_UV_MAPS} UV maps, Blender's limit: choose one of them "
                         f"for its texels")
    return PRT_UV_MAP, lightmap_pack_uvs(mesh, margin_texels, resolution)


def lightmap_pack_uvs(mesh, margin_texels: float, resolution: int) -> np.ndarray:
    """(C, 2) float32: the UV map Blender's own Lightmap Pack makes of the mesh, one box per face, `margin_texels`
    apart, found on a temporary copy of the mesh (removed again): the mesh itself is not touched."""
    from bl_operators.uvcalc_lightmap import lightmap_uvpack  # Blender's Lightmap Pack, without its operator
    copy = mesh.copy()
    try:
        layers = copy.uv_layers
        layers.new(name=PRT_UV_MAP, do_init=False)
        layers.active = layers[PRT_UV_MAP]  # it writes the active map
        with contextlib.redirect_stdout(io.StringIO()):  # it prints its progress
            lightmap_uvpack([copy], PREF_SEL_ONLY=False, PREF_NEW_UVLAYER=False, PREF_PACK_IN_ONE=False,
                            PREF_MARGIN_DIV=max(1, int(resolution / max(margin_texels, 1e-3))))
        uvs = np.empty(len(copy.loops) * 2, dtype=np.float32)
        layers[PRT_UV_MAP].uv.foreach_get("vector", uvs)
    finally:
        bpy.data.meshes.remove(copy)
    return uvs.reshape(-1, 2)


def add_lightmap_uv_map(mesh, uvs: np.ndarray):
    """Adds PRT's own lightmap UV map holding `uvs` (C, 2); the artist's active and render-active maps stay as
    they were (the new map is active while it is written, as Lightmap Pack leaves it where it is the only one)."""
    layers = mesh.uv_layers
    active = layers.active.name if layers.active else None
    render = next((layer.name for layer in layers if layer.active_render), None)
    layers.new(name=PRT_UV_MAP, do_init=False)
    layers.active = layers[PRT_UV_MAP]
    layers[PRT_UV_MAP].uv.foreach_set("vector", np.ascontiguousarray(uvs, dtype=np.float32).ravel())
    if active is not None:
        layers.active = layers[active]
    if render is not None:
        layers[render].active_render = True


def triangle_uvs(mesh, uv_map: str, loop_triangles: np.ndarray) -> np.ndarray:
    """(T, 3, 2) the UVs of each triangle's corners (loop_triangles: (T, 3) face corners)."""
    uvs = np.empty(len(mesh.loops) * 2, dtype=np.float64)
    mesh.uv_layers[uv_map].uv.foreach_get("vector", uvs)
    return uvs.reshape(-1, 2)[loop_triangles]


# -- the stored maps --------------------------------------------------------------------------------------------
def is_texel_bake(mesh) -> bool:
    meta = mesh.get(storage.METADATA_KEY)
    return meta is not None and meta.get(STORAGE_KEY) == TEXEL_STORAGE


def image_names(mesh_name: str, order: int) -> list[str]:
    return [f"_prt_{mesh_name}_t{j:02d}" for j in range(-(-order * order // 4))]


def write_maps(mesh, layout: texels.TexelLayout, transfer: np.ndarray, rel_error: np.ndarray, order: int,
               uv_map: str) -> dict:
    """Packs the coefficient and error images (replacing the mesh's earlier ones) and returns the metadata that
    names them."""
    storage.remove_images(mesh)
    names = image_names(mesh.name, order)
    rows = np.zeros((len(transfer), 4 * len(names) + 4), dtype=np.float32)  # the coefficient maps', then the error's
    rows[:, : order * order] = transfer
    rows[:, -4:-1] = rel_error[:, None]
    rows[:, -1] = 1.0
    pixels = texels.to_image(layout, rows)  # one dilation for every map
    images = [_packed_image(name, mesh, pixels[..., 4 * j: 4 * j + 4]) for j, name in enumerate(names)]
    error_image = _packed_image(f"_prt_{mesh.name}_error", mesh, pixels[..., -4:])
    return {STORAGE_KEY: TEXEL_STORAGE, "uv_map": uv_map, "width": layout.width, "height": layout.height,
            "texels": len(layout.texels), "gutter": texels.GUTTER_TEXELS,
            "images": [image.name for image in images], "error_image": error_image.name}


def _packed_image(name, mesh, pixels: np.ndarray):
    """A float RGBA image of `pixels` (height, width, 4), Non-Color, packed as 32-bit OpenEXR, kept by a fake user
    (nothing else uses it until the display does)."""
    height, width = pixels.shape[:2]
    image = bpy.data.images.new(name, width, height, alpha=True, float_buffer=True)
    image.colorspace_settings.name = "Non-Color"
    image.pixels.foreach_set(np.ascontiguousarray(pixels, dtype=np.float32).ravel())
    image.file_format = "OPEN_EXR"
    image.use_half_precision = False
    image.use_fake_user = True
    image[storage.MAP_OF_KEY] = mesh.name
    image.pack()
    return image


def read_planes(mesh) -> tuple[np.ndarray, dict]:
    """(n², height·width) float32 coefficient planes of every texel (gutters included) and the metadata; the
    shading reads planes, one contiguous row per coefficient."""
    meta = mesh[storage.METADATA_KEY].to_dict()
    order, width, height = meta["order"], meta["width"], meta["height"]
    planes = np.empty((4 * len(meta["images"]), height * width), dtype=np.float32)
    pixels = np.empty(height * width * 4, dtype=np.float32)
    for j, name in enumerate(meta["images"]):
        image = bpy.data.images.get(name)
        if image is None or tuple(image.size) != (width, height):
            raise StaleBake(f"mesh {mesh.name!r} lost its PRT texel map {name!r}; rebake it")
        image.pixels.foreach_get(pixels)
        planes[4 * j: 4 * j + 4] = pixels.reshape(-1, 4).T
    return planes[: order * order], meta


def read_error(mesh) -> np.ndarray:
    """(height, width) the estimated relative error image."""
    meta = mesh[storage.METADATA_KEY]
    image = bpy.data.images[meta["error_image"]]
    pixels = np.empty(meta["width"] * meta["height"] * 4, dtype=np.float32)
    image.pixels.foreach_get(pixels)
    return pixels.reshape(meta["height"], meta["width"], 4)[..., 0]


def exr_paths(mesh, stem: str) -> list[str]:
    """Where save_exr writes the mesh's maps: `<stem>_t00.exr`, ..., `<stem>_error.exr`."""
    return [f"{stem}_t{j:02d}.exr" for j in range(len(mesh[storage.METADATA_KEY]["images"]))] + [f"{stem}_error.exr"]


def save_exr(mesh, stem: str) -> list[str]:
    """Writes the mesh's maps as 32-bit OpenEXR files (exr_paths), each whole or not at all; returns their paths.
    The packed images stay as they are."""
    meta = mesh[storage.METADATA_KEY]
    paths = exr_paths(mesh, stem)
    for name, path in zip(list(meta["images"]) + [meta["error_image"]], paths):
        outputs.save_image(bpy.data.images[name], path)
    return paths


# -- the shaded image -------------------------------------------------------------------------------------------
def shaded_image(mesh):
    """The float image the relighting writes and the display material shows (made once per mesh and size; not
    packed: it is shaded again whenever the file is opened)."""
    meta = mesh[storage.METADATA_KEY]
    name = f"_prt_{mesh.name}{SHADED_SUFFIX}"
    image = bpy.data.images.get(name)
    if image is not None and tuple(image.size) != (meta["width"], meta["height"]):
        bpy.data.images.remove(image)
        image = None
    if image is None:
        image = bpy.data.images.new(name, meta["width"], meta["height"], alpha=True, float_buffer=True)
        image[storage.MAP_OF_KEY] = mesh.name
    return image


def write_shaded(mesh, transfer: np.ndarray, light: np.ndarray):
    """One product per texel: Σ_k L_k T_k for transfer (N, n²) (one row per texel, float32) and light (3, n²) into
    the shaded image (RGBA, alpha 1, negative values clamped to black), with float32 foreach_set. One matrix
    product straight into RGBA rows (the light padded with a zero column for alpha) is about twice as fast as
    shading per channel and interleaving."""
    image = shaded_image(mesh)
    padded = np.zeros((transfer.shape[1], 4), dtype=np.float32)
    padded[:, :3] = light.T
    rgba = transfer @ padded
    rgba[:, 3] = 1.0
    np.maximum(rgba, 0.0, out=rgba)
    image.pixels.foreach_set(rgba.ravel())
    image.update()
    return image


def display_source(mesh) -> tuple[str, str]:
    """(shaded image name, UV map) for the display material of a texel bake."""
    return shaded_image(mesh).name, mesh[storage.METADATA_KEY]["uv_map"]
