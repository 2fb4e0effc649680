"""Checks before any ray: findings graded error, warning, info or ok, what a bake will cost in memory and time,
and whether a path can be written. Errors stop a bake before work is spent; the rest is listed.

Only arithmetic and the operating system's figures: no ray is cast and nothing written. What is gathered from
Blender's data is blender/checks.py's."""

from dataclasses import dataclass
import os

from . import bake, engines, outputs
from .errors import InputError
from .progress import format_duration

ERROR, WARNING, INFO, OK = "error", "warning", "info", "ok"
LEVELS = (ERROR, WARNING, INFO, OK)

# Memory, in bytes, measured or read off the arrays the bake allocates:
POINT_BYTES = 9 * 8 + 8 + 8 + 1      # positions, normals, inward (float64 × 3 each); std error, rays, skipped
OCCLUDER_VERTEX_BYTES = 2 * 3 * 8    # world positions and the recentred copy the ray caster keeps
TRIANGLE_BYTES = 8 * 3 + 114         # indices, and mathutils' BVHTree: 114 bytes a triangle (178 k triangles)
EMBREE_TRIANGLE_BYTES = 110          # Embree's scene beside the BVHTree its engine keeps (1.4 M triangles)
PROCESS_BYTES = 64 << 20             # a process's chunk at work: 32 MB of basis values (REPLICATE_VALUES_AT_ONCE)
SPAWNED_BYTES = 256 << 20            # a spawned worker itself: Blender, or Python with bpy (257 MB measured)
HIT_BYTES = 48 + 170                 # a recorded hit (vertex, triangle, barycentric, weight) and its share of the
#                                      bounce operator while it is built (corners, rows, columns, sorting keys)
HITS_PER_RAY = 1.0                   # an interreflected ray records its first hit, if any: counted as hitting,
#                                      since only casting the rays would tell how many miss
WARN_FRACTION = 0.8                  # of the available memory: beyond it the machine may start to swap



@dataclass(frozen=True)
class Check:
    """One finding: its level, what it is about (an object's name, the output, memory, time) and the problem or
    the figure, in words; for a fault of a mesh, (object name, fault) to select its faces by (blender.fault_checks)."""
    level: str
    subject: str
    text: str
    select: tuple = ()

    def line(self) -> str:
        return f"{self.level:<7} {self.subject}: {self.text}"


def errors(checks) -> list[Check]:
    return [check for check in checks if check.level == ERROR]


def stop_on_errors(checks):
    """Raises InputError naming every error, so nothing is baked."""
    found = errors(checks)
    if found:
        raise InputError("; ".join(f"{check.subject}: {check.text}" for check in found) + "; nothing was baked")


# -- paths --------------------------------------------------------------------------------------------------------
def writable_check(path: str, subject: str, required: bool) -> Check:
    """Whether a file can be saved at `path`, by outputs.unwritable's rule (missing folders are created when
    saving). A problem is an error where saving is `required`, else a warning."""
    problem = outputs.unwritable(path)
    if problem:
        return Check(ERROR if required else WARNING, subject, problem)
    return Check(OK, subject, f"{os.path.abspath(path)} can be written")


def workers_check(processes: int, temporary_folder: str) -> Check:
    """Workers read the job from a file in the temporary folder and leave their results there; they never read the
    .blend file, so an unsaved file bakes with workers as well."""
    if processes == 1:
        return Check(OK, "workers", "one process (too few rays to repay starting workers)")
    if not os.path.isdir(temporary_folder) or not os.access(temporary_folder, os.W_OK | os.X_OK):
        return Check(ERROR, "workers", f"{processes} processes exchange the job through the temporary folder "
                                       f"{temporary_folder}, which cannot be written; set TMPDIR to a writable "
                                       f"folder, or bake with 1 worker")
    return Check(OK, "workers", f"{processes} processes, sharing the job through {temporary_folder}")


# -- memory ---------------------------------------------------------------------------------------------------------
@dataclass(frozen=True)
class BakeSize:
    """What a bake holds, counted before it starts."""
    points: int               # shading points solved (receivers, and bouncers in interreflected bakes)
    stored_rows: int          # rows written on the receivers' meshes: points, or face corners where split
    split_corners: int        # face corners of split meshes (their `_prt_point` attribute)
    occluder_vertices: int
    occluder_triangles: int
    order: int
    channels: int             # 1 grey, 3 coloured (interreflected bakes over coloured albedo)
    rays: int                 # the first round's rays: points × samples (0 without rays)
    hits_per_ray: float       # recorded hits per ray: interreflected, at most one (HITS_PER_RAY), else 0
    processes: int            # processes that cast rays
    spawned: bool             # spawned workers load their own copy of the job
    ray_engine: str = "bvhtree"  # the engine that casts them (core.engines)
    probe_values: int = 0     # the probe volumes' matrices: probes × channels × N² × n² (core.probe_transfer)

    @property
    def coefficients(self) -> int:
        return self.order * self.order


def bake_bytes(size: BakeSize) -> int:
    """Peak memory of the bake in this process and its workers: the points and their transfer, the occluders and
    their ray engine (once more per spawned worker, which is a Blender of its own), each process's working chunk,
    and in interreflected bakes the recorded hits and the bounce operator built from them; the probes' matrices
    (float64)."""
    transfer = size.points * size.coefficients * size.channels * (4 + 3 * 8)  # float32 result, float64 bounces
    per_triangle = TRIANGLE_BYTES + (EMBREE_TRIANGLE_BYTES if size.ray_engine == "embree" else 0)
    scene = size.occluder_vertices * OCCLUDER_VERTEX_BYTES + size.occluder_triangles * per_triangle
    spawned = size.processes - 1 if size.spawned else 0
    hits = int(size.rays * size.hits_per_ray * HIT_BYTES)
    return ((size.points * POINT_BYTES + scene) * (1 + spawned) + transfer + size.processes * PROCESS_BYTES + hits
            + spawned * SPAWNED_BYTES + size.probe_values * 8)


def stored_bytes(size: BakeSize) -> int:
    """The attributes written on the meshes (kept in memory and in the saved file): float32 vectors of 3
    coefficients per channel, the error, the rule that decided each row (int32), and each split corner's point; and
    the probes' float32 matrices."""
    vectors = -(-size.coefficients // 3) * 3
    return size.stored_rows * (vectors * size.channels + 2) * 4 + size.split_corners * 4 + size.probe_values * 4


def available_memory() -> int | None:
    """Bytes the system can still give without swapping: MemAvailable from /proc/meminfo (Linux), else the free
    physical pages; None where neither is known."""
    try:
        with open("/proc/meminfo", encoding="ascii") as meminfo:
            for line in meminfo:
                if line.startswith("MemAvailable:"):
                    return int(line.split()[1]) * 1024
    except OSError:
        pass
    try:
        return os.sysconf("SC_AVPHYS_PAGES") * os.sysconf("SC_PAGE_SIZE")
    except (ValueError, OSError, AttributeError):
        return None


def memory_check(sizes: list[BakeSize], available: int | None) -> Check:
    """The bake of `sizes`, its parts, baked one after another: its peak is its largest part's, and every part's
    result is kept until all are stored."""
    needed, stored = max(bake_bytes(size) for size in sizes), sum(stored_bytes(size) for size in sizes)
    said = f"the bake needs about {format_bytes(needed)}, its result {format_bytes(stored)}"
    if available is None:
        return Check(INFO, "memory", f"{said}; the memory available is unknown here")
    if needed + stored > available:
        return Check(ERROR, "memory", f"{said}, more than the {format_bytes(available)} available; lower the order, "
                                      f"the samples or the workers, or bake fewer objects or probes at a time")
    if needed + stored > WARN_FRACTION * available:
        return Check(WARNING, "memory", f"{said}, close to the {format_bytes(available)} available")
    return Check(OK, "memory", f"{said}, of {format_bytes(available)} available")


def format_bytes(count: int) -> str:
    for unit, scale in (("GB", 1 << 30), ("MB", 1 << 20), ("kB", 1 << 10)):
        if count >= scale:
            return f"{count / scale:.1f} {unit}"
    return f"{count} B"


# -- time -----------------------------------------------------------------------------------------------------------
def estimated_seconds(rays: int, triangles: int, engine: str, processes: int, start_s: float = 0.0) -> float:
    """The first round's time at the engine's typical rates (core.engines.RATES): its ray tree over the triangles,
    built once, the workers' start, and the rays shared by the processes."""
    if not rays:
        return 0.0
    rate = engines.RATES[engine]
    return triangles / rate.triangles_per_s + start_s + rays / rate.rays_per_s / max(1, processes)


def time_check(rays: int, seconds: float, engine: str, settings: bake.BakeSettings, processes: int) -> Check:
    """The first round's time, estimated from its rays (estimated_seconds), and what may add to it."""
    if not rays:
        return Check(OK, "time", "no rays to cast: the transfer is exact in closed form")
    said = (f"about {format_duration(seconds)} with {processes} process{'es' if processes > 1 else ''} "
            f"({rays} rays at a typical {engines.RATES[engine].rays_per_s / 1e3:.0f} k rays/s a process with "
            f"{engine}; the bake's report gives this machine's rate)")
    if settings.target_error > 0:
        said += f"; the target error may add rounds, up to {settings.max_samples // settings.samples}× the rays"
    if settings.mode == "interreflected":
        said += ", plus the bounces"
    return Check(INFO, "time", said)
