"""Fingerprints of what a bake depends on: stable digests of arrays and values, one per part, so a later check can
say which part changed.

Floats are hashed as float32 (what Blender stores meshes and matrices in), so the last bits of float64 arithmetic
(a BLAS kernel chosen by size or alignment) do not count as a change; integers as int64, little-endian, with each
array's shape, so the digest is the same on every run, machine and array layout.
"""

from dataclasses import asdict
import hashlib
import json

import numpy as np

from .bake import CONVENTION_VERSION, BakeSettings

# The parts, in the order a change is told, and how it is told.
CHANGES = {
    "geometry": "geometry changed",
    "transform": "moved",
    "occluders": "occluders changed",
    "materials": "materials changed",
    "settings": "settings changed",
}
PARTS = tuple(CHANGES)
# A probe volume's parts (blender.fingerprint.volume_fingerprints): where its probes stand and what they see.
PROBE_CHANGES = {
    "transform": "moved or scaled",
    "resolution": "resolution changed",
    "occluders": "static scene changed",
    "settings": "settings changed",
}


def _digest(*chunks: bytes) -> str:
    digest = hashlib.blake2b(digest_size=16)
    for chunk in chunks:
        digest.update(chunk)
    return digest.hexdigest()


def array_digest(*arrays) -> str:
    """Hex digest of arrays: floats rounded to float32, integers and booleans as int64, shapes included."""
    chunks = []
    for array in map(np.asarray, arrays):
        if array.dtype.kind == "f":
            stored = (array.astype(np.float32) + np.float32(0.0)).astype("<f4")  # −0.0 and 0.0 are one value
        else:
            stored = array.astype("<i8")
        chunks += [f"{stored.dtype.kind}{stored.shape}".encode(), stored.tobytes()]
    return _digest(*chunks)


def values_digest(values) -> str:
    """Hex digest of JSON-able values; a dict's order does not count."""
    return _digest(json.dumps(values, sort_keys=True).encode())


def set_digest(digests) -> str:
    """Hex digest of a collection of digests, however it is ordered (duplicates count)."""
    return _digest("".join(sorted(digests)).encode())


def settings_values(settings: BakeSettings) -> dict:
    """The settings a bake of this mode reads, and the stored layout's version. Settings the mode ignores (samples
    for an unshadowed bake, bounces for a shadowed one, max samples without a target error) are left out, so
    changing them leaves the bake up to date; so is the ray engine, whose bakes agree but for float32 rounding."""
    values = asdict(settings)
    ignored = {"ray_engine"}
    if settings.mode == "unshadowed":
        ignored |= {"samples", "target_error", "max_samples", "replicates", "seed"}
    if not settings.target_error:
        ignored.add("max_samples")
    if settings.mode != "interreflected":
        ignored |= {"bounces", "bounce_tolerance"}
    elif settings.bounces is not None:
        ignored.add("bounce_tolerance")
    return {name: value for name, value in values.items() if name not in ignored} | {
        "convention": CONVENTION_VERSION}


def probe_settings_values(settings: BakeSettings) -> dict:
    """The settings a probe volume's bake reads: a receiver's (settings_values), but for the target error and max
    samples outside interreflected bakes, since a probe casts Samples rays whatever they are (interreflected, its
    bounces gather the solved surfaces' light, which reads them)."""
    values = settings_values(settings)
    if settings.mode != "interreflected":
        values = {name: value for name, value in values.items() if name not in {"target_error", "max_samples"}}
    return values


def changes(stored: dict, current: dict, told: dict = CHANGES) -> list[str]:
    """What changed between a stored fingerprint and the current one, in words, in the order of `told`'s parts
    (CHANGES, a receiver's; PROBE_CHANGES, a probe volume's); [] when nothing did."""
    return [words for part, words in told.items() if stored.get(part) != current[part]]
