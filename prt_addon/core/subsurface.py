"""Subsurface SH transfer per vertex with the diffusion dipole (Jensen, Marschner, Levoy and Hanrahan 2001),
as D3DX's PRT engine's ComputeSS did.

Relations (per colour channel; σ_s' reduced scattering, σ_a absorption, η the medium's index of refraction
relative to outside):
    σ_t' = σ_s' + σ_a,   α' = σ_s'/σ_t',   σ_tr = √(3 σ_a σ_t')
    F_dr = ∫_0^1 F(μ) 2μ dμ    (the diffuse Fresnel reflectance of light inside meeting the boundary: F is the
                                unpolarised Fresnel reflectance at cosine μ inside, 1 beyond the critical angle)
    A = (1 + F_dr)/(1 − F_dr),   z_r = 1/σ_t',   z_v = z_r (1 + 4A/3),   d = √(r² + z²)
    R_d(r) = α'/(4π) · Σ_{z ∈ {z_r, z_v}} z (1 + σ_tr d) e^{−σ_tr d} / d³
Integrating over the plane (r dr = d dd, and d/dd[−e^{−σd}/d] = (σ/d + 1/d²) e^{−σd}) gives in closed form
    ∫_0^R R_d(r) 2πr dr = α'/2 · Σ_z [e^{−σ_tr z} − (z/d(R)) e^{−σ_tr d(R)}]
whose limit R → ∞ is the total diffuse reflectance (with s = σ_tr/σ_t' = √(3(1 − α'))):
    R_d,total = α'/2 · (1 + e^{−(4/3) A s}) e^{−s}.

F_dr is integrated exactly for any η > 0 (boundary_factor; η < 1 by reciprocity), not with the polynomial fit of
Egan and Hilgeman that Jensen quotes (for η ≥ 1): that drifts from the integral beyond η ≈ 2.3 and exceeds 1 from
η ≈ 3.85 (A < 0, the dipole turns black), while the Principled BSDF's IOR, passed on as η, goes up to 1000.

Material inputs (Jensen and Buhler 2002, "A rapid hierarchical rendering technique for translucent materials"):
Blender's Subsurface Radius × Subsurface Scale is the diffuse mean free path ℓ_d = 1/σ_tr per channel, and the
base colour is the total diffuse reflectance R_d,total. R_d,total decreases monotonically in s ∈ [0, √3]
(from 1 to 0), so s is found by bisection; then σ_t' = σ_tr/s, σ_a = (s²/3) σ_t', σ_s' = (1 − s²/3) σ_t'.

Transfer: a source vertex q stands for a patch of area A_q receiving irradiance E_q = π Σ_k L_k T_k(q), with
T the shadowed direct transfer of core.estimator (which carries 1/π). Jensen's BSSRDF without the directional
Fresnel factors, S_d = R_d(r)/π, makes the exitant radiance at p
    L(p) = (1/π) Σ_q R_d(|p − q|) A_q E_q = Σ_k L_k Σ_q R_d(|p − q|) A_q T_k(q),
so T_sss(p) = Σ_q w_pq T(q) with the π's cancelled, in the same convention as T: radiance = Σ_k L_k T_sss_k,
with the colour already inside (do not multiply by albedo again). Under uniform irradiance E on a flat
semi-infinite slab, L = R_d,total E/π = albedo E/π, exactly a Lambertian surface of the base colour.

Each vertex q stands for a disc of its area A_q = πρ_q² around it. Far from q (r ≥ NEAR_DISC_RADII·ρ_q)
w_pq = R_d(r)·A_q. Nearer, a point sample is poor wherever the profile is sharper than the vertex spacing
(high albedo, small radius: R_d(0) ∝ 1/z_r², and the self term R_d(0)·A_q alone can exceed R_d,total a
thousandfold), so w_pq = A_q · the mean of R_d over q's disc, taken as lying in p's plane: rings around p
carry their exact reflectance (the closed form above), each counted with the share of its area inside the
disc (lens areas). The self term is then exact, no sharpness of the peak is missed, and as ℓ_d → 0,
T_sss → albedo · T.
Coincident vertices (unwelded seams) count as one site of their summed area and summed A·T, or a sharp peak
would count twice.
Distances are straight lines, so light crosses thin parts (and, a known limit of the method, gaps).
"""

from dataclasses import dataclass
from functools import lru_cache

import numpy as np

# At albedo 1 nothing is absorbed and no finite ℓ_d exists (σ_t' = ∞); 0.999 is visibly the same colour.
MAX_DIFFUSE_ALBEDO = 0.999
# Radii (Blender units) below this are taken as this: the profile is far below any vertex spacing anyway.
MIN_MEAN_FREE_PATH = 1e-9
# The default gather radius loses at most this fraction of the total diffuse reflectance in any channel.
TAIL_FRACTION = 1e-3
# Cells per axis at most, so integer cell coordinates stay small whatever the radius (a tiny radius only
# makes most cells hold one vertex).
MAX_CELLS_PER_AXIS = 1 << 20
# Pairs nearer than this many disc radii of the source use the disc's mean profile, split into RING_STEPS
# rings. On a flat grid the gathered total is then within about 1 % of R_d,total for spacings of 0.05-1 ℓ_d
# and albedos of 0.05-0.99, that is whether the profile is much wider or much sharper than the spacing.
NEAR_DISC_RADII = 4.0
RING_STEPS = 8
# Values of (pairs × 3 channels × coefficients) held at once by the gather: 32 MB of float64.
BLOCK_VALUES = 1 << 22
_BISECTION_STEPS = 64
# s is bisected further: where F_dr ≈ 1 (A up to 4e8 at η = 1000) R_d,total falls from 1 to 1/2 within s ≲ 1/A and
# is as steep as A/2 there; 96 halvings of [0, √3] leave R_d,total within rounding of the albedo (64: 7e-12).
_S_BISECTION_STEPS = 96
# η is clamped to [1/MAX_IOR, MAX_IOR], a range reciprocity maps onto itself (the Principled BSDF's IOR slider
# ends at 1000; F_dr is then within 6e-9 of 1, and far beyond it 1 − F_dr ∝ η⁻³ would underflow).
MAX_IOR = 1000.0
# Gauss-Legendre nodes on [0, 1] for the boundary's transmittance 1 − F_dr (see _boundary_transmittance): within
# a relative 2e-14 of the integral (checked against its closed form in 80-digit decimals) for η (or 1/η) from
# 1 + 1e-7 to 1000, 5e-13 nearer to 1. (64 nodes without the stretch would be 3e-6 off at η = 1000.)
_FRESNEL_NODES, _FRESNEL_WEIGHTS = np.polynomial.legendre.leggauss(48)
_FRESNEL_NODES, _FRESNEL_WEIGHTS = 0.5 * (_FRESNEL_NODES + 1.0), 0.5 * _FRESNEL_WEIGHTS


@dataclass(frozen=True)
class DipoleParameters:
    """Per-channel (3,) coefficients in 1/length, and the relative index of refraction η."""
    sigma_s_prime: np.ndarray
    sigma_a: np.ndarray
    ior: float

    @property
    def sigma_t_prime(self):
        return self.sigma_s_prime + self.sigma_a

    @property
    def reduced_albedo(self):
        return self.sigma_s_prime / self.sigma_t_prime

    @property
    def sigma_tr(self):
        return np.sqrt(3.0 * self.sigma_a * self.sigma_t_prime)

    @property
    def z_r(self):
        return 1.0 / self.sigma_t_prime

    @property
    def z_v(self):
        return self.z_r * (1.0 + 4.0 * boundary_factor(self.ior) / 3.0)


@lru_cache(maxsize=64)
def _boundary_transmittance(ior: float) -> float:
    """1 − F_dr = ∫_0^1 (1 − F(μ)) 2μ dμ for light inside a medium of relative index η > 0 (see boundary_factor)."""
    if ior == 1.0:
        return 1.0
    if ior < 1.0:
        # Reciprocity: light crossing the boundary from either side, 1 − F_dr(η) = (1 − F_dr,outside(η))/η²,
        # and light inside a medium of index η < 1 sees the interface as light outside one of index 1/η does,
        # F_dr(η) = F_dr,outside(1/η): together 1 − F_dr(η) = (1 − F_dr(1/η))/η². No total internal reflection.
        return _boundary_transmittance(1.0 / ior) / (ior * ior)
    # For μ below the critical cosine μ_c = √(1 − 1/η²) all is reflected (the F = 1 part of F_dr is μ_c²): only
    # [μ_c, 1] transmits. There the cosine outside, η√(μ² − μ_c²), has a square-root kink at μ_c, which
    # μ = μ_c + (1 − μ_c) x² turns into an analytic integrand in x ∈ [0, 1]: the cosine outside is
    # η x √((1 − μ_c)(μ + μ_c)), and dμ = 2(1 − μ_c) x dx. The p wave's transmittance then varies on a scale 1/η
    # near x = 0 (a pole at x ≈ −1/η), which x = (e^{λy} − 1)/(e^λ − 1) with λ = ln(1 + η) moves to y = −∞; the
    # nodes are in y ∈ [0, 1].
    stretch = np.log1p(ior)
    x = np.expm1(stretch * _FRESNEL_NODES) / np.expm1(stretch)
    dx_dy = stretch * (x + 1.0 / np.expm1(stretch))
    inverse_square = 1.0 / (ior * ior)
    critical = np.sqrt(1.0 - inverse_square)
    span = inverse_square / (1.0 + critical)  # 1 − μ_c without cancellation at large η
    inside = critical + span * x * x
    outside = ior * x * np.sqrt(span * (inside + critical))
    # Transmittance 1 − F of unpolarised light, s and p apart: 4ab/(a + b)² has no cancellation where F ≈ 1.
    s_a, s_b = ior * inside, outside
    p_a, p_b = ior * outside, inside
    transmitted = 2.0 * s_a * s_b / (s_a + s_b) ** 2 + 2.0 * p_a * p_b / (p_a + p_b) ** 2
    return float(np.dot(_FRESNEL_WEIGHTS, transmitted * 2.0 * inside * 2.0 * span * x * dx_dy))


def diffuse_fresnel_reflectance(ior):
    """F_dr = ∫_0^1 F(μ) 2μ dμ for light inside a medium of relative index η > 0 meeting its boundary."""
    return 1.0 - _boundary_transmittance(float(ior))


def boundary_factor(ior):
    """A = (1 + F_dr)/(1 − F_dr) for a medium of relative index η > 0, F_dr = ∫_0^1 F(μ) 2μ dμ integrated exactly
    (not Egan and Hilgeman's fit): 1 at η = 1, rising on both sides (η < 1 by reciprocity, see
    _boundary_transmittance), ≈ (3/8) η³ for large η. Cached per η: the dipole's z_v asks for it often."""
    transmitted = _boundary_transmittance(float(ior))
    return (2.0 - transmitted) / transmitted


def _total_reflectance_of(s, boundary):
    """R_d,total as a function of s = √(3(1 − α')): decreasing from 1 at s = 0 to 0 at s = √3."""
    return 0.5 * (1.0 - s * s / 3.0) * (1.0 + np.exp(-4.0 / 3.0 * boundary * s)) * np.exp(-s)


def _solve_for_s(albedo, boundary):
    """Bisection for R_d,total(s) = albedo; bisecting s (not α') keeps full relative precision near α' = 1."""
    low, high = np.zeros_like(albedo), np.full_like(albedo, np.sqrt(3.0))
    for _ in range(_S_BISECTION_STEPS):
        middle = 0.5 * (low + high)
        too_bright = _total_reflectance_of(middle, boundary) > albedo
        low, high = np.where(too_bright, middle, low), np.where(too_bright, high, middle)
    return 0.5 * (low + high)


def dipole_parameters(mean_free_path_rgb, albedo_rgb, ior) -> DipoleParameters:
    """Subsurface Radius × Scale (ℓ_d = 1/σ_tr), base colour (R_d,total) and IOR (η) → σ_s', σ_a per channel.

    The albedo is clamped to [0, MAX_DIFFUSE_ALBEDO], ℓ_d to at least MIN_MEAN_FREE_PATH, η to
    [1/MAX_IOR, MAX_IOR]. η < 1 (allowed by the Principled BSDF) is a medium optically thinner than outside: its
    boundary reflects without total internal reflection, F_dr rising again from 0 at η = 1 (see boundary_factor)."""
    mean_free_path = np.maximum(np.asarray(mean_free_path_rgb, dtype=np.float64), MIN_MEAN_FREE_PATH)
    albedo = np.clip(np.asarray(albedo_rgb, dtype=np.float64), 0.0, MAX_DIFFUSE_ALBEDO)
    ior = min(max(float(ior), 1.0 / MAX_IOR), MAX_IOR)
    s = _solve_for_s(albedo, boundary_factor(ior))
    reduced_albedo = np.where(albedo > 0.0, 1.0 - s * s / 3.0, 0.0)  # bisection leaves ~1e-19 at albedo 0
    sigma_t_prime = 1.0 / (mean_free_path * s)
    return DipoleParameters(sigma_s_prime=reduced_albedo * sigma_t_prime, sigma_a=s * s / 3.0 * sigma_t_prime,
                            ior=ior)


def _sum_over_sources(term, r, params):
    """term(r², z, σ_tr) summed over the real and the virtual source, per channel: r (...) → (..., 3).
    One channel and source at a time: long contiguous loops, several times faster than broadcasting."""
    r_squared = np.square(np.asarray(r, dtype=np.float64))
    total = np.empty(r_squared.shape + params.sigma_a.shape)
    for channel, (z_r, z_v, sigma_tr) in enumerate(zip(params.z_r, params.z_v, params.sigma_tr)):
        total[..., channel] = term(r_squared, z_r, sigma_tr) + term(r_squared, z_v, sigma_tr)
    return total


def _source_profile(r_squared, z, sigma_tr):
    """z (1 + σ_tr d) e^{−σ_tr d} / d³: one source's share of R_d(r), up to α'/4π."""
    d = np.sqrt(r_squared + z * z)
    return z * (1.0 + sigma_tr * d) * np.exp(-sigma_tr * d) / (d * d * d)


def _source_beyond(r_squared, z, sigma_tr):
    """(z/d) e^{−σ_tr d}: one source's share of ∫_R^∞ R_d 2πr dr, up to α'/2."""
    d = np.sqrt(r_squared + z * z)
    return z / d * np.exp(-sigma_tr * d)


def diffuse_reflectance_profile(r, params: DipoleParameters) -> np.ndarray:
    """R_d(r) per channel: r (...) → (..., 3); finite at r = 0 since d ≥ z_r > 0."""
    return params.reduced_albedo / (4.0 * np.pi) * _sum_over_sources(_source_profile, r, params)


def reflectance_within(radius, params: DipoleParameters) -> np.ndarray:
    """∫_0^R R_d(r) 2πr dr in closed form: R (...) → (..., 3); R = ∞ gives the total diffuse reflectance."""
    return 0.5 * params.reduced_albedo * (_sum_over_sources(_source_beyond, 0.0, params)
                                          - _sum_over_sources(_source_beyond, radius, params))


def default_max_radius(params: DipoleParameters) -> float:
    """The smallest R beyond which at most TAIL_FRACTION of R_d,total lies, in every channel that scatters.

    (A cut where R_d falls to 1e-4 of R_d(0) would lose up to 8 % of it at high albedo, where the peak is
    sharpest, and reach further than needed at low albedo.)
    The tail fraction is at most 2e^{−σ_tr R}/e^{−√3} < 12 e^{−R/ℓ_d}, which brackets the bisection."""
    target = TAIL_FRACTION * _sum_over_sources(_source_beyond, 0.0, params)
    high = np.log(12.0 / TAIL_FRACTION) / params.sigma_tr
    low = np.zeros_like(high)
    for _ in range(_BISECTION_STEPS):
        middle = 0.5 * (low + high)
        too_short = np.diagonal(_sum_over_sources(_source_beyond, middle, params)) > target  # own R each
        low, high = np.where(too_short, middle, low), np.where(too_short, high, middle)
    return float(np.max(np.where(params.reduced_albedo > 0.0, high, 0.0)))


def _lens_area(a, b, r):
    """Area of the intersection of two discs of radii a ≥ 0 and b > 0 whose centres are r apart (broadcast).

    Half-chord and half-angles through atan2 stay well conditioned where the circles touch (arccos of a
    cosine near 1 would turn rounding into errors of 1e-8); r = 0 is taken as 1e-12·b, its limit."""
    r = np.maximum(r, 1e-12 * b)
    kite = (a + b - r) * (r + a - b) * (r - a + b) * (a + b + r)
    half_chord = np.sqrt(np.maximum(kite, 0.0)) / (2.0 * r)
    to_chord = (r * r + a * a - b * b) / (2.0 * r)  # signed distance from a's centre to the common chord
    return (a * a * np.arctan2(half_chord, to_chord) + b * b * np.arctan2(half_chord, r - to_chord)
            - r * half_chord)


def disc_mean_profile(r, disc_radius, params: DipoleParameters) -> np.ndarray:
    """Mean of R_d(|p − x|) over x in a disc of radius ρ > 0 whose centre is r from p, in p's plane:
    r, ρ (P,) → (P, 3).

    Rings around p carry their exact reflectance (reflectance_within); each counts with the share of its area
    inside the disc. Only the share's variation across each of RING_STEPS rings from |r − ρ| to r + ρ is
    approximated; the ring [0, |r − ρ|] lies wholly inside (r < ρ) or outside, so a sharp peak at p is exact."""
    r = np.asarray(r, dtype=np.float64)[:, None]
    disc_radius = np.asarray(disc_radius, dtype=np.float64)[:, None]
    inner = np.abs(r - disc_radius)
    steps = np.linspace(0.0, 1.0, RING_STEPS + 1)
    radii = np.concatenate([np.zeros_like(r), inner + (r + disc_radius - inner) * steps], axis=1)
    ring_reflectance = np.diff(reflectance_within(radii, params), axis=1)
    ring_area = np.diff(np.pi * radii * radii, axis=1)
    inside = np.diff(_lens_area(radii, disc_radius, r), axis=1)
    share = inside / np.maximum(ring_area, np.finfo(np.float64).tiny)  # an empty ring (r = ρ) counts 0
    return np.einsum("pk,pkc->pc", share, ring_reflectance) / (np.pi * disc_radius * disc_radius)


def vertex_areas(positions, triangles) -> np.ndarray:
    """(V,) one third of the area of every triangle around each vertex."""
    positions = np.asarray(positions, dtype=np.float64)
    triangles = np.asarray(triangles, dtype=np.int64).reshape(-1, 3)
    corners = positions[triangles]
    thirds = np.linalg.norm(np.cross(corners[:, 1] - corners[:, 0], corners[:, 2] - corners[:, 0]), axis=1) / 6.0
    return np.bincount(triangles.ravel(), weights=np.repeat(thirds, 3), minlength=len(positions))


def subsurface_transfer(positions, normals, areas, incident_transfer, params: DipoleParameters,
                        max_radius=None) -> np.ndarray:
    """T_sss (V, 3, n²) from the incident (shadowed direct) transfer: see the module docstring.

    incident_transfer is (V, n²), grey light that every channel scatters with its own profile, or (V, 3, n²),
    coloured light whose channel c scatters with channel c's profile. Sources within max_radius (default:
    default_max_radius) are gathered through a uniform grid; vertices with a zero normal have no surface and
    neither receive nor pass on light."""
    positions = np.asarray(positions, dtype=np.float64)
    incident = np.asarray(incident_transfer, dtype=np.float64)
    has_surface = np.abs(np.asarray(normals)).sum(-1) > 0
    areas = np.where(has_surface, np.asarray(areas, dtype=np.float64), 0.0)
    radius = default_max_radius(params) if max_radius is None else float(max_radius)
    count, coefficients, channels = len(incident), incident.shape[-1], len(params.sigma_a)
    width = channels * coefficients
    sites, site_of = np.unique(positions, axis=0, return_inverse=True)
    site_of = site_of.reshape(-1)
    site_area = np.bincount(site_of, weights=areas, minlength=len(sites))
    site_radius = np.sqrt(site_area / np.pi)
    # Σ A·T over each site's vertices, (sites, 1 or 3, n²): grey light broadcasts over the channels.
    light_channels = channels if incident.ndim == 3 else 1
    site_flux = np.zeros((len(sites), light_channels, coefficients))
    np.add.at(site_flux, site_of, areas[:, None, None] * incident.reshape(count, light_channels, coefficients))
    gathered = np.zeros((len(sites), width))
    for receivers, sources, distance in _pairs_within(sites, radius, max(1, BLOCK_VALUES // width)):
        weight = diffuse_reflectance_profile(distance, params)
        near = distance < NEAR_DISC_RADII * site_radius[sources]
        weight[near] = disc_mean_profile(distance[near], site_radius[sources[near]], params)
        contribution = (weight[:, :, None] * site_flux[sources]).reshape(-1, width)
        # Pairs come in runs of one receiver (a receiver against a source cell): sum each run first.
        run_starts = np.flatnonzero(np.diff(receivers, prepend=-1))
        if len(run_starts):
            np.add.at(gathered, receivers[run_starts], np.add.reduceat(contribution, run_starts, axis=0))
    transfer = gathered[site_of].reshape(count, channels, coefficients)
    transfer[~has_surface] = 0.0
    return transfer


def _grid_cells(positions, cell_size):
    """Vertices sorted by cell, and each occupied cell's key, first index into that order and vertex count;
    `neighbour_steps` are the key offsets of the 27 cells around a cell."""
    low = positions.min(0)
    extent = float(np.max(positions.max(0) - low))
    # A little larger than asked, so rounding never puts two points within cell_size two cells apart.
    cell_size = max(cell_size, extent / MAX_CELLS_PER_AXIS, np.finfo(np.float64).tiny) * (1.0 + 1e-6)
    # +1: a border cell's neighbours keep coordinates ≥ 0, so keys never wrap into another row.
    coords = np.floor((positions - low) / cell_size).astype(np.int64) + 1
    dims = coords.max(0) + 2
    keys = (coords[:, 0] * dims[1] + coords[:, 1]) * dims[2] + coords[:, 2]
    order = np.argsort(keys, kind="stable")
    cell_keys, starts, counts = np.unique(keys[order], return_index=True, return_counts=True)
    steps = np.array([-1, 0, 1])
    neighbour_steps = ((steps[:, None, None] * dims[1] + steps[None, :, None]) * dims[2]
                       + steps[None, None, :]).ravel()
    return order, cell_keys, starts, counts, neighbour_steps


def _pairs_within(positions, radius, block_pairs):
    """Yields (receivers, sources, distances) of every ordered pair of points (self pairs included) at most
    `radius` apart, testing at most `block_pairs` candidate pairs (from adjacent cells) at a time."""
    if len(positions) == 0:
        return
    order, cell_keys, starts, counts, neighbour_steps = _grid_cells(positions, radius)
    neighbours = cell_keys[:, None] + neighbour_steps[None, :]
    found = np.searchsorted(cell_keys, neighbours).clip(max=len(cell_keys) - 1)
    receiver_cell, step = np.nonzero(cell_keys[found] == neighbours)
    source_cell = found[receiver_cell, step]
    sizes = counts[receiver_cell] * counts[source_cell]
    ends = np.cumsum(sizes)
    radius_squared = radius * radius
    for first in range(0, int(ends[-1]), block_pairs):
        # Candidate t of cell pair c is (receiver i, source j) = divmod(t − start of c, sources in c).
        candidate = np.arange(first, min(first + block_pairs, int(ends[-1])))
        pair = np.searchsorted(ends, candidate, side="right")
        i, j = np.divmod(candidate - (ends[pair] - sizes[pair]), counts[source_cell[pair]])
        receivers = order[starts[receiver_cell[pair]] + i]
        sources = order[starts[source_cell[pair]] + j]
        offsets = positions[receivers] - positions[sources]
        distance_squared = np.einsum("ij,ij->i", offsets, offsets)
        close = distance_squared <= radius_squared
        yield receivers[close], sources[close], np.sqrt(distance_squared[close])
