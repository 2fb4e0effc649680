"""Probe volumes for glTF: each volume's transfer matrices turned into glTF's Y-up frame, as one float32 buffer view,
with its placement, resolution and valid probes in the scene's extras (docs/reference/gltf-extras.md).

A probe's matrix T maps the distant light's SH (order n) to the SH of the light arriving at the probe (order N,
core.probe_transfer.received_order), both functions of world directions; in glTF's frame, where both are rotated by
the same SH rotation R (core.gltf_pack, each to its own order), it is R_N T R_nᵀ.
The placement takes core.probe_grid's cube [−1, 1]³ to world space: in glTF's frame the axis conversion is applied
after it, so the cube's axes, along which the probes are numbered, stay those of the bake.
"""

import math
from dataclasses import dataclass

import numpy as np

from . import gltf_pack, rotation

LAYOUT = 2  # bump when the extras below change
CONVENTION = {
    "matrices": "float32, probe after probe (x slowest, z fastest over the resolution), channel after channel, "
                "each N² × n² by rows, n the order and N the received_order: light arriving (glTF frame, to order "
                "N) = T · distant light (glTF frame, order n)",
    "placement": "the matrix taking the cube [-1, 1]^3 to glTF world space, 16 floats by rows; probe (i, j, k) "
                 "sits at ((2i + 1)/nx - 1, (2j + 1)/ny - 1, (2k + 1)/nz - 1) in the cube",
    "interpolation": "trilinear over the 8 probes around the point, those with valid 0 weighted 0 and the rest "
                     "rescaled to sum to 1; a point outside the lattice of probes clamped onto it; a point outside "
                     "every cube lit by the distant light, one inside two by the smaller volume's probes",
}


@dataclass
class PackedProbes:
    """One probe volume as the glTF file carries it; `matrices` (P, C, N², n²) float32 in glTF's frame."""
    name: str
    matrices: np.ndarray
    valid: np.ndarray
    placement: np.ndarray
    resolution: tuple
    bake: dict  # what the stored metadata says of the bake: mode, samples, bake_id, layout

    def buffers(self) -> list:
        return [self.matrices]

    def extras(self, views: list) -> dict:
        probes, channels, received, size = self.matrices.shape
        return {"name": self.name, "layout": LAYOUT, "order": math.isqrt(size),
                "received_order": math.isqrt(received), "channels": channels,
                "resolution": list(self.resolution), "probes": probes,
                "placement": self.placement.ravel().tolist(), "valid": self.valid.astype(int).tolist(),
                "bufferView": views[0], "format": "float32", "bake": self.bake}


def matrices_to_gltf(matrices: np.ndarray) -> np.ndarray:
    """(..., N², n²) transfer matrices between functions of Blender's world directions → the same maps in glTF's
    frame, R_N T R_nᵀ (core.rotation.rotate turns the last axis: T R_nᵀ, then the rows)."""
    turned = rotation.rotate(matrices, gltf_pack.Z_UP_TO_Y_UP)
    return np.swapaxes(rotation.rotate(np.swapaxes(turned, -1, -2), gltf_pack.Z_UP_TO_Y_UP), -1, -2)


def placement_to_gltf(placement: np.ndarray) -> np.ndarray:
    """(4, 4) the cube's placement in Blender's world → in glTF's world."""
    convert = np.eye(4)
    convert[:3, :3] = gltf_pack.Z_UP_TO_Y_UP
    return convert @ np.asarray(placement, dtype=np.float64)


def pack_probes(name: str, matrices, valid, placement, resolution, bake: dict) -> PackedProbes:
    """A stored volume (matrices (P, C, N², n²), valid (P,), placement (4, 4), all in Blender's world) for glTF."""
    turned = matrices_to_gltf(np.asarray(matrices, dtype=np.float64)).astype(np.float32)
    return PackedProbes(name, np.ascontiguousarray(turned), np.asarray(valid, dtype=bool),
                        placement_to_gltf(placement), tuple(int(n) for n in resolution), bake)
