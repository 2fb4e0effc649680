"""A farm's part files (core.shards) read as untrusted input: a part comes from another machine over shared
storage, and may be truncated, corrupted, or made to harm whoever merges it.

Nothing large is allocated or decompressed before the scene says how large it may be. The description (read_part)
is a string of at most DESCRIPTION_CHARS characters, every field of the type and range a shard writes. The chunks
(load_part) are read once the scene is gathered: each zip member's declared size is held to what the scene's chunk
can hold before it is opened, each .npy header's shape and dtype compared with the scene's, then the data read
(never a pickle) and every value checked against what a bake produces. Each refusal is an InputError of one line:
the part's path and its problem.
"""

from contextlib import contextmanager
from dataclasses import asdict, dataclass, fields
import json
import math
import struct
import zipfile
import zlib

import numpy as np

from . import rules as decided
from .bake import BakeSettings, ChunkResult
from .error_curve import CHUNK_COLUMNS
from .errors import InputError
from .interreflect import HitRecords
from .job_file import RESULT_ARRAYS
from .scheduling import MAX_ROUNDS
from .shards import PART_FORMAT, PROBES, PartInfo, shown
from .workers import shard_chunks

# The description's JSON: a receiver takes about 300 characters (its name thrice, five digests), so some 10 000.
DESCRIPTION_CHARS = 1 << 22
HEADER_BYTES = 10_000  # the largest .npy header numpy itself parses (np.lib.format's max_header_size)
# A hit's barycentric weights are clipped to [0, 1] (interreflect.barycentric); their sum is 1 but for rounding.
BARYCENTRIC_SLACK = 1e-9
# What np.savez and np.savez_compressed write. Deflate is read in bounded pieces; bzip2 and LZMA members are
# decompressed a whole compressed block at a time, a bomb's gigabytes before any size is checked.
COMPRESSIONS = {zipfile.ZIP_STORED, zipfile.ZIP_DEFLATED}
# What a damaged archive, .npy header or JSON raises as it is read: each is told as the part being unreadable.
UNREADABLE = (OSError, EOFError, zipfile.BadZipFile, zipfile.LargeZipFile, zlib.error, struct.error, ValueError,
              NotImplementedError, RuntimeError, OverflowError)


@dataclass
class PartShape:
    """What the scene says each part of its bake holds: how many points each chunk has, and how large and which
    values its arrays may have."""
    rows: list          # points in each of the bake's chunks, in order
    probe_rows: list    # points in each of its chunks of points between vertices
    coefficients: int   # order²
    records: bool       # interreflected: the vertices' chunks carry their blocked rays' hit records
    triangles: int      # the occluders' triangles a hit lands on
    replicates: int
    most_rays: int      # most rays a point's estimate uses (and records): twice its budget, as the target error's
    #                     last round may overshoot the budget by a lattice size (scheduling.next_rounds)

    @staticmethod
    def of(job, probe_job) -> "PartShape":
        """The shape of parts of the bake of `job` (a core.job.TransferJob of the vertices) and `probe_job`."""
        settings = job.settings
        return PartShape([len(rows) for _, rows in job.chunks], [len(rows) for _, rows in probe_job.chunks],
                         settings.order ** 2, settings.mode == "interreflected",
                         0 if job.occluders is None else len(job.occluders.triangles), settings.replicates,
                         2 * max(settings.samples, settings.max_samples))


class _Refused(Exception):
    """A part's problem, in words after its path."""


def _check(holds: bool, problem: str):
    """Refuses the part with `problem` unless `holds`."""
    if not holds:
        raise _Refused(problem)


@contextmanager
def _refusing(path: str):
    """Turns what reading the part at `path` raises into one line naming it."""
    try:
        yield
    except _Refused as refused:
        raise InputError(f"{path} {refused}") from None
    except FileNotFoundError:
        raise InputError(f"no such part file: {path}") from None
    except UNREADABLE as error:
        told = shown(" ".join(str(error).split()), 120)
        raise InputError(f"{path} is not a readable PRT part file ({type(error).__name__}: {told})") from None


def read_part(path: str) -> PartInfo:
    """A part's description, every field of the type and range a shard writes; what the part holds is read by
    load_part, once the scene says how much it may be."""
    with _refusing(path), zipfile.ZipFile(path) as archive:
        _check("part.npy" in archive.namelist(), "is not a PRT part file (written by prt bake --shard): it holds no "
                                                 "description")
        text = _read(archive, "part", _description_header, DESCRIPTION_CHARS * 4)
        return _info(json.loads(str(text[()])))


def load_part(path: str, info: PartInfo, shape: PartShape) -> tuple[list, list]:
    """The part's (chunk index, ChunkResult) pairs, of its vertices' chunks and of its probes', each array of the
    shape `shape` (the scene) says and every value one a bake makes. `info`: its description, accepted as shard K/N
    of this scene's bake (shards.refusals)."""
    shares = [shard_chunks(len(rows), info.shard, info.shards) for rows in (shape.rows, shape.probe_rows)]
    with _refusing(path), zipfile.ZipFile(path) as archive:
        for prefix, share in zip(("", PROBES), shares):
            chunks = _read(archive, prefix + "chunks", _exactly(np.int64, (None,), len(share)), 8 * len(share))
            _check(chunks.tolist() == share, f"does not hold shard {info.shard}/{info.shards}'s chunks")
        _members(archive, _member_names(shares, shape))
        return ([(index, _chunk(archive, "", slot, shape.rows[index], shape, shape.records))
                 for slot, index in enumerate(shares[0])],
                [(index, _chunk(archive, PROBES, slot, shape.probe_rows[index], shape, False))
                 for slot, index in enumerate(shares[1])])


# -- the description -----------------------------------------------------------------------------------------------

def _description_header(shape, dtype) -> str | None:
    """A header check: the description is one string of at most DESCRIPTION_CHARS characters."""
    if shape != () or dtype.kind != "U" or dtype.itemsize > 4 * DESCRIPTION_CHARS:
        return f"of {dtype} {shape}, not a description (a string of at most {DESCRIPTION_CHARS} characters)"
    return None


def _info(meta) -> PartInfo:
    """The description read from JSON, or refused: this format, PartInfo's fields each of its type and range, the
    settings a bake takes, a fingerprint of every receiver."""
    _check(isinstance(meta, dict), "is not a PRT part file (its description is not a JSON object)")
    _check(meta.get("format") == PART_FORMAT, f"is a part file of another format than {PART_FORMAT}")
    kinds = {field.name: field.type for field in fields(PartInfo)}
    _check(set(meta) == {"format", *kinds}, f"has a description of other fields than a {PART_FORMAT} part's")
    info = PartInfo(**{name: _field(name, meta[name], kind) for name, kind in kinds.items()})
    _settings(info.settings)
    _check(set(info.fingerprints) == set(info.receivers)
           and all(isinstance(digests, dict) and all(isinstance(value, str) for value in digests.values())
                   for digests in info.fingerprints.values()),
           "has a description whose fingerprints are not its receivers' digests")
    return info


def _field(name: str, value, kind):
    """`value` as the field `name` of PartInfo holds it, or refused: whole numbers and seconds ≥ 0, names."""
    if kind is int:
        holds, wanted = type(value) is int and value >= 0, "a whole number ≥ 0"
    elif kind is float:
        holds = type(value) in (int, float) and math.isfinite(value) and value >= 0
        value, wanted = float(value) if holds else value, "a number of seconds ≥ 0"
    elif kind is list:
        holds, wanted = isinstance(value, list) and all(type(item) is str for item in value), "a list of names"
    else:
        holds, wanted = isinstance(value, kind), kind.__name__
    _check(holds, f"has a description whose {name} is {shown(repr(value))}, not {wanted}")
    return value


def _settings(settings: dict):
    """Refuses settings a bake would not take: each of BakeSettings' fields, of its default's type."""
    defaults = asdict(BakeSettings())
    _check(set(settings) == set(defaults), "has settings of another version (" + ", ".join(
        map(shown, sorted(set(settings) ^ set(defaults))[:8])) + ")")
    for name, default in defaults.items():
        value = settings[name]
        if default is None:  # auto, or a count
            holds, wanted = value is None or type(value) is int, "auto (null) or a whole number"
        elif type(default) is float:
            holds, wanted = type(value) in (int, float), "a number"
        else:
            holds, wanted = type(value) is type(default), f"of the type {type(default).__name__}"
        _check(holds, f"has the setting {name} {shown(repr(value))}, not {wanted}")
    problems = BakeSettings(**settings).problems()
    _check(not problems, "has settings no bake takes: " + "; ".join(problems))


# -- the chunks ----------------------------------------------------------------------------------------------------

def _member_names(shares, shape: PartShape) -> set[str]:
    """Every member a part of these shares holds."""
    per_chunk = list(RESULT_ARRAYS)
    names = {"part", "chunks", PROBES + "chunks"}
    names |= {f"{name}_{slot}" for slot in range(len(shares[0]))
              for name in per_chunk + ([f"records_{f}" for f in HitRecords.FIELDS] if shape.records else [])}
    names |= {f"{PROBES}{name}_{slot}" for slot in range(len(shares[1])) for name in per_chunk}
    return {name + ".npy" for name in names}


def _members(archive: zipfile.ZipFile, wanted: set[str]):
    """Refuses an archive that does not hold exactly the members `wanted`, each once."""
    names = archive.namelist()
    _check(len(names) == len(set(names)), "holds an entry twice")
    extra, missing = sorted(set(names) - wanted), sorted(wanted - set(names))
    _check(not extra, f"holds entries no part of this bake has: {', '.join(map(shown, extra[:4]))}")
    _check(not missing, f"lacks {', '.join(missing[:4])}{' ...' if len(missing) > 4 else ''}")


def _chunk(archive, prefix: str, slot: int, rows: int, shape: PartShape, records: bool) -> ChunkResult:
    """One chunk's result, of `rows` points, its values checked."""
    def read(name, dtype, dimensions, most=0):
        member = f"{prefix}{name}_{slot}"
        size = math.prod(most if extent is None else extent for extent in dimensions)
        return member, _read(archive, member, _exactly(dtype, dimensions, most), size * np.dtype(dtype).itemsize)

    name, transfer = read("transfer", np.float64, (rows, shape.coefficients))
    _check(np.isfinite(transfer).all(), f"has NaN or infinite values in {name}")
    name, std_error = read("std_error", np.float64, (rows,))
    _check(np.isfinite(std_error).all() and (std_error >= 0).all(), f"has NaN, infinite or negative values in {name}")
    name, rays = read("rays", np.int64, (rows,))
    _check(((rays >= 0) & (rays <= shape.most_rays)).all(), f"has ray counts outside 0-{shape.most_rays} in {name}")
    name, skipped = read("skipped", np.bool_, (rows,))
    _check((skipped.view(np.uint8) <= 1).all(), f"has values neither true nor false in {name}")
    name, rules = read("rules", decided.DTYPE, (rows,))
    _check((rules <= decided.LARGEST).all(), f"has rule codes outside 0-{decided.LARGEST} in {name}")
    name, rule_error = read("rule_error", np.float64, (rows,))
    _check(np.isfinite(rule_error).all() and (rule_error >= 0).all()
           and (rule_error[rules == decided.MEASURED] == 0).all(),
           f"has NaN, infinite or negative values, or values at points no rule decided, in {name}")
    name, curve = read("curve", np.float64, (None, len(CHUNK_COLUMNS)), MAX_ROUNDS)
    _check(len(curve) > 0 and np.isfinite(curve).all() and (curve >= 0).all()
           and (np.diff(curve[:, :2], axis=0) >= 0).all() and curve[-1, 1] == rays.sum(),
           f"has an error curve that is not a bake's (rows after each round: seconds and rays growing, the last "
           f"row's rays the chunk's) in {name}")
    hits = _records(read, rows, shape) if records else None
    return ChunkResult(transfer, std_error, rays, skipped, rules, rule_error, curve, hits)


def _records(read, rows: int, shape: PartShape) -> HitRecords:
    """A chunk's hit records: as many as its points' rays at most, each on one of its points and the scene's
    triangles."""
    name, vertex = read("records_vertex", np.int64, (None,), rows * shape.most_rays)
    hits = len(vertex)
    _check(((vertex >= 0) & (vertex < rows)).all(), f"has hits of points outside its chunk's {rows} in {name}")
    name, triangle = read("records_triangle", np.int64, (hits,))
    _check(((triangle >= 0) & (triangle < shape.triangles)).all(),
           f"has hits on triangles outside the scene's {shape.triangles} in {name}")
    name, barycentric = read("records_barycentric", np.float64, (hits, 3))
    _check(np.isfinite(barycentric).all() and (barycentric >= 0).all() and (barycentric <= 1).all()
           and (np.abs(barycentric.sum(axis=1) - 1.0) <= BARYCENTRIC_SLACK).all(),
           f"has barycentric weights outside 0-1 or not summing to 1 in {name}")
    name, weight = read("records_weight", np.float64, (hits,))
    _check(np.isfinite(weight).all() and (weight >= 0).all(), f"has NaN, infinite or negative weights in {name}")
    name, replicate = read("records_replicate", np.int64, (hits,))
    _check(((replicate >= 0) & (replicate < shape.replicates)).all(),
           f"has replicates outside 0-{shape.replicates - 1} in {name}")
    return HitRecords(vertex, triangle, barycentric, weight, replicate)


# -- zip members and .npy headers ----------------------------------------------------------------------------------

def _exactly(dtype, dimensions: tuple, most: int = 0):
    """A header check: this dtype, and these dimensions (None: any extent up to `most`)."""
    dtype = np.dtype(dtype)

    def problem(shape, found) -> str | None:
        if found != dtype:
            return f"{found}, not {dtype}"
        if len(shape) != len(dimensions) or any(
                extent != wanted if wanted is not None else not 0 <= extent <= most
                for extent, wanted in zip(shape, dimensions)):
            wanted = ", ".join(f"up to {most}" if extent is None else str(extent) for extent in dimensions)
            return f"of shape {shape}, not ({wanted}{',' if len(dimensions) == 1 else ''}) as the scene's chunk holds"
        return None
    return problem


def _read(archive: zipfile.ZipFile, name: str, accepts, most_bytes: int) -> np.ndarray:
    """The array of member `name`.npy. Before it is opened, its compression and declared size (at most
    `most_bytes` of data); before its data is read, its header: accepts(shape, dtype) says what is wrong with it,
    or None. Its size must be the header's and its CRC right."""
    try:
        entry = archive.getinfo(name + ".npy")
    except KeyError:
        raise _Refused(f"lacks {name}.npy") from None
    _check(entry.compress_type in COMPRESSIONS, f"holds {name}.npy compressed by method {entry.compress_type}, "
                                                f"not stored or deflated")
    _check(entry.file_size <= HEADER_BYTES + most_bytes,
           f"holds {name}.npy of {entry.file_size} bytes, more than the scene's chunk has")
    with archive.open(entry) as member:
        version = np.lib.format.read_magic(member)
        _check(version in ((1, 0), (2, 0)), f"holds {name}.npy of .npy version {version}")
        header = (np.lib.format.read_array_header_1_0 if version == (1, 0) else
                  np.lib.format.read_array_header_2_0)
        shape, fortran, dtype = header(member, max_header_size=HEADER_BYTES)
        problem = accepts(shape, dtype)
        _check(problem is None, f"holds {name}.npy {problem}")
        size = math.prod(shape) * dtype.itemsize
        _check(entry.file_size == member.tell() + size, f"holds {name}.npy whose size is not its header's")
        array = np.empty(size, np.uint8)
        _check(member.readinto(array) == size and member.read(1) == b"", f"holds {name}.npy cut short")
    return array.view(dtype).reshape(shape, order="F" if fortran else "C")
