"""Part files are untrusted input: corrupted, truncated and hostile parts (made by hypothesis from a good part of a
tiny interreflected bake) are each refused in one line naming the file, in bounded memory, or read with every value
one a bake makes; never a crash. The merge's reading without Blender: descriptions, refusals, then contents."""

from dataclasses import asdict
import json
import tempfile
import tracemalloc
import zipfile
from pathlib import Path

import numpy as np
import pytest
from hypothesis import HealthCheck, example, given, settings, strategies as st

from hostile_parts import archive, npy, npy_header
from prt_addon.core import part_file, rules, shards
from prt_addon.core.bake import BakeSettings, ChunkResult
from prt_addon.core.errors import InputError
from prt_addon.core.interreflect import HitRecords

# The tiny scene: two chunks of 3 and 2 points, one chunk of 2 probes, 5 triangles; order 2, 8 rays a point.
SHAPE = part_file.PartShape(rows=[3, 2], probe_rows=[2], coefficients=4, records=True, triangles=5, replicates=4,
                            most_rays=16)
SETTINGS = asdict(BakeSettings(order=2, mode="interreflected", samples=8, max_samples=8))
DIGESTS = {"geometry": "g", "transform": "t", "occluders": "o", "materials": "m", "settings": "s"}
SCENE = shards.PartInfo(shard=0, shards=1, chunks=2, probe_chunks=1, scene="tiny.blend", surfaces=["A"],
                        receivers=["A"], settings=SETTINGS, fingerprints={"A": DIGESTS})
MEMORY_BOUND = 16 << 20  # bytes: the good part is 6 kB; nothing hostile may make reading it cost more


def chunk(rows: int, seed: int, records: bool) -> ChunkResult:
    """A result a bake could make: finite transfer (negative coefficients too), errors ≥ 0, 8 rays, hits."""
    random = np.random.default_rng(seed)
    hits = None
    if records:
        weights = random.dirichlet([1, 1, 1], size=4)
        hits = HitRecords(np.array([0, 1, rows - 1, 0]), np.array([0, 4, 2, 2]), weights, np.full(4, 0.125),
                          np.array([0, 1, 2, 3]))
    codes = np.arange(rows, dtype=np.uint8) % (rules.LARGEST + 1)
    return ChunkResult(random.normal(size=(rows, 4)), random.uniform(0, 0.1, rows), np.full(rows, 8),
                       np.array([False] * (rows - 1) + [True]), codes,
                       np.where(codes != rules.MEASURED, random.uniform(0, 0.1, rows), 0.0),
                       np.array([[0.5, 4.0 * rows, 0.02], [1.0, 8.0 * rows, 0.01]]), hits)


def good_members() -> dict:
    """The good part's arrays by name, as shards.write_part writes them."""
    description = shards.PartInfo(**{**asdict(SCENE), "shard": 1, "time_s": 2.0, "cpu_s": 1.0, "rays": 40,
                                     "rays_s": 1.5, "workers": 2})
    with tempfile.TemporaryDirectory() as folder:
        path = Path(folder) / "good.npz"
        shards.write_part(str(path), description, {0: chunk(3, 0, True), 1: chunk(2, 1, True)},
                          {0: chunk(2, 2, False)}, shards.Stopwatch())
        with np.load(path) as data:
            return {name: data[name] for name in data.files}


GOOD = good_members()
DESCRIPTION = json.loads(str(GOOD["part"]))


def part_bytes(arrays: dict, compression=zipfile.ZIP_STORED) -> bytes:
    return archive([(name, npy(array)) for name, array in arrays.items()], compression)


def with_description(**changed) -> dict:
    meta = {**DESCRIPTION, **changed}
    return {**GOOD, "part": np.array(json.dumps({key: value for key, value in meta.items() if value is not DROP}))}


DROP = object()
GOOD_BYTES = part_bytes(GOOD)
ARRAY_NAMES = sorted(name for name in GOOD if name != "part")
json_values = st.recursive(st.none() | st.booleans() | st.integers() | st.floats() | st.text(max_size=20),
                           lambda inner: st.lists(inner, max_size=4) | st.dictionaries(st.text(max_size=8), inner,
                                                                                       max_size=4), max_leaves=12)


@st.composite
def hostile_parts(draw) -> bytes:
    """A part corrupted, truncated, or made hostile in one of many ways."""
    kind = draw(st.sampled_from(["truncated", "overwritten", "value", "array", "members", "compression",
                                 "description", "setting"]))
    if kind == "truncated":
        return GOOD_BYTES[: draw(st.integers(0, len(GOOD_BYTES) - 1))]
    if kind == "overwritten":
        at = draw(st.integers(0, len(GOOD_BYTES) - 1))
        patch = draw(st.binary(min_size=1, max_size=8))
        return GOOD_BYTES[:at] + patch + GOOD_BYTES[at + len(patch):]
    name = draw(st.sampled_from(ARRAY_NAMES))
    if kind == "value":  # one value replaced: NaN, infinite, negative, huge, a byte a bool never holds, or a code
        #                  no rule has
        array = GOOD[name].copy()
        flat = array.reshape(-1).view(np.uint8) if array.dtype == bool else array.reshape(-1)
        if not flat.size:
            return part_bytes(GOOD)
        value = draw(st.sampled_from({"f": [np.nan, np.inf, -np.inf, -1.0, -1e-300, 1e300, 1.5],
                                      "b": [2, 17, 255], "u": [rules.LARGEST + 1, 17, 255]}.get(
                                          array.dtype.kind, [-1, 2, 5, 17, 2 ** 62, -2 ** 63])))
        flat[draw(st.integers(0, flat.size - 1))] = value
        return part_bytes({**GOOD, name: array})
    if kind == "array":  # another shape or dtype, a pickle, or a header claiming far more than it holds
        array = GOOD[name]
        replacement = draw(st.sampled_from([
            npy(array[:-1]), npy(np.concatenate([array, array[:1]])), npy(array[None]), npy(array.astype(np.float32)),
            npy(array.astype(">f8")), npy(array.astype(np.int32)), npy(np.array([object()] * 3), allow_pickle=True),
            npy(np.zeros(3, [("a", "<f8")])), npy_header((10 ** 12,)) + bytes(64), npy_header((2 ** 40, 4)) + bytes(64),
            npy_header((3, 4), "<i8") + bytes(8), b"", b"\x93NUMPY\x03\x00" + b"\0" * 16, npy(np.array("text"))]))
        return archive([(key, replacement if key == name else npy(value)) for key, value in GOOD.items()])
    if kind == "members":
        members = [(key, npy(value)) for key, value in GOOD.items()]
        change = draw(st.sampled_from(["drop", "extra", "twice", "rename"]))
        if change == "drop":
            members = [member for member in members if member[0] != name]
        elif change == "extra":
            members.append(("extra", npy(np.zeros(2))))
        elif change == "twice":
            members.append((name, npy(GOOD[name])))
        else:
            members = [("renamed" if key == name else key, data) for key, data in members]
        return archive(members)
    if kind == "compression":  # deflated is what np.savez_compressed writes; a bomb's header claims gigabytes
        choice = draw(st.sampled_from(["deflated", "bzip2", "lzma", "bomb"]))
        if choice == "bomb":
            header = npy_header((1 << 27, 4))
            bomb = header + bytes(1 << 20)  # 1 MiB of zeros deflate to 1 kB; the header claims 4 GiB
            return archive([(key, bomb if key == name else npy(value)) for key, value in GOOD.items()],
                           zipfile.ZIP_DEFLATED)
        return part_bytes(GOOD, {"deflated": zipfile.ZIP_DEFLATED, "bzip2": zipfile.ZIP_BZIP2,
                                 "lzma": zipfile.ZIP_LZMA}[choice])
    if kind == "description":
        field = draw(st.sampled_from(sorted(DESCRIPTION) + ["extra"]))
        value = draw(json_values | st.just(DROP) | st.sampled_from([10 ** 9, 10 ** 30, -1, 1e308]))
        if draw(st.booleans()):
            return part_bytes({**GOOD, "part": np.array(draw(st.text(max_size=40)) or "[" * 100_000)})
        return part_bytes(with_description(**{field: value}))
    field = draw(st.sampled_from(sorted(SETTINGS)))
    value = draw(json_values | st.sampled_from([0, 17, 10 ** 40, -3, 2.5, "auto", 1e-12]))
    return part_bytes(with_description(settings={**SETTINGS, field: value}))


def merged(path: Path):
    """What the merge reads of one part of the tiny scene's bake: its description, refused as the merge refuses
    foreign, stale and misnumbered parts, then its contents."""
    info = part_file.read_part(str(path))
    problems = shards.refusals([(str(path), info)], SCENE)
    if problems:
        raise InputError("cannot merge: " + "; ".join(problems))
    return part_file.load_part(str(path), info, SHAPE)


def assert_a_bake_could_make(chunks, probes):
    """Every value read is one a bake makes: the scene's shapes, finite, errors ≥ 0, rays 0-16, hits on the
    chunk's points and the scene's triangles with barycentric weights summing to 1."""
    assert [index for index, _ in chunks] == [0, 1] and [index for index, _ in probes] == [0]
    for (index, result), rows, records in [(chunks[0], 3, True), (chunks[1], 2, True), (probes[0], 2, False)]:
        assert result.transfer.shape == (rows, 4) and np.isfinite(result.transfer).all()
        assert result.std_error.shape == (rows,) and (result.std_error >= 0).all()
        assert result.rays.shape == (rows,) and ((0 <= result.rays) & (result.rays <= 16)).all()
        assert result.skipped.dtype == bool and set(result.skipped.view(np.uint8).tolist()) <= {0, 1}
        assert result.rules.dtype == np.uint8 and result.rules.shape == (rows,) and result.rules.max() <= rules.LARGEST
        assert result.rule_error.shape == (rows,) and (result.rule_error >= 0).all()
        assert (result.rule_error[result.rules == rules.MEASURED] == 0).all()
        assert (result.records is not None) == records
        if records:
            hits = result.records
            assert ((0 <= hits.vertex) & (hits.vertex < rows)).all()
            assert ((0 <= hits.triangle) & (hits.triangle < 5)).all()
            assert ((0 <= hits.barycentric) & (hits.barycentric <= 1)).all()
            assert np.allclose(hits.barycentric.sum(1), 1.0) and (hits.weight >= 0).all()
            assert ((0 <= hits.replicate) & (hits.replicate < 4)).all()


def outcome(data: bytes, folder: Path):
    """The refusal's line, or None, of merging a part holding `data` (written in `folder`); asserts the refusal is
    one line naming the part, and the memory traced at its peak under MEMORY_BOUND."""
    path = folder / "hostile part.npz"
    path.write_bytes(data)
    tracemalloc.start()
    try:
        assert_a_bake_could_make(*merged(path))
        refusal = None
    except InputError as refused:
        refusal = str(refused)
    finally:
        peak = tracemalloc.get_traced_memory()[1]
        tracemalloc.stop()
    if refusal is not None:
        assert str(path) in refusal and "\n" not in refusal and len(refusal) < 1000, refusal
    assert peak < MEMORY_BOUND, peak
    return refusal


def test_the_good_part_and_its_deflated_copy_are_read_whole(tmp_path):
    assert outcome(GOOD_BYTES, tmp_path) is None
    assert outcome(part_bytes(GOOD, zipfile.ZIP_DEFLATED), tmp_path) is None


@pytest.mark.parametrize("data, words", [
    (part_bytes({**GOOD, "transfer_0": np.full((3, 4), np.nan)}), "NaN or infinite values in transfer_0"),
    (part_bytes({**GOOD, "std_error_1": -GOOD["std_error_1"] - 1}), "negative values in std_error_1"),
    (part_bytes({**GOOD, "rays_0": np.full(3, -1)}), "ray counts outside 0-16 in rays_0"),
    (part_bytes({**GOOD, "rules_1": np.full(2, 200, np.uint8)}), f"rule codes outside 0-{rules.LARGEST} in rules_1"),
    (part_bytes({**GOOD, "curve_1": GOOD["curve_1"][::-1]}), "error curve that is not a bake's"),
    (part_bytes({**GOOD, "curve_0": GOOD["curve_0"] * [1, 2, 1]}), "error curve that is not a bake's"),
    (part_bytes({**GOOD, "curve_0": np.zeros((7, 3))}), "curve_0.npy of shape (7, 3), not (up to 6, 3)"),
    (part_bytes({**GOOD, "rule_error_0": np.full(3, 0.5)}), "values at points no rule decided, in rule_error_0"),
    (part_bytes({**GOOD, "records_vertex_1": GOOD["records_vertex_1"] + 2}), "outside its chunk's 2 in records_v"),
    (part_bytes({**GOOD, "records_triangle_0": GOOD["records_triangle_0"] + 5}), "outside the scene's 5"),
    (part_bytes({**GOOD, "records_barycentric_0": GOOD["records_barycentric_0"] * 2}), "not summing to 1"),
    (part_bytes({**GOOD, "records_replicate_0": GOOD["records_replicate_0"] + 1}), "replicates outside 0-3"),
    (part_bytes({**GOOD, "transfer_1": GOOD["transfer_1"][:, :3]}), "transfer_1.npy of shape (2, 3), not (2, 4)"),
    (part_bytes({**GOOD, "transfer_1": GOOD["transfer_1"].astype(np.float32)}), "float32, not float64"),
    (part_bytes(with_description(shards=10 ** 9)), "is shard 1/1000000000, the others are of 1"),
    (part_bytes(with_description(shards="1")), "whose shards is '1', not a whole number"),
    (part_bytes(with_description(format="prt-part-5")), f"of another format than {shards.PART_FORMAT}"),
    (part_bytes(with_description(settings={**SETTINGS, "order": 2.0})), "setting order 2.0, not of the type int"),
    (part_bytes(with_description(settings={**SETTINGS, "samples": 10 ** 9})), "settings no bake takes: samples"),
    (archive([(key, npy_header((1 << 27, 4)) + bytes(1 << 20) if key == "transfer_0" else npy(value))
              for key, value in GOOD.items()], zipfile.ZIP_DEFLATED), "more than the scene's chunk has"),
    (GOOD_BYTES[:-30], "is not a readable PRT part file (BadZipFile"),
    (b"", "is not a readable PRT part file (BadZipFile"),
    (part_bytes(GOOD, zipfile.ZIP_BZIP2), "compressed by method 12, not stored or deflated"),
], ids=["nan", "negative-error", "negative-rays", "rule-code", "curve-seconds-fall", "curve-rays-not-the-chunks",
        "curve-rows", "doubt-unruled", "hit-vertex", "hit-triangle", "barycentric", "replicate",
        "shape", "dtype", "a-billion-shards", "shards-text", "format", "order-float", "samples", "bomb",
        "truncated", "empty", "bzip2"])
def test_each_hostile_part_is_refused_in_one_line_naming_it_and_the_problem(tmp_path, data, words):
    refusal = outcome(data, tmp_path)
    assert refusal is not None and words in refusal, refusal


@settings(max_examples=150, deadline=None, derandomize=True, database=None,
          suppress_health_check=[HealthCheck.too_slow, HealthCheck.data_too_large,
                                 HealthCheck.function_scoped_fixture])  # one file in tmp_path, rewritten
@given(data=hostile_parts())
@example(data=GOOD_BYTES[:100])
def test_any_corrupted_truncated_or_hostile_part_is_refused_in_one_line_or_read_as_a_bake_makes_it(tmp_path, data):
    outcome(data, tmp_path)
