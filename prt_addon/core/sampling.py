"""Randomised low-discrepancy directions on the cosine-weighted hemisphere, and the hash that randomises them.

A vertex's estimate uses R replicates of one Fibonacci lattice, each replicate shifted modulo 1 by its own
hashed offset (Cranley-Patterson rotation). Every shifted point is uniform on the unit square, so each
replicate is an unbiased estimate, and the spread of the R replicates is an honest standard error, while each
replicate keeps the lattice's faster-than-Monte-Carlo convergence.
"""

import functools

import numpy as np


# Golden ratio conjugate: the generator whose lattice spreads best for every point count.
_GOLDEN = (np.sqrt(5.0) - 1.0) / 2.0
# splitmix64 constants: the Weyl increment 2^64/φ and the finaliser's multipliers.
_WEYL = np.uint64(0x9E3779B97F4A7C15)
_MIX_1 = np.uint64(0xBF58476D1CE4E5B9)
_MIX_2 = np.uint64(0x94D049BB133111EB)
# Hash values produced per pass: small enough that the uint64 temporaries stay in cache.
_HASH_CHUNK = 1 << 16
# A cap shared by several normals (cosine_lattice_directions' floor) has density ∝ (z − s)^CAP_EXPONENT above its
# floor s. Each normal weighs a ray by its own cosine density over the cap's, and what it sees blocked lies mostly
# low, near the floor, where a lower exponent puts more rays: the flat-shaded cow's estimated error at 256 samples,
# relative to the exponent 1 (the cosine lobe lowered to the floor): 0.5 0.992, 0.65 0.978, 0.7 0.976, 0.75 0.975,
# 0.85 0.977; on a floor, homer 0.982 and the teapot 0.977 at 0.75. (The mean of W² alone, the noise where the
# occlusion is even, is least near 1.4: it does not say where the occluders are.)
CAP_EXPONENT = 0.75


def _mix64(x):
    """splitmix64's finaliser on a uint64 array (in place): a bijection in which every input bit flips about
    half of the output bits. uint64 products wrap modulo 2^64, as the hash intends."""
    x ^= x >> np.uint64(30)
    x *= _MIX_1
    x ^= x >> np.uint64(27)
    x *= _MIX_2
    x ^= x >> np.uint64(31)
    return x


def _stream_starts(seed, keys):
    """One independent splitmix64 stream per key: a mixed (seed, key) pair."""
    seed_bits = np.array([seed], dtype=np.int64).view(np.uint64)
    key_bits = np.ascontiguousarray(keys, dtype=np.int64).view(np.uint64)
    return _mix64(key_bits ^ _mix64(seed_bits * _WEYL))


def hash_uniform(seed, keys, count):
    """Uniforms in [0, 1), shape (len(keys), count). Entry (i, j) is a hash of (seed, keys[i], j) alone, so
    splitting the keys into chunks, or asking for more values per key, never changes a value."""
    streams = _stream_starts(seed, np.reshape(keys, -1))
    counters = np.arange(1, count + 1, dtype=np.uint64) * _WEYL
    uniforms = np.empty((len(streams), count))
    rows = max(1, _HASH_CHUNK // max(count, 1))
    for start in range(0, len(streams), rows):
        bits = _mix64(streams[start:start + rows, None] + counters)
        # The top 53 bits fill a double's mantissa exactly: values k/2^53, never 1.
        np.multiply(bits >> np.uint64(11), 2.0 ** -53, out=uniforms[start:start + rows])
    return uniforms


@functools.lru_cache(maxsize=64)
def fibonacci_lattice(count):
    """(count, 2) points (i/n, frac(i·g)) in [0, 1)², g the golden ratio conjugate; read-only, made once per count
    (a bake asks for it in every round)."""
    index = np.arange(count)
    points = np.stack([index / count, np.mod(index * _GOLDEN, 1.0)], axis=-1)
    points.flags.writeable = False
    return points


def cranley_patterson(points, shifts):
    """Every shift (..., d) applied to all points (n, d) modulo 1 → (..., n, d).

    Works one coordinate at a time so numpy's inner loops run along the n points, not along pairs. float32 inputs
    give float32 points; anything else float64."""
    points, shifts = np.asarray(points), np.asarray(shifts)
    dtype = np.result_type(points.dtype, shifts.dtype, np.float32)
    points, shifts = points.astype(dtype, copy=False), shifts.astype(dtype, copy=False)
    shifted = np.empty(shifts.shape[:-1] + points.shape, dtype=dtype)
    for axis in range(points.shape[-1]):
        coordinate = shifted[..., axis]
        np.add(points[:, axis], shifts[..., None, axis], out=coordinate)
        # Both terms lie in [0, 1), so one subtraction wraps exactly (no floor, no rounding).
        np.subtract(coordinate, 1.0, out=coordinate, where=coordinate >= 1.0)
    return shifted


def cosine_lattice_directions(points, shifts, frames, floor=None, dtype=np.float64):
    """Unit directions (..., n, 3): the lattice `points` (n, 2) under every Cranley-Patterson shift (..., 2),
    mapped to the cosine-weighted hemisphere of each frame (..., 3, 3) whose rows are tangent, bitangent, normal.

    With `floor` s (..., ≤ 0), the directions fill the larger cap z ≥ s, z = normal·d, with density
    (q + 1)(z − s)^q / (2π (1 − s)^(q+1)), q = CAP_EXPONENT (a group of nearby normals shares such a cap, see
    core.estimator and cap_weights). Its height is s + (1 − s)·(cos² θ)^(1/(q+1)) of the hemisphere's map, so the strata
    stay equal-weight rings.

    Polar map (uniform on the disc, lifted to the hemisphere): the first coordinate is sin²θ, so its strata are
    equal-cosine-weight rings; the second is the azimuth. Shifting the azimuth turns the tangent frame, so cos and
    sin are taken once per lattice point and once per shift rather than once per ray. The result is a view of a
    component-major array: each coordinate of all the rays is contiguous, as the ray caster and SH evaluation
    read them. All arithmetic is in `dtype`: float32 directions are what the ray caster casts anyway (mathutils
    stores float32)."""
    points, shifts, frames = (np.asarray(a, dtype=dtype) for a in (points, shifts, frames))
    sin_squared = cranley_patterson(points[:, :1], shifts[..., :1])[..., 0]  # (..., n)
    if floor is None:
        height = np.sqrt(1.0 - sin_squared)
        radius = np.sqrt(sin_squared, out=sin_squared)
    else:
        floor = np.asarray(floor, dtype=dtype)[..., None]
        height = np.power(1.0 - sin_squared, dtype(1.0 / (CAP_EXPONENT + 1.0)))
        height *= 1.0 - floor  # in place: these are per-ray arrays
        height += floor
        radius = np.multiply(height, height, out=sin_squared)
        np.subtract(1.0, radius, out=radius)
        np.sqrt(np.maximum(radius, 0.0, out=radius), out=radius)
    azimuth, turn = 2.0 * np.pi * points[:, 1], 2.0 * np.pi * shifts[..., 1:]
    cos_turn, sin_turn = np.cos(turn), np.sin(turn)
    tangent = cos_turn * frames[..., 0, :] + sin_turn * frames[..., 1, :]  # (..., 3)
    bitangent = cos_turn * frames[..., 1, :] - sin_turn * frames[..., 0, :]
    across, along = radius * np.cos(azimuth), radius * np.sin(azimuth)
    directions = np.empty((3,) + radius.shape, dtype=dtype)
    for axis, component in enumerate(directions):
        np.multiply(across, tangent[..., axis, None], out=component)
        component += along * bitangent[..., axis, None]
        component += height * frames[..., 2, axis, None]
    return np.moveaxis(directions, 0, -1)


def cap_weights(above_floor, floor, scale=1.0):
    """1/(π p)·`scale` for directions in caps (cosine_lattice_directions with a floor) at heights z − s =
    `above_floor` over their floor s (`floor`, broadcast against it), p the cap's density, written over
    `above_floor`: a normal n weighs a ray of the cap by (n·d)₊ times this to estimate its own cosine lobe's
    integrals, 2(1 − s)^(q+1) / ((q + 1)(z − s)^q). Bounded where it counts: (n·d)₊ vanishes at the floor."""
    dtype = above_floor.dtype.type
    np.maximum(above_floor, np.finfo(dtype).tiny, out=above_floor)
    np.power(above_floor, dtype(CAP_EXPONENT), out=above_floor)
    numerator = (2.0 * scale / (CAP_EXPONENT + 1.0)) * (1.0 - floor) ** dtype(CAP_EXPONENT + 1.0)
    return np.divide(numerator.astype(dtype), above_floor, out=above_floor)


def orthonormal_basis(normals):
    """(tangents, bitangents) completing unit normals (N, 3) to right-handed frames (t × b = n).

    Duff et al. 2017, "Building an orthonormal basis, revisited": branchless and accurate for every normal,
    including n = -Z, where the sign flip keeps the denominator at least 1 in magnitude."""
    normals = np.asarray(normals, dtype=np.float64)
    x, y, z = normals[..., 0], normals[..., 1], normals[..., 2]
    sign = np.copysign(1.0, z)
    a = -1.0 / (sign + z)
    b = x * y * a
    tangents = np.stack([1.0 + sign * x * x * a, sign * b, -sign * x], axis=-1)
    bitangents = np.stack([b, sign + y * y * a, -y], axis=-1)
    return tangents, bitangents


def unit_or_zero(vectors, shortest=0.0):
    """Vectors (..., 3) scaled to unit length; zero where they are no longer than `shortest`."""
    vectors = np.asarray(vectors, dtype=np.float64)
    length = np.linalg.norm(vectors, axis=-1, keepdims=True)
    return np.where(length > shortest, vectors / np.where(length > 0, length, 1.0), 0.0)
