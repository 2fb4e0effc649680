"""Real assets, baked at the defaults as a user would and validated against Cycles (issue 13, items 6 and 7).

Each case starts from a fresh empty file: the asset (an OBJ of ../shared/assets through Blender's own importer,
as imported, so flat-shaded; or made in Blender with the shading under test), scaled to fit 2 units and resting on
a floor of a few quads, larger than it. The asset is baked at the defaults (order 4, shadowed, 256 samples; the
floor is an occluder only), validated against Cycles corner by corner where its vertices are split, and the bake's
actual error is measured against a many-ray reference bake (16 × the samples, another seed) at a random sample
of the same shading points, in the measure of the bake's own estimate: RMS over points of ‖T − T_ref‖ ÷
‖T_unshadowed‖ (benchmarks/convergence.py's coefficient_error); the estimate holds the noise and the doubt of the
points a rule set black.

Goals: every asset RMS ≤ 2 % and p99 ≤ 10 % against Cycles; the demo scene RMS ≤ 1 %; actual ÷ estimated error
within 1/1.5..1.5 for every case.

Run from the repository root:  .venv/bin/python benchmarks/assets.py [--quick] [--samples N] [--passes N]
                                   [--cases a,b] [--reference-points N] [--workers N] [--json [DIR]]
"""

import argparse
from dataclasses import asdict, dataclass, field
import math
import os
import sys
import time

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
sys.path.insert(0, ROOT)

import bpy  # noqa: E402  (bpy before mathutils, which the add-on imports)
import numpy as np  # noqa: E402

from benchmarks import results as result_files  # noqa: E402
from benchmarks.asset_goals import DEMO, goal_lines, goals, missed_goals  # noqa: E402
from benchmarks.bake import Picks, bake_picks  # noqa: E402
from benchmarks.convergence import REFERENCE_FACTOR, REFERENCE_SEED_OFFSET, coefficient_error  # noqa: E402
from prt_addon.blender import geometry, mesh_arrays, sample_scenes, schema, storage, validation  # noqa: E402
from prt_addon.blender.scene_bake import SceneBake  # noqa: E402
from prt_addon.commands.common import schema_registered  # noqa: E402
from prt_addon.core import lights  # noqa: E402
from prt_addon.core.bake import BakeSettings  # noqa: E402
from prt_addon.core.statistics import compare, rms  # noqa: E402

ASSETS = os.path.join(os.path.dirname(ROOT), "shared", "assets")
ASSET_SIZE = 2.0    # the asset's largest world dimension after placing it
FLOOR_SIZE = 6.0    # the floor's side: 3 × the asset
FLOOR_QUADS = 3     # per side: a plane of a few quads
LOW_SUN_THETA = math.radians(75.0)  # the spheres' sun, low over the horizon: a long terminator
PICK_SEED = 20260601                # which points the reference bakes; fixed so runs compare
CONTACT = 1e-5          # of the asset's size: a point this close to z = 0 lies on the floor
CONTACT_NORMAL_Z = 1e-3  # and faces into it when its normal's z is below minus this
EXACT = 1e-5            # an actual error this small beside a zero estimate: both exact (float32 storage)


# -- building the cases ------------------------------------------------------------------------------------------
def fresh_file():
    bpy.ops.wm.read_homefile(use_empty=True)


def import_obj(name: str):
    """The OBJ through Blender's importer with its defaults, as a user imports it (no normals in these files:
    flat-shaded)."""
    path = os.path.join(ASSETS, f"{name}.obj")
    if not os.path.isfile(path):
        raise FileNotFoundError(f"{path} is missing (the public test meshes live in ../shared/assets)")
    bpy.ops.wm.obj_import(filepath=path)
    (ob,) = bpy.context.selected_objects
    return ob


def evaluated_world_positions(ob) -> np.ndarray:
    bpy.context.view_layer.update()
    evaluated = ob.evaluated_get(bpy.context.evaluated_depsgraph_get())
    mesh = evaluated.to_mesh()
    try:
        return geometry.points_to_world(np.array(ob.matrix_world), mesh_arrays.mesh_positions(mesh))
    finally:
        evaluated.to_mesh_clear()


def place(objects: list, size: float = ASSET_SIZE):
    """Scales the objects uniformly together (their transforms, as a user scales a selection about one pivot) so
    that their largest world dimension is `size`, centres them over the origin and rests their lowest point on the
    floor (z = 0). Objects without parents only."""
    world = np.concatenate([evaluated_world_positions(ob) for ob in objects])
    low, high = world.min(axis=0), world.max(axis=0)
    factor = size / float((high - low).max())
    anchor = np.array([(low[0] + high[0]) / 2, (low[1] + high[1]) / 2, low[2]])
    # world' = factor · (world − anchor): a uniform scale commutes with each object's rotation, so scaling its
    # transform and moving its origin does it.
    for ob in objects:
        ob.location = (factor * (np.array(ob.location) - anchor)).tolist()
        ob.scale = [factor * s for s in ob.scale]
    bpy.context.view_layer.update()


def add_floor():
    bpy.ops.mesh.primitive_grid_add(x_subdivisions=FLOOR_QUADS, y_subdivisions=FLOOR_QUADS, size=FLOOR_SIZE)
    floor = bpy.context.active_object
    floor.name = floor.data.name = "Floor"
    return floor


def add_low_sun(scene):
    """SH lights (saved settings, so blender.schema must be registered): the default light's Hanning-windowed sun
    over its sky, but with the sun at θ 75°, so the spheres' terminator runs across them; nowhere negative (no
    clamping)."""
    sun = schema.add_light(scene, "SUN")
    sun.theta, sun.phi = LOW_SUN_THETA, lights.DEFAULT_SUN["phi"]
    sun.angular_radius, sun.strength = lights.DEFAULT_SUN["angular_radius"], lights.DEFAULT_SUN["irradiance"]
    schema.add_light(scene, "SKY").strength = lights.DEFAULT_SKY
    scene.prt_display.window = "hanning"


def obj_case(name, smooth=False):
    def build():
        ob = import_obj(name)
        if smooth:
            ob.data.shade_smooth()
        return ob
    return build


def bevelled_box():
    """A cube with its bevel applied (the bake refuses modifiers that change the vertex count) and a Weighted
    Normal modifier kept live: custom normals, leaning towards the large faces."""
    bpy.ops.mesh.primitive_cube_add(size=2.0)
    ob = bpy.context.active_object
    bevel = ob.modifiers.new("Bevel", "BEVEL")
    bevel.width, bevel.segments = 0.1, 3
    bpy.ops.object.modifier_apply(modifier=bevel.name)
    ob.data.shade_smooth()
    ob.modifiers.new("WeightedNormal", "WEIGHTED_NORMAL").keep_sharp = True
    return ob


def smooth_by_angle_cylinder():
    """A cylinder shaded Smooth by Angle (30°): smooth sides, sharp rims. Set in the mesh's data, as Shade Smooth by
    Angle does: the Shade Auto Smooth operator needs Blender's essentials asset library, which 4.5's bpy module
    lacks (it silently adds nothing there)."""
    bpy.ops.mesh.primitive_cylinder_add(vertices=32, radius=0.6, depth=2.0)
    ob = bpy.context.active_object
    ob.data.shade_smooth()
    ob.data.set_sharp_from_angle(angle=math.radians(30.0))
    return ob


def uv_sphere(name="Sphere", segments=16, rings=8):
    """A unit UV sphere like Blender's primitive (poles on z, triangles at the poles, quads between), its vertices
    and faces in a fixed order: the primitive's corner order, and with it its quads' diagonals, changes from one
    process to the next in Blender 5.0 (bmesh.ops.create_uvsphere's too), and the flat sphere's row with it (0.00 or
    0.31 % RMS against Cycles, depending on the run)."""
    polar = np.pi * np.arange(1, rings) / rings
    azimuth = 2.0 * np.pi * np.arange(segments) / segments
    ring = np.stack([np.outer(np.sin(polar), np.cos(azimuth)), np.outer(np.sin(polar), np.sin(azimuth)),
                     np.repeat(np.cos(polar)[:, None], segments, axis=1)], axis=-1).reshape(-1, 3)
    vertices = np.vstack([[0.0, 0.0, 1.0], ring, [0.0, 0.0, -1.0]])
    bottom = len(vertices) - 1
    at = lambda band, j: 1 + band * segments + j % segments  # noqa: E731  (ring `band`'s vertex j)
    faces = [(0, at(0, j), at(0, j + 1)) for j in range(segments)]
    faces += [(at(band, j), at(band + 1, j), at(band + 1, j + 1), at(band, j + 1))
              for band in range(rings - 2) for j in range(segments)]
    faces += [(bottom, at(rings - 2, j + 1), at(rings - 2, j)) for j in range(segments)]
    mesh = bpy.data.meshes.new(name)
    mesh.from_pydata(vertices.tolist(), [], faces)
    ob = bpy.data.objects.new(name, mesh)
    bpy.context.collection.objects.link(ob)
    bpy.context.view_layer.objects.active = ob
    return ob


def low_poly_sphere(smooth):
    def build():
        ob = uv_sphere()
        if smooth:
            ob.data.shade_smooth()
        else:
            ob.data.shade_flat()
        add_low_sun(bpy.context.scene)
        return ob
    return build


def thin_sheet():
    """A 16 × 16 grid given 0.005 of thickness by an applied Solidify, leaning at 45°: light must not leak
    between its two sides, 0.25 % of its size apart."""
    bpy.ops.mesh.primitive_grid_add(x_subdivisions=16, y_subdivisions=16, size=2.0)
    ob = bpy.context.active_object
    solidify = ob.modifiers.new("Solidify", "SOLIDIFY")
    solidify.thickness = 0.005
    bpy.ops.object.modifier_apply(modifier=solidify.name)
    ob.rotation_euler = (math.radians(45.0), 0.0, 0.0)
    return ob


@dataclass(frozen=True)
class Case:
    name: str
    build: object        # () → the asset object or a list of them (None: the demo scene, baked whole)
    small: bool = False  # in --quick
    what: str = ""
    # (mesh) → (R,) bool per compared row (vertex, or corner of a per-corner bake): rows where Cycles' answer is its
    # float rounding rather than the geometry (docs/cycles_conventions.md, R4), compared apart; None: none.
    left_out: object = None


CASES = [
    Case("rocker-arm", obj_case("rocker-arm"), what="CAD part, OBJ as imported (flat)"),
    Case("rocker-arm smooth", obj_case("rocker-arm", smooth=True), what="the same after Shade Smooth"),
    Case("cow", obj_case("cow"), what="OBJ as imported (flat)"),
    Case("homer", obj_case("homer"), what="OBJ as imported (flat)"),
    Case("teapot", obj_case("teapot"), what="OBJ as imported (flat)"),
    Case("woody", obj_case("woody"), small=True, what="OBJ as imported: a flat cut-out standing up"),
    Case("bevelled box", bevelled_box, small=True, what="bevel applied, Weighted Normal modifier"),
    Case("cylinder", smooth_by_angle_cylinder, small=True, what="Smooth by Angle: sharp rims"),
    Case("sphere flat", low_poly_sphere(smooth=False), small=True, what="UV 16 × 8, flat, sun at θ 75°"),
    Case("sphere smooth", low_poly_sphere(smooth=True), small=True, what="UV 16 × 8, smooth, sun at θ 75°"),
    Case("thin sheet", thin_sheet, small=True, what="Solidify 0.005 applied, leaning"),
    Case(DEMO, None, what="sample_scenes.build_demo_scene(), every mesh baked"),
]


def case_named(name, cases=CASES) -> Case:
    return next(case for case in cases if case.name == name)


def build_case(case: Case) -> list:
    """A fresh file with the case in it; returns the names of the objects to bake."""
    fresh_file()
    if case.build is None:
        objects = sample_scenes.build_demo_scene()
        return [ob.name for ob in objects.values() if ob.type == "MESH"]
    built = case.build()
    objects = built if isinstance(built, list) else [built]
    place(objects)
    add_floor()
    return [ob.name for ob in objects]


# -- measuring one case ------------------------------------------------------------------------------------------
@dataclass
class Settings:
    bake_samples: int = 256       # the add-on's default
    cycles_samples: int = validation.DEFAULT_SAMPLES
    passes: int = validation.DEFAULT_PASSES
    reference_points: int = 2048  # shading points the reference bakes (all of them when fewer)
    workers: int = 1              # the add-on's default
    ray_engine: str = BakeSettings.ray_engine  # the add-on's default, Auto

    @property
    def reference_samples(self) -> int:
        return REFERENCE_FACTOR * self.bake_samples


@dataclass
class Row:
    case: str
    vertices: int
    split_vertices: int
    points: int
    bake_s: float
    cycles_s: float
    rel_rms_error: float       # against Cycles, Cycles' noise taken out
    rel_p99_error: float
    rel_max_difference: float
    est_rms_rel_error: float   # the bake's own estimate, over all its points
    actual_rms_rel_error: float  # against the reference bake, at the reference points
    est_at_reference: float    # the bake's estimate at the same points
    reference_points: int
    reference_s: float
    cycles_noise_rel_rms: float
    measured_rel_rms: float
    light: str
    worst: str
    touching: int              # compared rows on the floor facing into it (touching_floor)
    off_floor_rms: float       # against Cycles without them
    off_floor_p99: float
    left_out: int = 0          # rows compared apart (Case.left_out): the figures above are the rest's
    left_out_rms: float = 0.0  # theirs, relative to the RMS of Cycles over all rows
    all_rows_rms: float = 0.0  # over all rows, left-out ones included
    all_rows_p99: float = 0.0
    goals_missed: list = field(default_factory=list)

    @property
    def honesty(self) -> float:
        """actual ÷ estimated error, at the same points; 1 where the bake says it is exact (no point's transfer
        has noise: every occluder in closed form) and the reference agrees to float32 round-off."""
        if self.est_at_reference > 0:
            return self.actual_rms_rel_error / self.est_at_reference
        return 1.0 if self.actual_rms_rel_error <= EXACT else float("inf")

    @property
    def exact(self) -> bool:
        return self.est_at_reference == 0 and self.actual_rms_rel_error <= EXACT


def bake_scene(names, settings: Settings) -> SceneBake:
    scene_bake = SceneBake(bpy.context, BakeSettings(samples=settings.bake_samples, ray_engine=settings.ray_engine),
                           names, settings.workers)
    scene_bake.run()
    return scene_bake


def validate(names, settings: Settings):
    """Validation against Cycles → (validation, comparisons, report dict)."""
    check = validation.Validation(bpy.context, settings.cycles_samples, settings.passes, names)
    comparisons = check.run()
    return check, comparisons, check.report(comparisons).as_dict()


def reference_error(scene_bake: SceneBake, settings: Settings) -> dict:
    """The bake's actual error against a reference bake of 16 × the samples with another seed, at up to
    `reference_points` random shading points (all of them when fewer), and its own estimate at those points (the
    noise and the rules' doubt)."""
    receivers = [receiver.layout.receiver for receiver in scene_bake.plan.receivers]
    owners = np.concatenate([np.full(len(r.positions), k) for k, r in enumerate(receivers)])
    indices = np.concatenate([np.arange(len(r.positions)) for r in receivers])
    chosen = np.arange(len(owners))
    if len(owners) > settings.reference_points:
        chosen = np.sort(np.random.default_rng(PICK_SEED).choice(len(owners), settings.reference_points,
                                                                 replace=False))
    picks = Picks(owners[chosen], indices[chosen])
    seed = scene_bake.plan.settings.seed + REFERENCE_SEED_OFFSET
    reference_settings = BakeSettings(order=scene_bake.plan.settings.order, samples=settings.reference_samples,
                                      max_samples=max(settings.reference_samples, BakeSettings.max_samples),
                                      seed=seed)
    start = time.perf_counter()
    reference, _, _ = bake_picks(receivers, scene_bake.plan.occluders, picks, reference_settings, settings.workers)
    seconds = time.perf_counter() - start
    stored = picks.of([storage.read_transfer(ob.data)[0] for ob in scene_bake.objects])  # what the mesh holds
    results = scene_bake.results.results
    noise, doubt = (picks.of([getattr(result, name) for result in results]) for name in ("rel_error", "rel_rule_error"))
    return {"actual": coefficient_error({"points": stored}, {"points": reference}, scene_bake.plan.settings.order),
            "estimate": rms(np.hypot(noise, doubt)), "noise_estimate": rms(noise), "rule_estimate": rms(doubt),
            "points": len(chosen), "time_s": seconds}


def compared_colours(check, ob):
    """The object's rows as validation compares them (its vertices, or its face corners where the bake is per
    corner) → (PRT colours (R, 3), Cycles' passes (k, R, 3), the shading point of each row (R,))."""
    _, meta = storage.read_transfer(ob.data)
    corner_points = storage.corner_points_of(ob.data)
    rows = np.arange(len(ob.data.vertices)) if corner_points is None else corner_points
    return check.colours(ob, check.lights[meta["order"]]), np.stack(check.cycles.radiance[ob.name]), rows


def touching_floor(receiver, rows) -> np.ndarray:
    """Rows whose shading point lies on the floor (z = 0) and faces into it: sandwiched between the asset and the
    floor, where Cycles sees no light."""
    return ((receiver.positions[rows, 2] <= CONTACT * ASSET_SIZE)
            & (receiver.normals[rows, 2] < -CONTACT_NORMAL_Z))


def measure(case: Case, settings: Settings, log=print) -> tuple:
    """Builds, bakes, validates and measures the case → (row, validation, touching): touching is, per baked
    object, the mask of its compared rows that touch the floor."""
    names = build_case(case)
    log(f"{case.name}: baking {', '.join(names)}")
    scene_bake = bake_scene(names, settings)
    summary = scene_bake.summary
    log(f"  {summary.line()}")
    log(f"  Cycles, {settings.passes} × {settings.cycles_samples} samples")
    check, comparisons, report = validate(names, settings)
    log(f"  reference bake, {settings.reference_samples} samples")
    reference = reference_error(scene_bake, settings)
    log(f"  at {reference['points']} points: actual {100 * reference['actual']:.2f} %, estimated "
        f"{100 * reference['estimate']:.2f} % (noise {100 * reference['noise_estimate']:.2f} %, rules "
        f"{100 * reference['rule_estimate']:.2f} %)")
    compared = report if len(names) > 1 else report["per_object"][names[0]]
    parts, touching, every, apart = [], {}, [], []
    receivers = [planned.layout.receiver for planned in scene_bake.plan.receivers]
    for ob, receiver in zip(scene_bake.objects, receivers):
        colours, passes, rows = compared_colours(check, ob)
        touching[ob.name] = touching_floor(receiver, rows)
        left_out = np.zeros(len(rows), dtype=bool) if case.left_out is None else case.left_out(ob.data)
        kept = ~touching[ob.name] & ~left_out
        parts.append((colours[kept], passes[:, kept]))
        every.append((colours, passes))
        apart.append(left_out)
    off_floor = compare("off the floor", np.concatenate([c for c, _ in parts]),
                        np.concatenate([p for _, p in parts], axis=1))
    apart = np.concatenate(apart)
    rms_error, p99, largest = compared["rel_rms_error"], compared["rel_p99_error"], compared["rel_max_difference"]
    whole = None
    if apart.any():  # the goals judge the rest; the left-out rows' own figure is printed beside them
        colours, passes = np.concatenate([c for c, _ in every]), np.concatenate([p for _, p in every], axis=1)
        whole, rest = compare("all", colours, passes), compare("rest", colours[~apart], passes[:, ~apart])
        rms_error, p99, largest = rest.error, rest.p99, rest.max_difference
    row = Row(case.name, summary.vertices, summary.split_vertices, summary.points, summary.time_s,
              check.cycles.time_s, rms_error, p99, largest, summary.est_rms_rel_error, reference["actual"],
              reference["estimate"], reference["points"], reference["time_s"], compared["cycles_noise_rel_rms"],
              compared["measured_rel_rms"], "scene SH lights" if check.scene_light else "default light",
              check.worst_line(comparisons).strip(), int(sum(mask.sum() for mask in touching.values())),
              off_floor.error, off_floor.p99, int(apart.sum()),
              0.0 if whole is None else rms(whole.errors[apart]), compared["rel_rms_error"],
              compared["rel_p99_error"])
    row.goals_missed = missed_goals(row)
    return row, check, touching


def smooth_normal_errors(name: str, check, touching, settings: Settings) -> dict:
    """For a flat-shaded object just baked per corner and validated (`check`): its RMS error against Cycles and
    the RMS error a bake with the smooth vertex normals has against the very same Cycles corners, over all
    corners and over those not touching the floor (mask `touching`). The second bake is of the same object after
    Shade Smooth (one transfer per vertex, shown on each of its corners: what a bake blind to the corner normals
    stores and shows); Cycles is not run again. Same reference, same measure: only the normal the transfer
    was baked with differs."""
    ob = bpy.data.objects[name]
    corner_colours, passes, _ = compared_colours(check, ob)
    corner_vertices = mesh_arrays.mesh_corner_vertices(ob.data)
    ob.data.shade_smooth()
    bake_scene([name], settings)
    transfer, meta = storage.read_transfer(ob.data)
    if meta["domain"] != "POINT":
        raise AssertionError(f"{name!r} after Shade Smooth should be baked per vertex")
    smooth = validation.prt_colours(transfer[corner_vertices], check.lights[meta["order"]],
                                    check.albedos[ob][corner_vertices])
    off = ~touching
    return {"per_corner": compare("per corner", corner_colours, passes).error,
            "smooth_normals": compare("smooth normals", smooth, passes).error,
            "per_corner_off_floor": compare("per corner", corner_colours[off], passes[:, off]).error,
            "smooth_normals_off_floor": compare("smooth normals", smooth[off], passes[:, off]).error}


# -- goals and the table -----------------------------------------------------------------------------------------
COLUMNS = [  # header, width, format of a row
    ("case", 17, lambda r: r.case),
    ("vertices", 8, lambda r: f"{r.vertices}"),
    ("split", 6, lambda r: f"{r.split_vertices}"),
    ("points", 6, lambda r: f"{r.points}"),
    ("bake s", 6, lambda r: f"{r.bake_s:.1f}"),
    ("Cycles s", 8, lambda r: f"{r.cycles_s:.1f}"),
    ("apart", 5, lambda r: f"{r.left_out}"),
    ("RMS %", 6, lambda r: f"{100 * r.rel_rms_error:.2f}"),
    ("p99 %", 6, lambda r: f"{100 * r.rel_p99_error:.1f}"),
    ("max %", 6, lambda r: f"{100 * r.rel_max_difference:.0f}"),
    ("est. %", 6, lambda r: f"{100 * r.est_rms_rel_error:.2f}"),
    ("actual/est.", 11, lambda r: "exact" if r.exact else f"{r.honesty:.2f}"),
    ("goals", 0, lambda r: "MISS " + ", ".join(r.goals_missed) if r.goals_missed else "ok"),
]


def table(rows) -> list[str]:
    def line(cells):
        return "  ".join(cell.ljust(w) if k == 0 else cell.rjust(w) for k, (cell, (_, w, _)) in
                         enumerate(zip(cells, COLUMNS))).rstrip()
    return [line([header for header, _, _ in COLUMNS])] + [line([fmt(row) for _, _, fmt in COLUMNS])
                                                           for row in rows]


# -- the run -----------------------------------------------------------------------------------------------------
def cycles_arguments(parser, quick_samples: int, quick_passes: int):
    """--samples and --passes of the Cycles renders a benchmark compares with, and what --quick makes them."""
    parser.add_argument("--samples", type=int, help=f"Cycles samples per pass (default "
                        f"{validation.DEFAULT_SAMPLES}; --quick {quick_samples})")
    parser.add_argument("--passes", type=int, help=f"Cycles passes (default {validation.DEFAULT_PASSES}; "
                        f"--quick {quick_passes})")


def build_parser(cases):
    parser = argparse.ArgumentParser(description="real assets baked at the defaults, validated against Cycles")
    parser.add_argument("--quick", action="store_true",
                        help="smoke run: the small cases only, 64-sample bakes, Cycles 2 × 16 samples")
    cycles_arguments(parser, quick_samples=16, quick_passes=2)
    parser.add_argument("--cases", help="comma-separated case names (default: all; --quick: the small ones): "
                        + ", ".join(case.name for case in cases))
    parser.add_argument("--reference-points", type=int, default=Settings.reference_points,
                        help="shading points per case the reference bake bakes (default %(default)s)")
    parser.add_argument("--workers", type=int, default=1, help="bake workers (default 1, the add-on's default)")
    result_files.add_argument(parser)
    return parser


def main(argv=None, catalogue=CASES, title="assets", diagnose=None) -> int:
    """Runs the catalogue's cases (all, --quick's small ones, or --cases) and prints the table and the goals.
    diagnose(names, check) → dict, when given, looks into each case after it is measured: its "line" is printed
    after the table, the dict goes into the JSON."""
    parser = build_parser(catalogue)
    args = parser.parse_args(argv)
    result_files.check_folder(parser, args)
    names = [case.name for case in catalogue]
    settings = Settings(bake_samples=64 if args.quick else 256,
                        cycles_samples=args.samples or (16 if args.quick else validation.DEFAULT_SAMPLES),
                        passes=args.passes or (2 if args.quick else validation.DEFAULT_PASSES),
                        reference_points=args.reference_points, workers=args.workers)
    if args.cases:
        wanted = [name.strip() for name in args.cases.split(",")]
        unknown = [name for name in wanted if name not in names]
        if unknown:
            print(f"{title}: error: no case {', '.join(map(repr, unknown))}; cases: {', '.join(names)}",
                  file=sys.stderr)
            return 1
        cases = [case_named(name, catalogue) for name in wanted]
    else:
        cases = [case for case in catalogue if case.small or not args.quick]
    print(f"{title} benchmark: {len(cases)} cases; bake order 4 shadowed, {settings.bake_samples} samples, "
          f"{settings.workers} worker(s); Cycles {settings.passes} × {settings.cycles_samples} samples; reference "
          f"{settings.reference_samples} samples at up to {settings.reference_points} points per case"
          + ("  (quick: the goals are for the full run)" if args.quick else ""), flush=True)
    rows, started, extra = [], time.perf_counter(), {}
    with schema_registered():  # the spheres' SH lights are saved settings (blender.schema)
        for case in cases:
            row, check, touching = measure(case, settings, log=lambda line: print(line, flush=True))
            rows.append(row)
            if diagnose is not None:
                extra.setdefault("diagnosis", {})[case.name] = diagnose(list(touching), check)
            if case.name == "sphere flat":  # the same sphere baked with its smooth vertex normals instead
                (name,) = touching
                extra["sphere_flat_vs_smooth_normals"] = smooth_normal_errors(name, check, touching[name], settings)
    total = time.perf_counter() - started
    print()
    for line in table(rows):
        print(line)
    print()
    for row in rows:
        print(f"{row.case}: {row.worst}")
    print()
    print("Without the vertices / corners on the floor facing into it (Cycles: no light there):")
    for row in rows:
        print(f"  {row.case}: {row.touching} on the floor; without them RMS {100 * row.off_floor_rms:.2f} %, "
              f"p99 {100 * row.off_floor_p99:.1f} %")
    if any(row.left_out for row in rows):
        print("Compared apart, the goals judging the rest (faces narrower than Cycles' corner nudge):")
    for row in rows:
        if row.left_out:
            print(f"  {row.case}: {row.left_out} rows compared apart (Cycles' rounding decides them: "
                  f"docs/cycles_conventions.md, R4), their RMS {100 * row.left_out_rms:.2f} %; with them RMS "
                  f"{100 * row.all_rows_rms:.2f} %, p99 {100 * row.all_rows_p99:.1f} %")
    if "diagnosis" in extra:
        print("\nWhere each case differs (rows: count and share of the squared difference; Cycles' noise in):")
    for name, found in extra.get("diagnosis", {}).items():
        print(f"  {name}: {found['line']}")
    if "sphere_flat_vs_smooth_normals" in extra:
        errors = extra["sphere_flat_vs_smooth_normals"]
        print(f"sphere flat baked with its smooth vertex normals instead, against the same Cycles corners: RMS "
              f"{100 * errors['smooth_normals']:.1f} % (per corner {100 * errors['per_corner']:.2f} %); off the "
              f"floor {100 * errors['smooth_normals_off_floor']:.1f} % (per corner "
              f"{100 * errors['per_corner_off_floor']:.2f} %)")
    print()
    judged = goals(rows)
    for line in goal_lines(rows):
        print(line)
    print(f"total {total / 60:.1f} min")
    if args.json:
        result_files.write(title.replace(" ", "_"), args, {
            "settings": {**asdict(settings), "reference_samples": settings.reference_samples},
            "rows": [{**asdict(row), "actual_to_estimate": row.honesty} for row in rows], **extra, "total_s": total},
            judged, argv)
    return 0


if __name__ == "__main__":
    sys.exit(main())
