"""Real assets, fast (issue 13, items 6 and 7): the small cases of benchmarks/assets.py, built, baked, validated
against Cycles and measured against a many-ray reference exactly as the benchmark does, with fewer samples.

Cases: woody.obj imported as a user imports it (flat-shaded), the low-poly UV sphere flat under a low sun, and a
cylinder with Smooth by Angle. The bounds are loose versions of the full run's figures (4 × 64 Cycles samples,
benchmarks/results/, tabled in docs/reference/benchmarks.md), each derived in its test's docstring. The benchmark
rests every asset on its floor, and a face lying on the floor facing into it is where the bake still disagrees with
Cycles: Cycles sees no light there, the bake lights it from below the floor (its ray origins move along the normal,
through the floor). That is an open problem the benchmark shows; here the agreement is asserted without those
vertices and corners, and the tests check that they are exactly the ones on the floor.
"""

import bpy
import numpy as np
import pytest

from benchmarks import assets
from conftest import ROOT
from prt_addon.blender.scene_bake import SceneBake
from prt_addon.core.bake import BakeSettings

ASSETS = ROOT.parent / "shared" / "assets"
needs_assets = pytest.mark.skipif(not (ASSETS / "woody.obj").is_file(),
                                  reason=f"the public test meshes are not at {ASSETS} (CI keeps shared/ beside "
                                         f"the clone)")

# Fast: 64-ray bakes, Cycles 4 × 16 samples (a quarter of the benchmark's; Cycles' noise about doubles, and it is
# taken out of the RMS), a 1024-ray reference at up to 512 points.
FAST = assets.Settings(bake_samples=64, cycles_samples=16, passes=4, reference_points=512)


@pytest.fixture(scope="module")
def measured(addon):
    """The three cases measured once (the sphere's SH lights need the add-on), and the flat sphere's bake with
    its smooth vertex normals against the same Cycles corners."""
    rows = {}
    for name in ("woody", "sphere flat", "cylinder"):
        if name == "woody" and not (ASSETS / "woody.obj").is_file():
            continue
        row, check, touching = assets.measure(assets.case_named(name), FAST, log=lambda line: None)
        rows[name] = row
        if name == "sphere flat":
            (sphere,) = touching
            rows["smooth normals"] = assets.smooth_normal_errors(sphere, check, touching[sphere], FAST)
    yield rows
    bpy.ops.wm.read_homefile(use_empty=True)


def split_bounds(mesh) -> tuple[tuple[int, int], tuple[int, int]]:
    """From the faces' own normals, without the bake's code: ((split vertices, points) counting only normals that
    clearly differ, to 1e-3; the same counting every float difference). A flat-shaded mesh's split lies between:
    each vertex gets a point per clearly different normal of its faces, and never more than the distinct normals
    its faces have (nearly coplanar faces, normals apart in the fifth decimal, may go either way)."""
    def counts(key):
        normals = {}
        for polygon in mesh.polygons:
            for vertex in polygon.vertices:
                normals.setdefault(vertex, set()).add(key(polygon.normal))
        split = sum(len(keys) > 1 for keys in normals.values())
        return split, len(mesh.vertices) - len(normals) + sum(len(keys) for keys in normals.values())
    return counts(lambda normal: tuple(np.round(np.array(normal), 3))), counts(tuple)


@needs_assets
@pytest.mark.parametrize("name", ["woody", "cow", "teapot"])
def test_an_imported_obj_is_split_exactly_where_its_faces_differ(empty_scene, name):
    """OBJs without normals import flat-shaded: every vertex whose faces have clearly different normals must
    become one shading point per normal, and no vertex may get more points than its faces have distinct normals.
    woody is a flat cut-out (its faces are coplanar: nothing splits); every one of the cow's 2,903 vertices sits
    between faces of different normals; the teapot has a few vertices amid coplanar faces."""
    ob = assets.import_obj(name)
    assert not any(polygon.use_smooth for polygon in ob.data.polygons)
    (least_split, least_points), (most_split, most_points) = split_bounds(ob.data)
    gathered = SceneBake(bpy.context, BakeSettings(), [ob.name])  # gathers the surface; nothing is baked
    (surface,) = [receiver.surface for receiver in gathered.plan.receivers]
    assert least_split <= surface.split_vertices <= most_split
    assert least_points <= len(surface.receiver.positions) <= most_points
    if name in ("woody", "cow"):  # no nearly coplanar faces: the count is exact
        assert surface.split_vertices == least_split == most_split == {"woody": 0, "cow": 2903}[name]
    assert len(surface.receiver.positions) > len(ob.data.vertices) or name == "woody"


def test_the_flat_sphere_and_the_cylinder_split_every_vertex_where_shading_breaks(measured):
    """A flat UV sphere of 16 × 8 rings has 114 vertices, each between faces of different normals, and 480 face
    corners (96 quads, 32 triangles at the poles), each with its own face's normal: 480 points. The cylinder's
    Smooth by Angle keeps its rims sharp: each of its 64 vertices is split into a side point and a cap point."""
    sphere, cylinder = measured["sphere flat"], measured["cylinder"]
    assert (sphere.vertices, sphere.split_vertices, sphere.points) == (114, 114, 480)
    assert (cylinder.vertices, cylinder.split_vertices, cylinder.points) == (64, 64, 128)


def test_small_assets_agree_with_cycles_off_the_floor(measured):
    """Against Cycles, without the rows that lie on the floor facing into it. The full run (4 × 64 samples) gives
    RMS 0.21 % (woody), 0.00 % (sphere) and 0.31 % (cylinder), p99 1.2-2.5 %: the bake is exact for these up to
    Cycles' noise. At 4 × 16 samples Cycles' noise RMS doubles to 1.3-3.1 %, and taking it out of a few hundred
    rows is itself uncertain: the RMS then reads 0-1.5 % (measured); the p99, whose tail keeps about 2-3 × Cycles'
    noise RMS where PRT is exact, reads 4.5-10 %. Bounds: RMS 3 % (the full run's figure plus twice the spread
    at 4 × 16) and p99 20 % (twice what Cycles' noise alone gives)."""
    for name in ("woody", "sphere flat", "cylinder"):
        if name not in measured:
            continue
        row = measured[name]
        assert row.off_floor_rms <= 0.03, (name, row)
        assert row.off_floor_p99 <= 0.20, (name, row)
        assert row.light == ("scene SH lights" if name == "sphere flat" else "default light")


def test_the_disagreement_left_is_on_the_floor_only(measured):
    """The rows the off-floor figures leave out are exactly the faces lying on the floor: the sphere's south pole
    (16 corners, one per face around it), the cylinder's bottom cap (32 corners); woody, a cut-out standing on its
    edge, has none (its lowest vertices face sideways)."""
    expected = {"woody": 0, "sphere flat": 16, "cylinder": 32}
    for name, count in expected.items():
        if name in measured:
            assert measured[name].touching == count, name


def test_a_flat_sphere_agrees_with_cycles_far_better_than_its_smooth_normal_bake(measured):
    """Like for like: one Cycles reference, the flat sphere as Blender shades it, corner by corner, under a low
    sun (θ 75°, its terminator across the sphere); two bakes of the same geometry judged against it in the same
    measure. The shading-aware bake (one transfer per corner normal) against the bake a smooth vertex normal gives,
    stored once per vertex and shown on each of its corners (a bake blind to the corner normals). Off
    the floor the first is exact up to Cycles' noise (full run 0.00 % RMS, at 4 × 16 samples 0-1.5 %), the second
    is 12.1 % off (12.0-12.1 % at 4 × 16: far above the noise). Bounds: ≤ 3 % (as for every small case) against
    ≥ 6 % (half the measured), and at least 3 × apart."""
    errors = measured["smooth normals"]
    assert errors["per_corner_off_floor"] <= 0.03, errors
    assert errors["smooth_normals_off_floor"] >= 0.06, errors
    assert errors["smooth_normals_off_floor"] >= 3 * errors["per_corner_off_floor"], errors


def test_the_estimate_is_exact_where_the_bake_is_and_honest_elsewhere(measured):
    """Every occluder woody and the cylinder see is the floor, a flat polygon integrated in closed form, or their
    own convex (or planar) surface: every ray's control variate cancels, so the bake estimates zero error and the
    16 × reference (another seed) agrees to float32 round-off. The flat sphere's pole corners touch the floor at
    an angle: their rays start above it, inside the sphere, and its own faces block them by ray casting, which has
    noise: there the estimate must be honest (within 1.5 × of the actual error at the same points)."""
    for name, row in measured.items():
        if not isinstance(row, assets.Row):
            continue
        if name == "sphere flat":
            assert 1 / 1.5 <= row.honesty <= 1.5, row
        else:
            assert row.est_rms_rel_error == 0.0 and row.exact, row


@needs_assets
def test_the_estimate_is_honest_on_the_cow(empty_scene):
    """The cow, flat-shaded, shadows itself (legs, head, ears): a bake with real noise. Its estimated RMS error is
    within 1.5 × of the actual error against a 16 × reference at the same shading points (the issue's goal; the
    full run's ratio at 256 rays is in docs/reference/benchmarks.md). No Cycles here."""
    names = assets.build_case(assets.case_named("cow"))
    scene_bake = assets.bake_scene(names, FAST)
    reference = assets.reference_error(scene_bake, FAST)
    assert reference["points"] == FAST.reference_points and reference["estimate"] > 0.01
    ratio = reference["actual"] / reference["estimate"]
    assert 1 / 1.5 <= ratio <= 1.5, reference
