"""Messy models as artists make them (issue 33, item 2), measured as benchmarks/assets.py measures every asset.

One case per fault class, built in Blender from explicit vertices and faces in a fixed order (as assets.py builds
its UV sphere: some operators' output order differs from run to run), edited where needed by an applied Bevel and
bmesh, or written as an OBJ and imported; then placed, floored, baked at the defaults, validated against Cycles and
measured against a many-ray reference exactly as assets.py does (its Case, measure, table and goals; its command
line, with this module's cases):

- boxes crossing: two boxes of one mesh that interpenetrate (separate parts of one receiver);
- wheel in arch: a body with a wheel arch cut through it and a wheel pushed up into the arch (two objects);
- normals against winding: a smooth UV sphere with a fifth of its faces wound inward while its custom normals
  (normals_split_custom_set) point outward, as an OBJ's `vn` lines give them;
- OBJ reversed vn: a torus written as an OBJ whose `vn` lines on a quarter of it point inward and a fifth of whose
  other faces are wound against their `vn`, imported through Blender's importer as a user imports it (the
  importer keeps the `vn` lines as custom normals);
- sliver edges: a flat-shaded box whose edges are bevelled by strips 1e-5 of its size wide, cut into sliver
  triangles;
- open parts: an open tube (no caps) standing on the floor with a fin on one of its edges (a non-manifold edge);
- assembly: a small car of all of these: a bevelled body with two arches, a cabin sunk into it whose windows are
  wound inward under outward custom normals, four wheels pushed into the arches, an open fender with a fin.

Goals, as for every asset: RMS ≤ 2 % and p99 ≤ 10 % against Cycles, actual ÷ estimated error within 1/1.5..1.5.
docs/cycles_conventions.md says what Cycles decides at each of these faults, and where in its source.

Run from the repository root:  .venv/bin/python benchmarks/messy_assets.py [--quick] [--samples N] [--passes N]
                                   [--cases a,b] [--reference-points N] [--workers N] [--json [DIR]]
"""

import math
import os
import sys
import tempfile

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
sys.path.insert(0, ROOT)

import bpy  # noqa: E402  (bpy before bmesh, which it provides)
import bmesh  # noqa: E402
import numpy as np  # noqa: E402

from benchmarks import assets  # noqa: E402
from prt_addon.blender import storage  # noqa: E402

SELECT_SEED = 20260633   # which faces are wound inward; fixed so runs compare
INWARD_SHARE = 5         # a fifth of the faces
SLIVER_WIDTH = 2e-5      # the sliver strips' width: 1e-5 of the 2-unit asset
SHARP_ANGLE = math.radians(30.0)  # Smooth by Angle for the wheels and the tube
ARCH_RADIUS = 0.3
ARCH_SEGMENTS = 12
WHEEL_RADIUS = 0.28
WHEEL_RISE = 0.06        # the wheel's axis above the arch's: its tread runs 0.04 into the arch's roof
CYLINDER_SEGMENTS = 24


# -- meshes from vertices and faces ------------------------------------------------------------------------------
def mesh_object(name, vertices, faces, smooth=False):
    """A new object linked to the scene, its mesh exactly these vertices and faces (their order kept)."""
    mesh = bpy.data.meshes.new(name)
    mesh.from_pydata([tuple(map(float, v)) for v in vertices], [], [tuple(map(int, f)) for f in faces])
    mesh.update()
    if smooth:
        mesh.shade_smooth()
    ob = bpy.data.objects.new(name, mesh)
    bpy.context.collection.objects.link(ob)
    bpy.context.view_layer.objects.active = ob
    return ob


def box(centre, size, turn_z=0.0, first=0):
    """A box's 8 vertices and its 6 quads wound outward (indices from `first`), turned about its vertical axis."""
    c, s = math.cos(turn_z), math.sin(turn_z)
    vertices = []
    for h in (-0.5, 0.5):
        for u, v in ((-0.5, -0.5), (0.5, -0.5), (0.5, 0.5), (-0.5, 0.5)):
            x, y, z = u * size[0], v * size[1], h * size[2]
            vertices.append((centre[0] + c * x - s * y, centre[1] + s * x + c * y, centre[2] + z))
    faces = [(0, 3, 2, 1), (4, 5, 6, 7), (0, 1, 5, 4), (1, 2, 6, 5), (2, 3, 7, 6), (3, 0, 4, 7)]
    return vertices, [tuple(first + k for k in face) for face in faces]


def cylinder_y(centre, radius, width, segments=CYLINDER_SEGMENTS):
    """A closed cylinder along y (a wheel): two rings, side quads wound outward and an n-gon at each end."""
    angles = 2.0 * np.pi * np.arange(segments) / segments
    rings = [[(centre[0] + radius * math.cos(a), centre[1] + y, centre[2] + radius * math.sin(a)) for a in angles]
             for y in (-width / 2, width / 2)]
    faces = [(j, segments + j, segments + (j + 1) % segments, (j + 1) % segments) for j in range(segments)]
    faces += [tuple(range(segments)), tuple(range(2 * segments - 1, segments - 1, -1))]
    return rings[0] + rings[1], faces


def arched_profile(length, height, arches):
    """The side outline (x, z) of a body whose bottom has a half-round arch at each x in `arches`, counter-clockwise
    seen from −y, starting at the bottom's left end."""
    outline = [(-length / 2, 0.0)]
    for x in sorted(arches):
        outline += [(x + ARCH_RADIUS * math.cos(a), ARCH_RADIUS * math.sin(a))
                    for a in np.linspace(np.pi, 0.0, ARCH_SEGMENTS + 1)]
    return outline + [(length / 2, 0.0), (length / 2, height), (-length / 2, height)]


def extruded(outline, width):
    """The outline (x, z) swept along y over `width`: a quad per outline edge and an n-gon at each end, wound
    outward (the outline runs counter-clockwise seen from −y)."""
    n = len(outline)
    vertices = [(x, y, z) for y in (-width / 2, width / 2) for x, z in outline]
    faces = [(j, n + j, n + (j + 1) % n, (j + 1) % n) for j in range(n)]
    faces += [tuple(range(n)), tuple(range(2 * n - 1, n - 1, -1))]
    return vertices, faces


def edited(ob, edit):
    """Runs edit(bm) on the object's mesh through bmesh and writes it back."""
    bm = bmesh.new()
    bm.from_mesh(ob.data)
    edit(bm)
    bm.to_mesh(ob.data)
    bm.free()
    ob.data.update()
    return ob


def chosen_faces(count, seed=SELECT_SEED, share=INWARD_SHARE) -> list:
    """A fixed random 1/share of the face indices 0..count-1, sorted."""
    return sorted(np.random.default_rng(seed).choice(count, count // share, replace=False).tolist())


def reverse_winding(ob, faces):
    """Reverses the winding of the object's `faces` (indices) and shades it smooth: its custom normals are set
    after, per corner."""
    def reverse(bm):
        bm.faces.ensure_lookup_table()
        bmesh.ops.reverse_faces(bm, faces=[bm.faces[k] for k in faces])
    edited(ob, reverse)
    ob.data.shade_smooth()
    return ob


def set_corner_normals(ob, normals):
    """Sets the mesh's custom normals, (C, 3) one per face corner, in corner order."""
    ob.data.normals_split_custom_set([tuple(map(float, n)) for n in normals])
    return ob


def unit(vectors):
    vectors = np.asarray(vectors, dtype=float)
    return vectors / np.linalg.norm(vectors, axis=-1, keepdims=True)


def sliver_bevel(ob, width=SLIVER_WIDTH):
    """Bevels the object's edges sharper than 30° by strips `width` wide (applied: the bake refuses modifiers that
    change the vertex count) and cuts each strip into two sliver triangles."""
    bevel = ob.modifiers.new("Bevel", "BEVEL")
    bevel.width, bevel.segments, bevel.limit_method = width, 1, "ANGLE"
    bpy.context.view_layer.objects.active = ob
    bpy.ops.object.modifier_apply(modifier=bevel.name)
    return edited(ob, lambda bm: bmesh.ops.triangulate(
        bm, faces=[face for face in bm.faces if len(face.verts) == 4 and face.calc_area() < 100 * width]))


def smooth_by_angle(ob):
    ob.data.shade_smooth()
    ob.data.set_sharp_from_angle(angle=SHARP_ANGLE)
    return ob


# -- the cases ---------------------------------------------------------------------------------------------------
def boxes_crossing():
    """Two boxes of one flat-shaded mesh: the first (1.2 × 0.8 × 0.6) on the floor, the second (a 0.8 cube turned
    30°) pushed into it from above, through its top and two of its sides."""
    a_vertices, a_faces = box((0.0, 0.0, 0.3), (1.2, 0.8, 0.6))
    b_vertices, b_faces = box((0.45, 0.2, 0.45), (0.8, 0.8, 0.8), math.radians(30.0), first=8)
    return mesh_object("Boxes", a_vertices + b_vertices, a_faces + b_faces)


def wheel(name, x, y, width=0.3):
    """A wheel of WHEEL_RADIUS along y, its axis WHEEL_RISE above an arch's at x (the body's bottom at z = 0)."""
    return smooth_by_angle(mesh_object(name, *cylinder_y((x, y, WHEEL_RISE), WHEEL_RADIUS, width), smooth=True))


def wheel_in_arch():
    """A flat-shaded body (2 × 1 × 0.6) with an arch cut through it at x = −0.5 and a wheel pushed up into the
    arch: its tread runs into the arch's roof, and it stands out of the body's side."""
    body = mesh_object("Body", *extruded(arched_profile(2.0, 0.6, [-0.5]), 1.0))
    return [body, wheel("Wheel", -0.5, -0.45)]


def normals_against_winding():
    """A smooth 24 × 12 UV sphere with a fifth of its faces wound inward; every corner's custom normal points out
    (normals_split_custom_set)."""
    sphere = assets.uv_sphere(segments=24, rings=12)
    ob = reverse_winding(sphere, chosen_faces(len(sphere.data.polygons)))
    positions = np.array([vertex.co for vertex in ob.data.vertices])
    return set_corner_normals(ob, unit(positions[[loop.vertex_index for loop in ob.data.loops]]))


def torus_obj(path, major=1.0, minor=0.4, segments=24, sides=12):
    """Writes a torus as an OBJ (y up, as OBJ files are) with one `vn` per vertex, outward, except on the quarter
    of the torus at major angles below 90°, whose `vn` lines point inward; elsewhere a fifth of the faces (a fixed
    choice) are wound inward, against their outward `vn`. Returns the indices of those faces, in the file's
    order."""
    lines = []
    for i in range(segments):
        a = 2.0 * math.pi * i / segments
        for j in range(sides):
            b = 2.0 * math.pi * j / sides
            lines.append(f"v {(major + minor * math.cos(b)) * math.cos(a):.6f} {minor * math.sin(b):.6f} "
                         f"{-(major + minor * math.cos(b)) * math.sin(a):.6f}")
    quarter = segments // 4
    for i in range(segments):
        a = 2.0 * math.pi * i / segments
        sign = -1.0 if i < quarter else 1.0
        for j in range(sides):
            b = 2.0 * math.pi * j / sides
            lines.append(f"vn {sign * math.cos(b) * math.cos(a):.6f} {sign * math.sin(b):.6f} "
                         f"{-sign * math.cos(b) * math.sin(a):.6f}")
    at = lambda i, j: 1 + (i % segments) * sides + j % sides  # noqa: E731  (OBJ counts from 1)
    rest = range(quarter * sides, (segments - 1) * sides)  # faces none of whose rings has an inward vn
    inward = {rest[k] for k in chosen_faces(len(rest))}
    for i in range(segments):
        for j in range(sides):
            corners = (at(i, j), at(i + 1, j), at(i + 1, j + 1), at(i, j + 1))
            if i * sides + j in inward:
                corners = corners[::-1]
            lines.append("f " + " ".join(f"{k}//{k}" for k in corners))
    with open(path, "w") as file:
        file.write("\n".join(lines) + "\n")
    return sorted(inward)


def obj_reversed_vn():
    """The torus OBJ imported through Blender's importer with its defaults, as a user imports it: its `vn` lines
    become custom normals."""
    with tempfile.TemporaryDirectory(prefix="prt_messy_") as folder:
        path = os.path.join(folder, "torus_reversed_vn.obj")
        torus_obj(path)
        bpy.ops.wm.obj_import(filepath=path)
    (ob,) = bpy.context.selected_objects
    return ob


def sliver_edges():
    """A flat-shaded 2 × 1 × 0.6 box whose edges are bevelled by strips 1e-5 of its size wide, each cut into two
    sliver triangles (area about 5e-6 of the size squared, as an OBJ's slivers)."""
    return sliver_bevel(mesh_object("Slivers", *box((0.0, 0.0, 0.3), (2.0, 1.0, 0.6))))


def tube_with_fin(name="Tube", radius=0.5, height=1.2, segments=CYLINDER_SEGMENTS):
    """An open tube standing on z = 0 (no caps: two boundary loops) and a fin on its edge at angle 0, out to twice
    its radius: that edge has three faces."""
    angles = 2.0 * np.pi * np.arange(segments) / segments
    vertices = [(radius * math.cos(a), radius * math.sin(a), z) for z in (0.0, height) for a in angles]
    faces = [(j, (j + 1) % segments, segments + (j + 1) % segments, segments + j) for j in range(segments)]
    vertices += [(2 * radius, 0.0, 0.0), (2 * radius, 0.0, height)]
    faces.append((0, 2 * segments, 2 * segments + 1, segments))
    return smooth_by_angle(mesh_object(name, vertices, faces, smooth=True))


def fender(name, x, y, width=0.3, segments=8):
    """An open half-round sheet over a wheel at x (radius a little above the arch's), centred at y, with a fin
    standing out radially from its middle edge (three faces there)."""
    radius = ARCH_RADIUS + 0.06
    angles = np.linspace(0.0, np.pi, segments + 1)
    vertices = [(x + radius * math.cos(a), y + dy, radius * math.sin(a)) for dy in (-width / 2, width / 2)
                for a in angles]
    n = segments + 1
    faces = [(j + 1, j, n + j, n + j + 1) for j in range(segments)]  # wound outward, away from the wheel
    middle = segments // 2
    vertices += [(x, y - width / 2, radius + 0.15), (x, y + width / 2, radius + 0.15)]
    faces.append((middle, 2 * n, 2 * n + 1, n + middle))
    return mesh_object(name, vertices, faces)


def assembly():
    """A small car of every fault above: a body with two arches and sliver-bevelled edges, a cabin sunk into its
    top whose four windows are wound inward under outward custom normals, four wheels pushed up into the arches
    (standing out of both sides), and an open fender with a fin over the front left wheel, pushed into the body."""
    body = sliver_bevel(mesh_object("Body", *extruded(arched_profile(2.4, 0.6, [-0.7, 0.7]), 1.0)))
    cabin = mesh_object("Cabin", *box((0.0, 0.0, 0.75), (1.2, 0.8, 0.5)))
    outward = [polygon.normal.copy() for polygon in cabin.data.polygons for _ in polygon.vertices]
    set_corner_normals(reverse_winding(cabin, [2, 3, 4, 5]), outward)  # box()'s side faces: the windows
    wheels = [wheel(f"Wheel {k}", x, y) for k, (x, y) in
              enumerate(((-0.7, -0.5), (-0.7, 0.5), (0.7, -0.5), (0.7, 0.5)))]
    return [body, cabin, *wheels, fender("Fender", -0.7, -0.5)]


# -- where a case differs from Cycles ----------------------------------------------------------------------------
BLACK = 0.02  # of the RMS of ‖Cycles‖ over the compared rows: a row darker than this is black


THIN = 1e-4   # of the object's bounding box diagonal: a face narrower than this is thin (Cycles' corner nudge)


def per_row(mesh, per_corner: bool, corners: np.ndarray) -> np.ndarray:
    """A per-corner flag as a flag per compared row: the corner's own, or for a vertex any of its corners'."""
    if per_corner:
        return corners
    vertices = np.zeros(len(mesh.vertices), dtype=bool)
    np.logical_or.at(vertices, np.array([loop.vertex_index for loop in mesh.loops]), corners)
    return vertices


def corner_faults(mesh) -> dict:
    """Per face corner: whether its shading normal points more than 90° away from its face's normal, and whether
    its face is thin (its height over its longest edge, 2·area ÷ longest edge, below THIN × the mesh's size)."""
    positions = np.array([vertex.co for vertex in mesh.vertices])
    size = float(np.linalg.norm(positions.max(axis=0) - positions.min(axis=0)))
    face_normals = np.array([polygon.normal for polygon in mesh.polygons])
    sizes = [len(polygon.vertices) for polygon in mesh.polygons]
    corner_faces = np.repeat(np.arange(len(mesh.polygons)), sizes)
    normals = np.array([normal.vector for normal in mesh.corner_normals])
    longest = np.array([max(np.linalg.norm(positions[polygon.vertices[k]] - positions[polygon.vertices[k - 1]])
                            for k in range(len(polygon.vertices))) for polygon in mesh.polygons])
    heights = 2.0 * np.array([polygon.area for polygon in mesh.polygons]) / np.maximum(longest, 1e-300)
    return {"normal_against_face": np.einsum("ij,ij->i", normals, face_normals[corner_faces]) < 0.0,
            "on_thin_face": (heights < THIN * size)[corner_faces]}


def diagnose(names, check) -> dict:
    """Over the compared rows of every baked object, with Cycles' noise in (the mean of its passes): the rows black
    in Cycles but lit in PRT, lit in Cycles but black in PRT, with a shading normal against its face, and on a thin
    face, each with its count and share of the squared difference; and over the other rows the RMS and how much
    brighter PRT is on average, relative to the RMS of ‖Cycles‖ as validation's figures."""
    prt, cycles, faults = [], [], []
    for name in names:
        ob = bpy.data.objects[name]
        colours, passes, _ = assets.compared_colours(check, ob)
        prt.append(colours)
        cycles.append(passes.mean(axis=0))
        per_corner = storage.corner_points_of(ob.data) is not None
        faults.append({key: per_row(ob.data, per_corner, flags) for key, flags in corner_faults(ob.data).items()})
    prt, cycles = np.concatenate(prt), np.concatenate(cycles)
    scale = float(np.sqrt(np.mean(np.sum(cycles ** 2, axis=1))))
    squared = np.sum((prt - cycles) ** 2, axis=1)
    dark_cycles = np.linalg.norm(cycles, axis=1) < BLACK * scale
    dark_prt = np.linalg.norm(prt, axis=1) < BLACK * scale
    groups = {"cycles_black_prt_lit": dark_cycles & ~dark_prt, "prt_black_cycles_lit": dark_prt & ~dark_cycles,
              **{key: np.concatenate([found[key] for found in faults]) for key in faults[0]}}
    found = {key: {"rows": int(mask.sum()), "share": float(squared[mask].sum() / max(squared.sum(), 1e-300))}
             for key, mask in groups.items()}
    other = ~np.any(list(groups.values()), axis=0)
    brighter = np.linalg.norm(prt, axis=1) - np.linalg.norm(cycles, axis=1)
    found["other"] = {"rows": int(other.sum()), "rms": float(np.sqrt(np.mean(squared[other])) / scale),
                      "prt_brighter": float(np.mean(brighter[other]) / scale)} if other.any() else {}
    words = {"cycles_black_prt_lit": "Cycles black, PRT lit", "prt_black_cycles_lit": "PRT black, Cycles lit",
             "normal_against_face": "normal against its face", "on_thin_face": "on a thin face"}
    found["line"] = ", ".join(f"{text} {found[key]['rows']} ({100 * found[key]['share']:.0f} %)"
                              for key, text in words.items() if found[key]["rows"])
    if found["other"]:
        found["line"] += ("; " if found["line"] else "") + (
            f"the other {found['other']['rows']} rows RMS {100 * found['other']['rms']:.2f} %, PRT "
            f"{100 * found['other']['prt_brighter']:+.2f} % brighter on average")
    return found


def on_thin_faces(mesh) -> np.ndarray:
    """Per compared row: a corner (or a vertex with a corner) on a face narrower than Cycles' corner nudge, whose
    value in Cycles is its float rounding (docs/cycles_conventions.md, R4): every case compares these apart."""
    return per_row(mesh, storage.corner_points_of(mesh) is not None, corner_faults(mesh)["on_thin_face"])


def case(*args, **kwargs):
    return assets.Case(*args, **kwargs, left_out=on_thin_faces)


CASES = [
    case("boxes crossing", boxes_crossing, small=True, what="two boxes of one mesh interpenetrating"),
    case("wheel in arch", wheel_in_arch, small=True, what="a wheel pushed into a body's arch"),
    case("normals against winding", normals_against_winding, small=True,
         what="a fifth of a sphere's faces wound inward, custom normals out"),
    case("OBJ reversed vn", obj_reversed_vn, small=True,
         what="a torus OBJ: a quarter's vn inward, a fifth of faces against their vn"),
    case("sliver edges", sliver_edges, small=True, what="edges bevelled by 1e-5-wide sliver triangles"),
    case("open parts", tube_with_fin, small=True, what="an open tube with a fin: a non-manifold edge"),
    case("assembly", assembly, what="a small car of all of these on the floor"),
]


if __name__ == "__main__":
    sys.exit(assets.main(catalogue=CASES, title="messy assets", diagnose=diagnose))
