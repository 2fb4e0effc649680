"""The bake's plain values: what it computes (BakeSettings), the points it bakes (Receiver), what casts shadows
(Occluders) and what a chunk of points gives back (ChunkResult)."""

from dataclasses import dataclass, field
import zlib

import numpy as np

from . import arrays, engines, interreflect, settings as spec
from .ray_caster import RayCaster

MAX_REPLICATES = 16
# Version of the stored layout and conventions; bump when either changes (2: ray origins also move towards
# the inside of each vertex's faces, so a vertex on a seam is seen from its own side; 3: a vertex split by its
# corner normals is baked once per normal and stored per face corner, see blender/storage.py).
CONVENTION_VERSION = 3


@dataclass
class BakeSettings:
    """What a bake computes; defaults and ranges are core.settings'."""
    order: int = spec.ORDER.default
    mode: str = spec.MODE.default
    samples: int = spec.SAMPLES.default
    target_error: float = spec.TARGET_ERROR.default
    max_samples: int = spec.MAX_SAMPLES.default
    # 4 replicates: error 1.4x smaller than 8 at 256 rays (each replicate's lattice is denser) and still an
    # honest estimate (benchmarks/bake.py); 2 under-reports.
    replicates: int = 4
    seed: int = spec.SEED.default
    bounces: int | None = None  # interreflected: a count, or None for 'auto' (until the tail < tolerance)
    bounce_tolerance: float = spec.BOUNCE_TOLERANCE.default
    # 'auto' until the request resolves it to the engine that casts the rays (core.engines.choose)
    ray_engine: str = spec.RAY_ENGINE.default

    def problems(self) -> list[str]:
        """Every reason these settings cannot bake, as sentences for the user."""
        found = [f"{setting.label.lower()} must be {setting.range_text()}{' or auto' if setting.auto else ''}, "
                 f"not {getattr(self, setting.name)!r}"
                 for setting in spec.BAKE if not setting.contains(getattr(self, setting.name))]
        if self.max_samples < self.samples:
            found.append(f"max samples ({self.max_samples}) must be at least samples ({self.samples})")
        most_replicates = min(MAX_REPLICATES, max(self.samples, spec.FEWEST_SAMPLES))  # each needs a ray
        if not 2 <= self.replicates <= most_replicates:
            found.append(f"replicates must be 2-{most_replicates}, not {self.replicates}")
        return found

    @property
    def points_per_replicate(self) -> int:
        return max(1, self.samples // self.replicates)


@dataclass
class Receiver:
    """One object's vertices in world space; `key` makes its random streams independent of other objects."""
    name: str
    positions: np.ndarray  # (V, 3) float64
    normals: np.ndarray    # (V, 3) float64, unit; zero rows are vertices without a surface
    key: int
    # (V, 3) unit tangents from each vertex towards the inside of its faces, zero where there is no inside:
    # a vertex on a seam where another surface stands is baked as seen from its own faces' side.
    inward: np.ndarray | None = None
    # (V,) rows with the same label share their rays (core.corners.ray_groups: the corner points of one vertex
    # whose hemispheres overlap); None: every row casts its own.
    ray_groups: np.ndarray | None = None
    # (V, 3) unit steps from each vertex into its faces along the surface itself (not tangent to the normal), zero
    # where there is none: where a point lies against another surface is judged a step along them. None: `inward`.
    surface_step: np.ndarray | None = None
    # (V,) bool: rows whose normal N points against their faces, measured as Cycles shades them, from behind: with
    # the normal −N, clipped by their face reversed (`clip`; core.corners); None: none.
    against: np.ndarray | None = None
    # (V, 3) the unit normal whose plane clips each row's sky (core.corners.clip_planes: the corners at a vertex of an
    # edge with three or more faces, and those against their faces), zero where none does; None: none does.
    clip: np.ndarray | None = None

    @staticmethod
    def key_for(name: str) -> int:
        return zlib.crc32(name.encode("utf-8"))

    def subset(self, rows: np.ndarray) -> "Receiver":
        """The same receiver with only `rows`, each keeping its per-row arrays."""
        def part(values):
            return None if values is None else values[rows]
        return Receiver(self.name, self.positions[rows], self.normals[rows], self.key, part(self.inward),
                        part(self.ray_groups), part(self.surface_step), part(self.against), part(self.clip))


@dataclass
class Occluders:
    """Triangles that cast shadows, in world space, the points whose hull bounds them, and flat convex polygons
    among them whose shadows are integrated in closed form.

    The first `solved_vertices` vertices are those of the surfaces whose transfer the job solves, in the job's
    order: interreflection reads a hit triangle's corners as solved vertices, so it needs exactly that.
    `engine` names the ray engine that traces them (core.engines). `against` (P,) bool marks the vertices that are
    points whose normal points against their faces (Receiver.against; None: none is), so that contact can see a face
    as its corner at a vertex is shaded (core.contact)."""
    vertices: np.ndarray   # (P, 3) float64
    triangles: np.ndarray  # (T, 3) int
    hull: np.ndarray       # (H, 3) float64: any superset of the convex hull's vertices
    polygons: list = field(default_factory=list)  # (m, 3) float64 corners each; see polygons.py
    solved_vertices: int = 0
    engine: str = engines.DEFAULT
    against: np.ndarray | None = None
    _caster: RayCaster | None = field(default=None, init=False, repr=False, compare=False)

    def ray_caster(self) -> RayCaster:
        """Their ray caster, built on the first call and kept: a bake's jobs share it, and so do processes forked
        afterwards."""
        if self._caster is None:
            self._caster = RayCaster(self)
        return self._caster

    @property
    def center(self) -> np.ndarray:
        if len(self.vertices) == 0:
            return np.zeros(3)
        low, high = arrays.bounds(self.vertices)
        return 0.5 * (low + high)

    @property
    def diagonal(self) -> float:
        if len(self.vertices) == 0:
            return 1.0
        low, high = arrays.bounds(self.vertices)
        return float(np.linalg.norm(high - low)) or 1.0


@dataclass
class ChunkResult:
    transfer: np.ndarray   # (c, n²) float64
    std_error: np.ndarray  # (c,) norm of the coefficients' standard error
    rays: np.ndarray       # (c,) rays cast from each vertex (its estimate also uses its ray group's)
    skipped: np.ndarray    # (c,) bool: exact without rays (provably unoccluded, or in contact)
    rules: np.ndarray      # (c,) uint8: the rule that decided each point (core.rules), MEASURED where none did
    rule_error: np.ndarray  # (c,) the norm of what that rule may have got wrong (core.rules.doubt), 0 where none did
    curve: np.ndarray      # (r, 3) float64: after each of its r ≥ 1 rounds, core.error_curve.CHUNK_COLUMNS
    records: interreflect.HitRecords | None = None  # interreflected mode: blocked rays' hits (chunk-local rows)
