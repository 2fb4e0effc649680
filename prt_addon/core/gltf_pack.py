"""SH transfer for glTF: turned into glTF's Y-up frame and packed into vertex attributes as an export profile
allows, or into a float data texture indexed by shading point, or refused with the limit named.

Blender's glTF exporter writes positions and normals as (x, z, −y) but custom attributes as they are; SH
coefficients are functions of direction, so they are rotated (an SH rotation), not copied. With the transfer and
the light in one frame the shading Σ_k L_k T_k is the same number in either frame.
"""

import math
from dataclasses import dataclass

import numpy as np

from . import lights, lobes, rotation
from .errors import InputError

# glTF (x, y, z) = Blender (x, z, −y): the exporter's own axis conversion, a proper rotation (−90° about X).
Z_UP_TO_Y_UP = np.array([[1.0, 0.0, 0.0], [0.0, 0.0, 1.0], [0.0, -1.0, 0.0]])
INDEX_ATTRIBUTE = "_PRT_INDEX"  # each glTF vertex's shading point: its row of the data texture
TEXTURE_WIDTH = 4096  # texels per row of a data texture; WebGL 2 guarantees at least 2048, every GPU 4096
CONVENTION = {
    "basis": "real spherical harmonics, orthonormal, with the Condon-Shortley phase "
             "(Y_1,-1 = -sqrt(3/4pi) y, Y_1,0 = sqrt(3/4pi) z, Y_1,1 = -sqrt(3/4pi) x)",
    "index": "k = l(l+1) + m; order n holds bands l < n, n^2 coefficients",
    "normalisation": "transfer holds 1/pi: outgoing radiance = albedo * sum_k L_k T_k, L the light's radiance SH",
    "frame": "glTF world space, Y up: Blender's world coefficients rotated by (x, y, z) -> (x, z, -y)",
    "packing": "per vertex, channel-major (all of channel 0's coefficients, then channel 1's ...), zero-padded to "
               "a multiple of 4, four floats per VEC4 attribute or RGBA32F texel",
    "dynamic": "a mesh whose extras.prt has dynamic true holds its transfer in its node's own frame (glTF axes), "
               "lit by the light arriving at its bounding box's centre (probe_light centre) or at each vertex "
               "(probe_light vertex) through the probe volumes, else the distant light, turned into that frame: "
               "the coefficients of L(R w), R the node's world rotation; its transfer's order is the probes' "
               "received_order, above the distant light's (light_order), whose higher coefficients are zero",
}


@dataclass(frozen=True)
class Profile:
    name: str
    attribute_name: str  # format of the i-th VEC4 attribute's name
    max_attributes: int | None  # VEC4 attributes the profile allows for transfer; None: no limit
    texture_beyond: bool  # beyond the budget: a data texture (True) or a refusal (False)
    limit: str  # what the budget is, for the refusal and the manual


PROFILES = {
    "web": Profile("web", "_PRT_SH{}", 12, True, "WebGL 2 guarantees 16 vertex attributes: 12 VEC4s beside "
                   "POSITION, NORMAL, TEXCOORD_0 and COLOR_0"),
    "godot": Profile("godot", "_CUSTOM{}", 4, False, "Godot imports 4 custom VEC4 arrays (CUSTOM0-CUSTOM3), "
                     "16 floats: order 4 grey or order 2 RGB"),
    "generic": Profile("generic", "_PRT_SH{}", None, False, "none"),
}


@dataclass
class Packed:
    """One mesh's transfer as the profile packs it, per shading point (the Blender layer spreads it to vertices
    or corners): VEC4 attributes, or a data texture and the point index attribute that reads it."""
    attributes: dict  # glTF attribute name → (P, 4) float32
    texture: np.ndarray | None  # (height, TEXTURE_WIDTH, 4) float32: texel point·vec4s + j holds VEC4 j
    vec4s: int  # VEC4s per point
    order: int
    channels: int

    @property
    def indexed(self) -> bool:
        """Whether each point's index goes with it as INDEX_ATTRIBUTE (to read its texels of the data texture)."""
        return self.texture is not None

    def buffers(self) -> list:
        """The arrays that go into the file as buffer views, in the order extras() takes their views."""
        return [] if self.texture is None else [self.texture]

    def extras(self, views=()) -> dict:
        """The mesh's `prt` extras, `views` the buffer views of buffers()."""
        layout = {"order": self.order, "channels": self.channels, "vec4s": self.vec4s}
        if self.texture is None:
            return {**layout, "layout": "attributes", "attributes": list(self.attributes)}
        height, width = self.texture.shape[:2]
        texture = {"width": width, "height": height, "format": "RGBA32F", **{"bufferView": view for view in views}}
        return {**layout, "layout": "texture", "index_attribute": INDEX_ATTRIBUTE, "texture": texture}

    def describe(self) -> str:
        return (f"order {self.order} × {self.channels} in {self.vec4s} VEC4 "
                f"{'attributes' if self.texture is None else 'texels of a data texture'}")


def to_gltf_frame(coefficients: np.ndarray) -> np.ndarray:
    """SH coefficients (..., n²) of a function of Blender's world directions → the same function in glTF's frame."""
    return rotation.rotate(coefficients, Z_UP_TO_Y_UP)


def direction_to_gltf(direction) -> list:
    return (Z_UP_TO_Y_UP @ np.asarray(direction, dtype=np.float64)).tolist()


def channel_major(transfer: np.ndarray) -> np.ndarray:
    """(P, n²) grey or (P, C, n²) coloured → (P, C·n²), channel after channel."""
    return transfer.reshape(len(transfer), -1)


def pack(transfer: np.ndarray, profile: Profile, object_name: str) -> Packed:
    """Transfer (P, n²) or (P, C, n²), already in glTF's frame, packed as `profile` allows."""
    order = math.isqrt(transfer.shape[-1])
    channels = 1 if transfer.ndim == 2 else transfer.shape[1]
    flat = channel_major(np.asarray(transfer, dtype=np.float32))
    vec4s = -(-flat.shape[1] // 4)
    padded = np.zeros((len(flat), 4 * vec4s), dtype=np.float32)
    padded[:, : flat.shape[1]] = flat
    if profile.max_attributes is None or vec4s <= profile.max_attributes:
        attributes = {profile.attribute_name.format(j): np.ascontiguousarray(padded[:, 4 * j: 4 * j + 4])
                      for j in range(vec4s)}
        return Packed(attributes, None, vec4s, order, channels)
    if not profile.texture_beyond:
        raise InputError(f"{object_name}: order {order} with {channels} channel(s) needs {vec4s} VEC4 attributes; "
                         f"the {profile.name} profile allows {profile.max_attributes} ({profile.limit}). "
                         f"Bake a lower order or use the web or generic profile")
    return Packed({}, _data_texture(padded), vec4s, order, channels)


@dataclass
class PackedMaps:
    """A texel bake's transfer as RGBA32F maps through a lightmap UV set: map j holds coefficients 4j .. 4j + 3 of
    each texel, rows from the top (glTF's v = 0), so a viewer samples them with the TEXCOORD set as any texture.
    No vertex attributes: the maps go into the file as buffer views."""
    maps: list  # vec4s × (height, width, 4) float32
    texcoord: str  # the glTF attribute of the lightmap UV map
    order: int
    attributes = {}
    indexed = False

    def buffers(self) -> list:
        return self.maps

    def extras(self, views: list) -> dict:
        height, width = self.maps[0].shape[:2]
        return {"order": self.order, "channels": 1, "vec4s": len(self.maps), "layout": "texel_maps",
                "texcoord": self.texcoord, "maps": {"width": width, "height": height, "format": "RGBA32F",
                                                     "rows": "top first (v = 0)", "bufferViews": views}}

    def describe(self) -> str:
        height, width = self.maps[0].shape[:2]
        return f"order {self.order} in {len(self.maps)} RGBA32F texel maps of {width} × {height} ({self.texcoord})"


def pack_maps(planes: np.ndarray, width: int, height: int, texcoord: str) -> PackedMaps:
    """planes (n², height·width), rows from v = 0 at the bottom as Blender stores images, already in glTF's frame."""
    order = math.isqrt(len(planes))
    vec4s = -(-len(planes) // 4)
    padded = np.zeros((4 * vec4s, height * width), dtype=np.float32)
    padded[: len(planes)] = planes
    images = padded.T.reshape(height, width, 4 * vec4s)[::-1]  # glTF's v runs down the image
    return PackedMaps([np.ascontiguousarray(images[..., 4 * j: 4 * j + 4]) for j in range(vec4s)], texcoord, order)


def _data_texture(padded: np.ndarray) -> np.ndarray:
    """(P, 4·vec4s) → (height, TEXTURE_WIDTH, 4): the texels of point p are p·vec4s .. p·vec4s + vec4s − 1."""
    texels = padded.reshape(-1, 4)
    height = max(1, -(-len(texels) // TEXTURE_WIDTH))
    texture = np.zeros((height * TEXTURE_WIDTH, 4), dtype=np.float32)
    texture[: len(texels)] = texels
    return texture.reshape(height, TEXTURE_WIDTH, 4)


def light_extras(scene_lights, order: int) -> list[dict]:
    """The scene's SH lights for a viewer, in glTF's frame: a sun as its direction (and Blender's θ, φ, which a
    viewer turns), disc radius, irradiance and zonal coefficients z_l (f_lm = sqrt(4π/(2l+1)) z_l Y_lm(d)); a sky
    or an environment as its (3, n²) coefficients, colour and rotation applied."""
    cache, described = lights.LightCache(), []
    for light in scene_lights:
        if isinstance(light, lights.Sun):
            direction = np.asarray(light.direction, dtype=np.float64) / np.linalg.norm(light.direction)
            described.append({
                "kind": "sun", "direction": direction_to_gltf(direction),
                "theta": math.acos(max(-1.0, min(1.0, direction[2]))), "phi": math.atan2(direction[1], direction[0]),
                "angular_radius": light.angular_radius, "rgb": list(light.rgb),
                "zonal": lobes.sun_disc_zonal(order, light.angular_radius).tolist()})
        else:
            kind = "sky" if isinstance(light, lights.Sky) else "environment"
            placed = cache.totals([light], [order])[order]
            described.append({"kind": kind, "rgb": list(light.rgb), "coefficients": to_gltf_frame(placed).tolist()})
    return described
