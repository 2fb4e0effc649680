"""Messy models (issue 33, item 2), fast: the cases of benchmarks/messy_assets.py, first checked against facts of
their geometry computed here in closed form (so each case holds the fault it is named for), then built, baked,
validated against Cycles and measured against a many-ray reference exactly as the benchmark does, with fewer
samples.

The goals are every asset's: RMS ≤ 2 % and p99 ≤ 10 % against Cycles at 4 × 64 samples, and actual ÷ estimated
error within 1/1.5..1.5. At 4 × 16 samples they loosen as tests/test_assets.py derives it: RMS ≤ 3 %, p99 ≤ 20 %.
As in the benchmark, the goals judge the rows off faces narrower than Cycles' corner nudge; those are compared apart
(Case.left_out).
"""

import math

import bpy
import numpy as np
import pytest

from benchmarks import assets, messy_assets

# The benchmark's 256-ray bakes (these meshes bake in a fraction of a second, and 64 rays' noise, 2-7 % here, would
# hide the faults), Cycles 4 × 16 samples as tests/test_assets.py, the 16 × reference at up to 256 points.
FAST = assets.Settings(bake_samples=256, cycles_samples=16, passes=4, reference_points=256)
RMS_BOUND, P99_BOUND, HONEST = 0.03, 0.20, 1.5


def corner_normals_against_faces(mesh) -> np.ndarray:
    """Per face corner: its normal more than 90° from its face's, from Blender's corner and face normals."""
    faces = np.repeat(np.arange(len(mesh.polygons)), [len(polygon.vertices) for polygon in mesh.polygons])
    face_normals = np.array([polygon.normal for polygon in mesh.polygons])
    normals = np.array([normal.vector for normal in mesh.corner_normals])
    return np.einsum("ij,ij->i", normals, face_normals[faces]) < 0.0


def edge_face_counts(mesh) -> np.ndarray:
    """How many faces each distinct edge (as a pair of vertices) has."""
    counts = {}
    for polygon in mesh.polygons:
        for key in polygon.edge_keys:
            counts[key] = counts.get(key, 0) + 1
    return np.array(list(counts.values()))


def inside_box(points, centre, size, turn_z=0.0) -> np.ndarray:
    """Points strictly inside a box of that centre and size turned by turn_z about its vertical axis."""
    local = np.asarray(points, dtype=float) - centre
    c, s = math.cos(turn_z), math.sin(turn_z)
    local = np.stack([c * local[:, 0] + s * local[:, 1], -s * local[:, 0] + c * local[:, 1], local[:, 2]], axis=1)
    return np.all(np.abs(local) < np.asarray(size) / 2, axis=1)


def test_the_two_boxes_interpenetrate(empty_scene):
    """Box A (1.2 × 0.8 × 0.6, centre (0, 0, 0.3)) and box B (a 0.8 cube turned 30°, centre (0.45, 0.2, 0.45)) in one
    mesh. B's corners lie at its centre + R(30°)·(±0.4, ±0.4): (−0.096, 0.346) and (0.304, −0.346) fall inside A's
    footprint (|x| < 0.6, |y| < 0.4), at B's bottom (z 0.05, inside A's 0..0.6), the other two outside; A's corner
    (0.6, 0.4, 0.6) lies in B's frame at (0.23, 0.10), inside. So 2 of B's corners are inside A and 1 of A's inside
    B: the two parts cross."""
    ob = messy_assets.boxes_crossing()
    positions = np.array([vertex.co for vertex in ob.data.vertices])
    assert (len(positions), len(ob.data.polygons)) == (16, 12)
    a_in_b = inside_box(positions[:8], (0.45, 0.2, 0.45), (0.8, 0.8, 0.8), math.radians(30.0))
    b_in_a = inside_box(positions[8:], (0.0, 0.0, 0.3), (1.2, 0.8, 0.6))
    assert (int(b_in_a.sum()), int(a_in_b.sum())) == (2, 1)


def test_the_wheel_runs_into_the_body_around_its_arch(empty_scene):
    """The arch is a 12-sided half polygon of radius 0.3 about (x −0.5, z 0) through the body (x ±1, y ±0.5, z
    0..0.6); the wheel's inner rim (y −0.3, inside the body's width) is a ring of 24 points of radius 0.28 about z
    0.06. A rim point at angle a lies sqrt(0.082 + 0.0336 sin a) from the arch's axis: beyond the arch's radius
    (and so in the body's solid) for sin a > 0.238, at 15°, 30°, ..., 165°: 11 points, the nearest 0.301 from it."""
    body, wheel = messy_assets.wheel_in_arch()
    rim = np.array([vertex.co for vertex in wheel.data.vertices if abs(vertex.co.y + 0.3) < 1e-6])
    assert len(rim) == messy_assets.CYLINDER_SEGMENTS
    from_axis = np.hypot(rim[:, 0] + 0.5, rim[:, 2])
    in_solid = (from_axis > messy_assets.ARCH_RADIUS) & (rim[:, 2] > 0) & (rim[:, 2] < 0.6)
    assert int(in_solid.sum()) == 11
    assert body.data.polygons and not any(polygon.use_smooth for polygon in body.data.polygons)


def test_a_fifth_of_the_sphere_is_wound_against_its_custom_normals(empty_scene):
    """Exactly the corners of the faces chosen (every corner's custom normal is its vertex's outward direction,
    so it points against a face whose winding is reversed, and along every other face of a 24 × 12 sphere)."""
    ob = messy_assets.normals_against_winding()
    mesh = ob.data
    chosen = messy_assets.chosen_faces(len(mesh.polygons))
    expected = np.zeros(len(mesh.loops), dtype=bool)
    for k in chosen:
        expected[mesh.polygons[k].loop_start:mesh.polygons[k].loop_start + mesh.polygons[k].loop_total] = True
    assert len(chosen) == 288 // 5
    assert np.array_equal(corner_normals_against_faces(mesh), expected)
    positions = np.array([mesh.vertices[loop.vertex_index].co for loop in mesh.loops])
    normals = np.array([normal.vector for normal in mesh.corner_normals])
    assert np.min(np.einsum("ij,ij->i", normals, positions / np.linalg.norm(positions, axis=1)[:, None])) > 0.999


def test_blenders_obj_importer_keeps_the_reversed_vn_lines(empty_scene):
    """The torus OBJ (24 × 12) through Blender's importer, as a user imports it: smooth faces with custom normals
    from the file. Its inward `vn` lines are 6 rings of 12 vertices, 4 corners each: 288 corners against their
    faces; 40 of the 204 faces on no such ring (a fifth, rounded down) are wound against their `vn`: 160 more."""
    ob = messy_assets.obj_reversed_vn()
    mesh = ob.data
    assert mesh.has_custom_normals and all(polygon.use_smooth for polygon in mesh.polygons)
    assert (len(mesh.vertices), len(mesh.polygons)) == (288, 288)
    assert int(corner_normals_against_faces(mesh).sum()) == 6 * 12 * 4 + (204 // 5) * 4


def test_the_box_edges_are_sliver_triangles(empty_scene):
    """A 2 × 1 × 0.6 box bevelled 2e-5 wide: its 12 edges become strips of 2 sliver triangles each, its 8 corners
    tiny triangles (sides about 3e-5), all 32 narrower than 1e-4 of its diagonal; its 6 sides stay, and the area
    stays the box's, 2·(2·1 + 2·0.6 + 1·0.6) = 7.6, to O(width)."""
    mesh = messy_assets.sliver_edges().data
    faults = messy_assets.corner_faults(mesh)
    thin_faces = [polygon.index for polygon in mesh.polygons if faults["on_thin_face"][polygon.loop_start]]
    assert len(mesh.polygons) == 6 + 12 * 2 + 8 and len(thin_faces) == 32
    assert all(len(mesh.polygons[k].vertices) == 3 for k in thin_faces)
    assert sum(polygon.area for polygon in mesh.polygons) == pytest.approx(7.6, abs=1e-3)
    assert not faults["normal_against_face"].any()


def test_the_tube_is_open_and_its_fin_makes_a_non_manifold_edge(empty_scene):
    """24 side quads without caps: two boundary loops of 24 edges; the fin's quad adds 3 free edges and gives the
    tube's edge at angle 0 a third face."""
    counts = edge_face_counts(messy_assets.tube_with_fin().data)
    assert (int((counts == 1).sum()), int((counts == 3).sum()), int((counts > 3).sum())) == (24 + 24 + 3, 1, 0)


def test_the_assembly_holds_every_fault(empty_scene):
    """Body, cabin, four wheels and a fender: the cabin's four windows (4 corners each) wound against their custom
    normals, the body's edges sliver triangles, the fender open with one non-manifold edge, the wheels' rims in the
    body's solid above the arches (as in the single wheel's case)."""
    objects = messy_assets.assembly()
    named = {ob.name: ob for ob in objects}
    assert sorted(named) == ["Body", "Cabin", "Fender", "Wheel 0", "Wheel 1", "Wheel 2", "Wheel 3"]
    assert int(corner_normals_against_faces(named["Cabin"].data).sum()) == 16
    assert messy_assets.corner_faults(named["Body"].data)["on_thin_face"].any()
    counts = edge_face_counts(named["Fender"].data)
    assert int((counts == 3).sum()) == 1 and int((counts == 1).sum()) > 0


@pytest.fixture(scope="module")
def measured(addon):
    """Each case measured once, when a test first asks for it: (row, diagnosis)."""
    found = {}

    def measure(name):
        if name not in found:
            case = assets.case_named(name, messy_assets.CASES)
            row, check, touching = assets.measure(case, FAST, log=lambda line: None)
            found[name] = row, messy_assets.diagnose(list(touching), check)
        return found[name]
    yield measure
    bpy.ops.wm.read_homefile(use_empty=True)


@pytest.mark.study  # Cycles renders of every case: once per CI run, on the newest Blender
@pytest.mark.parametrize("name", [
    "boxes crossing",  # RMS 1.24 %, p99 6.7 % at these settings (full run, 4 × 32: 0.00 %, 3.2 %)
    "wheel in arch",   # RMS 1.81 %, p99 16.0 % (full run: 1.09 %, 7.3 %)
    "normals against winding",  # RMS 0.00 %, p99 5.5 %, actual ÷ estimated 1.02
    "OBJ reversed vn",  # RMS 0.72 %, p99 8.1 %, actual ÷ estimated 0.98 (full run: 1.04 %, 4.3 %, 0.98)
    "sliver edges",  # its 96 rows on sliver faces compared apart (Cycles' rounding, R4), the rest exact
    "open parts",
    "assembly",  # the rest within these bounds; the full run (4 × 64) misses by a little: RMS 2.27 %, p99 10.5 %
])
def test_a_messy_case_meets_the_goals(measured, name):
    """Against Cycles (its noise taken out) RMS ≤ 3 % and p99 ≤ 20 % at these settings, and the bake's estimate
    within 1.5 × of its actual error against the 16 × reference (or both exact)."""
    row, _ = measured(name)
    assert row.rel_rms_error <= RMS_BOUND and row.rel_p99_error <= P99_BOUND, (name, row)
    assert 1 / HONEST <= row.honesty <= HONEST, (name, row)


@pytest.mark.study
def test_the_diagnosis_finds_the_faults_where_they_are(measured):
    """The benchmark's diagnosis counts, among the compared rows, the corners whose normal is against their face
    (the 219 corners of the sphere's 57 reversed faces: 288 // 5 faces, 3 corners at a pole, else 4) and those on
    thin faces (the sliver box's 32 thin faces: 24 slivers and 8 corner triangles, 96 corners)."""
    _, sphere = measured("normals against winding")
    poles = 24  # the sphere's faces: 24 triangles at the top, 10 × 24 quads, 24 triangles at the bottom
    corners = [3 if k < poles or k >= 288 - poles else 4 for k in messy_assets.chosen_faces(288)]
    assert sphere["normal_against_face"]["rows"] == sum(corners) == 219
    _, slivers = measured("sliver edges")
    assert slivers["on_thin_face"]["rows"] == 96 and slivers["normal_against_face"]["rows"] == 0
    row, _ = measured("sliver edges")
    assert row.left_out == 96 and row.all_rows_rms > 0.1  # compared apart, and their error still printed
