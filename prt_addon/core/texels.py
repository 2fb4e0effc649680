"""Texels as receiver points: UV triangles rasterised in numpy, each covered texel's centre placed on its triangle
(world position, interpolated corner normal, a tangent step into its own triangle), gutters dilated around the UV
islands, and the resolution and memory a texel bake needs.

A texel is covered when its centre lies in a UV triangle (edges included), or, at an island's border, when its
square reaches into one (its centre less than half a texel's diagonal away): such a border texel is baked at the
triangle's point nearest its centre, so bilinear filtering between it and the texels inside reads values of the
surface, never guesses. A centre strictly inside two triangles is an overlap: two surfaces would share one texel.
Texels farther out get values only from the gutter dilation.
"""

from dataclasses import dataclass

import numpy as np

# Candidate texel centres tested at once: bounded memory whatever the resolution (8 bytes × a few arrays each).
CANDIDATES_AT_ONCE = 1 << 21
# A centre this close to an edge (in barycentric weight) is on it: it belongs to both triangles without being an
# overlap, so shared edges never count as overlaps.
ON_EDGE = 1e-7
BORDER = np.sqrt(0.5) - 1e-6  # a texel whose centre is nearer a triangle than this touches it (a corner alone: not)
GUTTER_TEXELS = 4  # texels dilated around each island: bilinear filtering and a mip level or two see no seam
# PRT's own lightmap UV map leaves this many texels (at the resolution it is packed for) on each side of each face's
# box: a gap of 4 between islands, so the gutter texel next to an island is dilated from that island alone.
PACK_MARGIN_TEXELS = 2.0
SMALLEST_RESOLUTION = 16
MIN_TEXELS_PER_TRIANGLE = 16  # a resolution from the target error gives each triangle at least this many
LARGEST_RESOLUTION = 8192
# What one texel costs while baking (position, normal, inward step, transfer float64 and float32 per coefficient,
# error, rays, flags, layout) and stored (RGBA float32 per 4 coefficients and the error, the shaded image).
TEXEL_POINT_BYTES = 3 * 3 * 8 + 8 + 8 + 1 + 8 + 3 * 8 + 4
TEXEL_COEFFICIENT_BYTES = 8 + 4


@dataclass
class TexelLayout:
    """Which texels a UV map covers at one resolution, and where each lies on the mesh."""
    width: int
    height: int
    texels: np.ndarray       # (N,) row-major index y·width + x of each covered texel
    triangles: np.ndarray    # (N,) the triangle its centre lies in (or, at a border, is nearest)
    barycentric: np.ndarray  # (N, 3) the weights of its point (its centre, or the nearest point) on the corners
    overlapping: int         # covered texels whose centre lies strictly inside more than one triangle
    zero_area: np.ndarray    # (T,) bool: triangles with no area in UV space (they get no texels)

    @property
    def covered_share(self) -> float:
        return len(self.texels) / float(self.width * self.height)

    @property
    def overlap_share(self) -> float:
        return self.overlapping / max(1, len(self.texels))


def rasterise(uvs: np.ndarray, width: int, height: int) -> TexelLayout:
    """uvs (T, 3, 2) per triangle corner → the texels the triangles cover. A texel in several triangles (a shared
    edge, or an overlap) goes to the one it lies deepest in; a border texel to the nearest triangle."""
    pixel = uvs * np.array([width, height], dtype=np.float64) - 0.5  # texel centres at whole numbers
    a, b, c = pixel[:, 0], pixel[:, 1], pixel[:, 2]
    doubled_area = _cross(b - a, c - a)
    zero_area = np.abs(doubled_area) <= 1e-12 * max(width, height) ** 2
    low = np.maximum(np.ceil(pixel.min(axis=1) - BORDER), 0).astype(np.int64)
    high = np.minimum(np.floor(pixel.max(axis=1) + BORDER), [width - 1, height - 1]).astype(np.int64)
    spans = np.maximum(high - low + 1, 0)
    counts = np.where(zero_area, 0, spans[:, 0] * spans[:, 1])
    found = [_covered(pixel, doubled_area, low, spans, part, width)
             for part in _batches(counts, CANDIDATES_AT_ONCE)]
    texel, triangle, weights, depth = (np.concatenate(column) for column in zip(*found)) if found else (
        np.zeros(0, np.int64), np.zeros(0, np.int64), np.zeros((0, 3)), np.zeros(0))
    order = np.lexsort((-depth, texel))  # per texel, deepest first (border texels, nearest first, after)
    texel, triangle, weights, depth = texel[order], triangle[order], weights[order], depth[order]
    first = np.r_[True, texel[1:] != texel[:-1]]
    strictly = depth > ON_EDGE
    inside_count = np.add.reduceat(strictly.astype(np.int64), np.flatnonzero(first)) if len(texel) else np.zeros(0)
    return TexelLayout(width, height, texel[first], triangle[first], weights[first],
                       int((inside_count > 1).sum()), zero_area)


def _covered(pixel, doubled_area, low, spans, triangles, width):
    """(texel, triangle, barycentric, depth) for the candidate centres in the bounding boxes of `triangles` (grown
    by BORDER) that lie in them, depth their smallest weight (≥ 0), or that are within BORDER of them, with the
    nearest point's weights and depth −1 − their distance."""
    counts = spans[triangles, 0] * spans[triangles, 1]
    owner = np.repeat(triangles, counts)
    local = np.arange(counts.sum()) - np.repeat(np.cumsum(counts) - counts, counts)
    x = low[owner, 0] + local % spans[owner, 0]
    y = low[owner, 1] + local // spans[owner, 0]
    point = np.stack([x, y], axis=1).astype(np.float64)
    a, b, c = (pixel[owner, i] for i in range(3))
    area = doubled_area[owner]
    weights = np.stack([_cross(b - point, c - point), _cross(c - point, a - point), _cross(a - point, b - point)],
                       axis=1) / area[:, None]
    depth = weights.min(axis=1)
    inside = depth >= -ON_EDGE
    distance, nearest = _nearest_on_edges(point, a, b, c)
    border = ~inside & (distance < BORDER)
    weights[border] = nearest[border]
    depth[border] = -1.0 - distance[border]
    kept = inside | border
    return y[kept] * width + x[kept], owner[kept], weights[kept], depth[kept]


def _nearest_on_edges(point, a, b, c):
    """(distance (M,), barycentric weights (M, 3)) of each point's nearest point on its triangle's edges."""
    best = np.full(len(point), np.inf)
    weights = np.zeros((len(point), 3))
    for start, end, (i, j) in ((a, b, (0, 1)), (b, c, (1, 2)), (c, a, (2, 0))):
        edge = end - start
        t = np.clip(np.einsum("md,md->m", point - start, edge) / np.maximum(np.einsum("md,md->m", edge, edge),
                                                                           1e-300), 0.0, 1.0)
        distance = np.linalg.norm(start + t[:, None] * edge - point, axis=1)
        closer = distance < best
        best[closer] = distance[closer]
        weights[closer] = 0.0
        weights[closer, i] = 1.0 - t[closer]
        weights[closer, j] = t[closer]
    return best, weights


def _batches(counts, limit):
    """Runs of triangles (indices) whose candidates add up to about `limit`; empty ones left out."""
    nonzero = np.flatnonzero(counts)
    if not len(nonzero):
        return []
    ends = np.cumsum(counts[nonzero])
    cuts = np.searchsorted(ends, np.arange(limit, ends[-1], limit), side="right")
    return [part for part in np.split(nonzero, np.unique(cuts)) if len(part)]


def uv_area(uvs: np.ndarray) -> float:
    """The area triangles (T, 3, 2) cover in UV space (overlaps counted twice)."""
    return float(np.abs(_cross(uvs[:, 1] - uvs[:, 0], uvs[:, 2] - uvs[:, 0])).sum() / 2)


def _cross(u, v):
    return u[..., 0] * v[..., 1] - u[..., 1] * v[..., 0]


# -- receiver points ------------------------------------------------------------------------------------------
def surface_points(triangles, barycentric, corner_positions, corner_normals):
    """World positions, unit normals and unit tangent steps into their own triangle, (N, 3) each, of points given
    by their triangle (N,) and barycentric weights (N, 3); corner_positions and corner_normals (T, 3, 3) per
    triangle corner. The normal is the corner normals interpolated, as Blender shades the face (flat faces: the
    face normal); the step keeps a point near an edge on its own triangle's side, as a vertex's does."""
    weights = barycentric[:, :, None]
    corners = corner_positions[triangles]
    positions = (weights * corners).sum(axis=1)
    normals = _unit((weights * corner_normals[triangles]).sum(axis=1))
    towards_centre = corners.mean(axis=1) - positions
    inward = towards_centre - np.einsum("ij,ij->i", towards_centre, normals)[:, None] * normals
    scale = np.linalg.norm(np.ptp(corner_positions.reshape(-1, 3), axis=0)) if len(corner_positions) else 1.0
    return positions, normals, _unit(inward, floor=1e-12 * scale)


def _unit(vectors, floor=1e-300):
    length = np.linalg.norm(vectors, axis=-1, keepdims=True)
    return np.where(length > floor, vectors / np.maximum(length, floor), 0.0)


# -- images ---------------------------------------------------------------------------------------------------
def to_image(layout: TexelLayout, values: np.ndarray, gutter: int = GUTTER_TEXELS) -> np.ndarray:
    """(height, width, C) float32 image of per-texel `values` (N, C), zero outside the islands but for a gutter of
    `gutter` texels dilated around them."""
    image = np.zeros((layout.height * layout.width, values.shape[1]), dtype=np.float32)
    image[layout.texels] = values
    covered = np.zeros(layout.height * layout.width, dtype=bool)
    covered[layout.texels] = True
    return dilate(image.reshape(layout.height, layout.width, -1), covered.reshape(layout.height, layout.width),
                  gutter)


def dilate(image: np.ndarray, covered: np.ndarray, steps: int) -> np.ndarray:
    """Fills uncovered texels next to covered ones with the mean of their covered 8 neighbours, `steps` times,
    so each island's border values reach `steps` texels into the gutter. Only the ring being filled is averaged
    (a bounded share of the image), so every channel of a map costs little more than its mask."""
    height, width = covered.shape
    values = image.reshape(height * width, -1).copy()
    known = np.pad(covered, 1)  # a frame of uncovered texels: no neighbour test runs off the image
    neighbours = [(dy, dx) for dy in (-1, 0, 1) for dx in (-1, 0, 1) if dx or dy]
    for _ in range(steps):
        near = np.zeros((height, width), dtype=bool)
        for dy, dx in neighbours:
            near |= known[1 + dy: 1 + dy + height, 1 + dx: 1 + dx + width]
        fill_y, fill_x = np.nonzero(near & ~known[1:-1, 1:-1])
        if not len(fill_y):
            break
        total = np.zeros((len(fill_y), values.shape[1]))
        count = np.zeros(len(fill_y))
        for dy, dx in neighbours:
            y, x = fill_y + dy, fill_x + dx
            source = known[y + 1, x + 1]
            total[source] += values[y[source] * width + x[source]]
            count += source
        values[fill_y * width + fill_x] = (total / count[:, None]).astype(values.dtype)
        known[fill_y + 1, fill_x + 1] = True
    return values.reshape(image.shape)


def from_image(layout: TexelLayout, image: np.ndarray) -> np.ndarray:
    """(N, C): the covered texels' rows of an image (height, width, C)."""
    return image.reshape(layout.height * layout.width, -1)[layout.texels]


# -- resolution and memory ------------------------------------------------------------------------------------
def resolution_for_texel_size(world_area: float, uv_area: float, texel_size: float) -> int:
    """The square resolution at which one texel covers about texel_size × texel_size of the surface: the UV map
    holds `world_area` of surface in `uv_area` of the unit square."""
    if world_area <= 0 or uv_area <= 0:
        return SMALLEST_RESOLUTION
    side = np.sqrt(world_area / uv_area) / texel_size
    return clamp_resolution(int(np.ceil(side)))


def resolution_for_target(spacing: float, error: float, target: float, world_area: float, uv_area: float) -> int:
    """The resolution whose texel spacing brings an interpolation error measured at vertex spacing `spacing` down
    to `target`. Across a sharp shadow's edge the RMS error falls only as the square root of the spacing (the
    band of texels the edge crosses narrows, each as wrong as before), the slowest case, so the spacing shrinks
    with the square of target ÷ error; smooth transfer then ends up well below the target."""
    if error <= target or spacing <= 0:
        return resolution_for_texel_size(world_area, uv_area, max(spacing, 1e-12))
    return resolution_for_texel_size(world_area, uv_area, spacing * (target / error) ** 2)


def resolution_for_triangles(triangles: int, uv_area: float) -> int:
    """The resolution at which the triangles get MIN_TEXELS_PER_TRIANGLE texels each on average: a per-face
    lightmap's islands then hold texels inside, not only borders."""
    return clamp_resolution(int(np.ceil(np.sqrt(MIN_TEXELS_PER_TRIANGLE * triangles / max(uv_area, 1e-12)))))


def clamp_resolution(side: int) -> int:
    """Whole multiples of 16 within the supported range."""
    return int(min(LARGEST_RESOLUTION, max(SMALLEST_RESOLUTION, -(-side // 16) * 16)))


def texel_bake_bytes(width: int, height: int, order: int) -> int:
    """Memory a texel bake needs at most for one object (every texel covered): its points while baking and its
    images (coefficients in RGBA float32, the error and the shaded image)."""
    texels = width * height
    coefficients = order * order
    images = texels * 4 * 4 * (-(-coefficients // 4) + 2)
    return texels * (TEXEL_POINT_BYTES + coefficients * TEXEL_COEFFICIENT_BYTES) + images


def sample_bilinear(image: np.ndarray, uvs: np.ndarray) -> np.ndarray:
    """(M, C) values of image (height, width, C), rows from v = 0 as Blender stores them, at uvs (M, 2), filtered as
    Blender's Linear image interpolation with Extend: texel centres at (x + ½) / width, edges clamped."""
    height, width = image.shape[:2]
    x = np.clip(uvs[:, 0] * width - 0.5, 0.0, width - 1.0)
    y = np.clip(uvs[:, 1] * height - 0.5, 0.0, height - 1.0)
    x0, y0 = np.minimum(x.astype(np.int64), width - 2 if width > 1 else 0), np.minimum(y.astype(np.int64),
                                                                                       height - 2 if height > 1 else 0)
    x1, y1 = np.minimum(x0 + 1, width - 1), np.minimum(y0 + 1, height - 1)
    fx, fy = (x - x0)[:, None], (y - y0)[:, None]
    return ((1 - fx) * (1 - fy) * image[y0, x0] + fx * (1 - fy) * image[y0, x1]
            + (1 - fx) * fy * image[y1, x0] + fx * fy * image[y1, x1])

