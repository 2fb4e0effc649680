"""The corner points of one vertex share their rays (core.corners.ray_groups, core.estimator._blocked_round): each
point's estimate stays unbiased and its error estimate honest, against polygon quadrature that does not use the
code under test."""

import numpy as np
import pytest

from quadrature import polygon_transfer, reference_sh

from prt_addon.core import bake, corners, interreflect, job, lobes, rings, scheduling
from prt_addon.core.engines.reference import ReferenceEngine

ENGINE = "reference"  # the estimator's tests need no Blender

# Three corner normals of one vertex, which share one ray group in the tests below.
NORMALS = np.array([[0.0, 0.0, 1.0], [np.sin(0.6), 0.0, np.cos(0.6)], [0.0, -np.sin(0.9), np.cos(0.9)]])
ROOF = np.array([[-0.4, -1.0, 0.8], [1.2, -1.0, 0.8], [1.2, 0.6, 1.1], [-0.4, 0.6, 1.1]])  # tilted, off-centre


def roof_occluders(as_polygon=False):
    triangles = np.array([[0, 1, 2], [0, 2, 3]])
    return bake.Occluders(ROOF, triangles, ROOF.copy(), [ROOF] if as_polygon else [], engine=ENGINE)


def shared_vertices(count):
    """`count` independent vertices at the origin, each split into the three NORMALS that share one ray group."""
    normals = np.tile(NORMALS, (count, 1))
    return bake.Receiver("split", np.zeros((3 * count, 3)), normals, 17, None, np.repeat(np.arange(count), 3))


def truth(order):
    """Quadrature: the unshadowed transfer minus what the roof blocks, per normal."""
    return np.array([lobes.unshadowed_transfer(order, n[None])[0] - polygon_transfer(order, np.zeros(3), n, ROOF)
                     for n in NORMALS])


def bake_points(receiver, occluders, **settings):
    the_job = job.TransferJob([receiver], occluders, bake.BakeSettings(**settings))
    return the_job.run()[0]


def test_ray_groups_part_a_vertex_only_where_its_normals_spread_beyond_the_share_angle():
    # Vertex 0 is a thin sheet's rim: two corners face up, two down, one out (90° from both); vertex 1 is alone;
    # vertex 2's three normals are 40° from their mean but 80° apart.
    tilt = np.radians(40.0)
    spread = [[np.sin(tilt) * np.cos(a), np.sin(tilt) * np.sin(a), np.cos(tilt)] for a in (0.0, 2.1, 4.2)]
    point_vertices = np.array([0, 1, 2, 0, 0, 0, 0, 2, 2])
    normals = np.array([[0, 0, 1.0], [1.0, 0, 0], spread[0], [0, 0, -1.0], [0, 0.1, 0.995], [1.0, 0, 0],
                        [0, 0, -1.0], spread[1], spread[2]])
    np.testing.assert_array_equal(corners.ray_groups(point_vertices, normals, 3), [0, 1, 2, 3, 0, 5, 3, 2, 2])


def greedy_parting(normals):
    """The parting rule, one vertex at a time (normals (k, 3)): the point with the most others within SHARE_COSINE
    of it gathers them, then those farthest from the group's mean leave one by one until all are within it."""
    near = normals @ normals.T >= corners.SHARE_COSINE
    np.fill_diagonal(near, True)
    left, groups = np.ones(len(normals), dtype=bool), []
    while left.any():
        members = list(np.flatnonzero(near[np.argmax((near & left).sum(1) * left)] & left))
        while len(members) > 1:
            mean = normals[members].sum(0)
            cosines = normals[members] @ (mean / max(np.linalg.norm(mean), 1e-300))
            if cosines.min() >= corners.SHARE_COSINE:
                break
            members.pop(int(np.argmin(cosines)))
        left[members] = False
        groups.append(members)
    return groups


def test_ray_groups_part_every_vertex_at_once_as_the_greedy_rule_does_one_by_one():
    """Vertices of 2-12 points with normals from nearly one direction to any, some zero (degenerate faces), parted
    all at once, give the labels of the rule applied vertex by vertex."""
    generator = np.random.default_rng(11)
    # points 0-399 are the vertices' own, the rest their other corners' (as core.corners.shading_points numbers them)
    point_vertices = np.concatenate([np.arange(400), np.repeat(np.arange(400), generator.integers(1, 12, 400))])
    spread = generator.uniform(0.2, 3.0, 400)[point_vertices, None]
    normals = generator.normal(size=(len(point_vertices), 3)) * spread * [1.0, 1.0, 0.0] + [0.0, 0.0, 1.0]
    normals /= np.linalg.norm(normals, axis=1, keepdims=True)
    normals[generator.random(len(normals)) < 0.02] = 0.0
    labels = corners.ray_groups(point_vertices, normals, 400)
    expected, parted = point_vertices.copy(), 0
    for vertex in range(400):
        points = np.flatnonzero(point_vertices == vertex)
        mean = normals[points].sum(0) / max(np.linalg.norm(normals[points].sum(0)), 1e-300)
        if (normals[points] @ mean).min() < corners.SHARE_COSINE:  # else one group, labelled by the vertex
            parted += 1
            for members in greedy_parting(normals[points]):
                expected[points[members]] = points[members].min()
    np.testing.assert_array_equal(labels, expected)
    assert 100 < parted < 400 and len(np.unique(labels)) > 400 + parted  # teeth: most vertices part, some in 3+


def test_every_ray_group_lies_within_the_share_angle_of_its_mean_normal():
    """Random corner normals: a group never spans two vertices, its normals are within SHARE_COSINE of their mean,
    and a vertex whose normals all are forms one group."""
    generator = np.random.default_rng(5)
    point_vertices = np.concatenate([np.arange(300), generator.integers(0, 300, 900)])
    normals = generator.normal(size=(1200, 3)) * [0.6, 0.6, 0.0] + [0.0, 0.0, 1.0]
    normals /= np.linalg.norm(normals, axis=1, keepdims=True)
    labels = corners.ray_groups(point_vertices, normals, 300)
    groups_per_vertex = [len(np.unique(labels[point_vertices == vertex])) for vertex in range(300)]
    assert 1 < max(groups_per_vertex) and 150 < groups_per_vertex.count(1) < 300  # teeth: both cases occur
    for label in np.unique(labels):
        members = labels == label
        assert len(np.unique(point_vertices[members])) == 1 and label == np.flatnonzero(members).min()
        mean = normals[members].sum(0) / np.linalg.norm(normals[members].sum(0))
        assert (normals[members] @ mean).min() >= corners.SHARE_COSINE - 1e-12
    for vertex in np.flatnonzero(np.array(groups_per_vertex) > 1):
        own = normals[point_vertices == vertex]
        mean = own.sum(0) / np.linalg.norm(own.sum(0))
        assert (own @ mean).min() < corners.SHARE_COSINE


@pytest.mark.parametrize("as_polygon", [False, True], ids=["rays", "closed-form roof"])
def test_shared_rays_are_unbiased_and_their_error_honest(as_polygon):
    """400 vertices, each three corner points casting one group's rays: every point's mean matches quadrature, the
    actual errors match the estimated ones, and the group cast at most as many rays as one point alone would (less
    those below every point's horizon)."""
    count, order = 400, 3
    result = bake_points(shared_vertices(count), roof_occluders(as_polygon), order=order, samples=64)
    assert 0.9 * count * 64 < result.rays.sum() <= count * 64
    expected = truth(order)
    transfer = result.transfer.reshape(count, 3, -1)
    spread = transfer.std(0) / np.sqrt(count)
    assert np.all(np.abs(transfer.mean(0) - expected) <= 4 * spread + 2e-4), (transfer.mean(0) - expected, spread)
    z = np.linalg.norm(transfer - expected, axis=2) / np.maximum(result.std_error.reshape(count, 3), 1e-12)
    if as_polygon:  # the roof is explained exactly: no noise left to be honest about
        assert result.std_error.max() < 1e-5
    else:
        assert 0.7 <= np.sqrt(np.mean(z ** 2)) <= 1.4
        # Teeth: the tilted points' transfer differs from the vertex normal's by far more than the tolerance.
        assert np.abs(expected[1] - expected[0]).max() > 20 * spread.max()


def test_shared_rays_cost_about_one_point_for_the_accuracy_of_each():
    """At equal rays per point, sharing three points' rays gives each nearly the error of a point alone while
    casting a third of the rays."""
    count = 200
    alone = shared_vertices(count)
    alone.ray_groups = None
    own, shared = (bake_points(r, roof_occluders(), order=4, samples=128) for r in (alone, shared_vertices(count)))
    assert shared.rays.sum() * 3 <= own.rays.sum()
    ratio = np.sqrt(np.mean(shared.rel_error ** 2) / np.mean(own.rel_error ** 2))
    assert ratio < 1.35, ratio


def test_rays_below_every_points_horizon_are_not_cast_and_change_nothing(monkeypatch):
    """A shared group's cap reaches below its points' horizons; a ray below all of them weighs nothing in any
    estimate, so it is not cast. The bake is bit for bit the one that casts every ray, every ray cast lies above
    some point's horizon, and the rays reported are those cast."""
    count = 50
    skipping = bake_points(shared_vertices(count), roof_occluders(), order=3, samples=64)
    cast, left = [], []
    original = ReferenceEngine.occluded

    def casting_every_ray(self, origins, directions, live=None):
        if live is not None:
            cast.append(directions[live])
            left.append(directions[~live])
        return original(self, origins, directions)

    monkeypatch.setattr(ReferenceEngine, "occluded", casting_every_ray)
    every = bake_points(shared_vertices(count), roof_occluders(), order=3, samples=64)
    np.testing.assert_array_equal(skipping.transfer, every.transfer)
    np.testing.assert_array_equal(skipping.std_error, every.std_error)
    cast, left = np.concatenate(cast), np.concatenate(left)
    assert len(left) > 0.01 * count * 64  # teeth: the cap does reach below every horizon
    assert (left @ NORMALS.T).max() <= 1e-6 and (cast @ NORMALS.T).max(axis=1).min() > -1e-6
    assert skipping.rays.sum() == len(cast) == count * 64 - len(left)


def test_a_shared_group_hands_each_point_its_hits_with_unbiased_weights():
    """Interreflections gather over the hit records: inside a closed box every ray hits a front face, so each
    point's weights sum to an estimate of its cosine-weighted hemisphere, 1, exactly 1 for a point alone."""
    half = 1.0
    corners_ = np.array([[x, y, z] for x in (-half, half) for y in (-half, half) for z in (-half, half)])
    faces = [[0, 1, 3, 2], [4, 6, 7, 5], [0, 4, 5, 1], [2, 3, 7, 6], [0, 2, 6, 4], [1, 5, 7, 3]]
    triangles = np.array([t for f in faces for t in ([f[0], f[1], f[2]], [f[0], f[2], f[3]])])
    a, b, c = (corners_[triangles[:, i]] for i in range(3))
    outward = np.einsum("ij,ij->i", np.cross(b - a, c - a), a + b + c) > 0
    triangles[outward] = triangles[outward][:, ::-1]  # every face faces into the box
    count = 50
    positions = np.tile([0.1, -0.2, -0.5], (3 * count, 1))
    receiver = bake.Receiver("inside", positions, np.tile(NORMALS, (count, 1)), 3, None,
                             np.repeat(np.arange(count), 3))
    vertices = np.vstack([positions, corners_])  # the solved rows first, as interreflection needs
    occluders = bake.Occluders(vertices, triangles + len(positions), corners_.copy(), solved_vertices=len(positions),
                               engine=ENGINE)
    the_job = job.TransferJob([receiver], occluders, bake.BakeSettings(mode="interreflected", order=2, samples=64,
                                                                        bounces=0), albedo=[np.zeros((len(positions), 1))])
    the_job.run()
    records = interreflect.HitRecords.concatenate(the_job.records)
    sums = np.bincount(records.vertex, weights=records.weight, minlength=len(positions))
    assert abs(sums.mean() - 1.0) < 0.01 and sums.std() < 0.1 and sums.std() > 1e-6
    assert np.all(records.weight > 0)


def test_a_chunk_whose_points_all_need_no_rays_bakes_exactly_without_any():
    """Split points that all see the whole sky (nothing above them) form no ray group at all."""
    receiver = shared_vertices(4)
    result = bake_points(receiver, bake.Occluders(ROOF - [0, 0, 3.0], np.array([[0, 1, 2], [0, 2, 3]]),
                                                  ROOF - [0, 0, 3.0], engine=ENGINE), order=3, samples=64)
    assert result.rays.sum() == 0 and result.skipped.all()
    np.testing.assert_allclose(result.transfer, np.tile(lobes.unshadowed_transfer(3, NORMALS), (4, 1)), atol=1e-7)



def test_chunks_take_whole_groups_and_twice_as_many_shared_ones():
    """Single rows chunk CHUNK_VERTICES at a time, shared groups SHARED_CHUNK_FACTOR times as many; every row is in
    exactly one chunk, and a group's rows in one chunk."""
    single, shared = 300, 700
    labels = np.r_[np.arange(single), single + np.repeat(np.arange(shared), 3)]
    receiver = bake.Receiver("mixed", np.zeros((len(labels), 3)), np.tile([0.0, 0.0, 1.0], (len(labels), 1)), 5,
                             None, labels)
    chunks = scheduling.chunk_rows([receiver])
    groups_per_chunk = [len(np.unique(labels[rows])) for _, rows in chunks]
    per_chunk = scheduling.CHUNK_VERTICES
    # 300 single rows: chunks of 128, 128, then 44 rows sharing a chunk with shared groups worth 84 more singles
    left = per_chunk - single % per_chunk
    first_shared = scheduling.SHARED_CHUNK_FACTOR * left
    whole = per_chunk * scheduling.SHARED_CHUNK_FACTOR
    expected = [per_chunk, per_chunk, single % per_chunk + first_shared]
    expected += [whole] * ((shared - first_shared) // whole) + [(shared - first_shared) % whole]
    assert groups_per_chunk == expected
    rows = np.concatenate([rows for _, rows in chunks])
    assert np.array_equal(np.sort(rows), np.arange(len(labels)))
    assert all(len(np.intersect1d(labels[a], labels[b])) == 0
               for (_, a), (_, b) in zip(chunks, chunks[1:]))  # no group spans two chunks


def v_groove(rise, vertices_along=41, wing=3.0, spacing=0.1):
    """A flat-shaded V groove along y: its wings rise `rise` from the crease on either side. Returns the occluders,
    the crease's vertices and the wings' normals."""
    y = spacing * (np.arange(vertices_along) - vertices_along // 2)
    crease = np.column_stack([np.zeros_like(y), y, np.zeros_like(y)])
    left, right = (crease + [side * wing, 0.0, wing * np.tan(rise)] for side in (-1.0, 1.0))
    vertices = np.vstack([crease, left, right])
    strips = [([j, outer, outer + 1], [j, outer + 1, j + 1]) for j in range(vertices_along - 1)
              for outer in (vertices_along + j, 2 * vertices_along + j)]
    triangles = np.array([triangle for strip in strips for triangle in strip])
    left_wing = triangles.max(1) < 2 * vertices_along
    triangles[left_wing] = triangles[left_wing][:, ::-1]  # both wings face up
    occluders = bake.Occluders(vertices, triangles, vertices.copy(), engine=ENGINE)
    return occluders, crease, np.array([[np.sin(rise), 0.0, np.cos(rise)], [-np.sin(rise), 0.0, np.cos(rise)]])


def wedge_transfer(order, normal, rise, side, nodes=64):
    """What the other wing of an endless groove blocks for a point just above its crease: every direction towards
    `side` (+1: +x) below that wing's plane and above the point's own, a lune about the crease from elevation −rise
    to +rise. Gauss-Legendre in the lune's angle and latitude, with scipy's SH."""
    t, wt = np.polynomial.legendre.leggauss(nodes)
    angle, latitude = np.meshgrid(rise * t, 0.5 * np.pi * t, indexing="ij")
    weights = np.outer(rise * wt, 0.5 * np.pi * wt) * np.cos(latitude)
    directions = np.stack([side * np.cos(latitude) * np.cos(angle), np.sin(latitude),
                           np.cos(latitude) * np.sin(angle)], axis=-1).reshape(-1, 3)
    return (weights.ravel() * (directions @ normal)) @ reference_sh(order, directions) / np.pi


@pytest.mark.parametrize("rise", [30.0, 50.0])
def test_a_v_grooves_crease_points_see_the_other_wing_as_quadrature_does(rise):
    """The crease of a flat-shaded V groove: each of its vertices' two points (one per wing) shares one ray group,
    and all that blocks their light is the other wing, whose faces meet at the vertex: for rays starting just
    above the crease, a lune of directions about it. Every point's transfer matches quadrature over that lune
    within its estimated error. At 50° the wings face each other (100° between their normals): each point touches
    the other wing at an angle, and the group's one origin is lifted in front of both wings."""
    rise, order = np.radians(rise), 3
    occluders, crease, normals = v_groove(rise)
    inner = crease[5:-5]  # away from the groove's ends
    count = len(inner)
    into_wings = np.tile([[-np.cos(rise), 0.0, np.sin(rise)], [np.cos(rise), 0.0, np.sin(rise)]], (count, 1))
    receiver = bake.Receiver("groove", np.repeat(inner, 2, axis=0), np.tile(normals, (count, 1)), 11, into_wings,
                             np.repeat(np.arange(count) * 2, 2), into_wings)
    result = bake_points(receiver, occluders, order=order, samples=64)
    assert 0 < result.rays.sum() <= count * 64  # a group casts at most what one point would
    expected = np.tile([lobes.unshadowed_transfer(order, normal[None])[0] - wedge_transfer(order, normal, rise, side)
                        for normal, side in zip(normals, (1.0, -1.0))], (count, 1))
    assert np.abs(expected - lobes.unshadowed_transfer(order, receiver.normals)).max() > 0.05  # teeth: a real shadow
    z = np.linalg.norm(result.transfer - expected, axis=1) / np.maximum(result.std_error, 1e-12)
    assert 0.6 <= np.sqrt(np.mean(z ** 2)) <= 1.5, z
    spread = result.std_error.mean() / np.sqrt(len(z))
    assert np.linalg.norm((result.transfer - expected).mean(0)) <= 4 * spread + 1e-4


def crossing(origins, directions, corners_):
    """(g, n, F) bool: does the ray from each origin (g, 3) along each of its directions (g, n, 3) cross each of its
    triangles (corners (g, F, 3, 3)) ahead of the origin: Möller-Trumbore in float64, written out here."""
    p0, e1, e2 = corners_[:, :, 0], corners_[:, :, 1] - corners_[:, :, 0], corners_[:, :, 2] - corners_[:, :, 0]
    d = directions[:, :, None]  # (g, n, 1, 3)
    pvec = np.cross(d, e2[:, None])
    det = np.einsum("gfd,gnfd->gnf", e1, pvec)
    s = (origins[:, None] - p0)[:, None]  # (g, 1, F, 3)
    u = np.einsum("gxfd,gnfd->gnf", s, pvec) / det
    q = np.cross(s, e1[:, None])
    v = np.einsum("gnxd,gnfd->gnf", d, q) / det
    t = np.einsum("gfd,gnfd->gnf", e2, np.broadcast_to(q, pvec.shape)) / det
    return (u >= 0) & (v >= 0) & (u + v <= 1) & (t > 0)


def test_ring_planes_mark_only_rays_that_cross_their_triangle():
    """rings.ring_planes with surely_hit, against a plain line-triangle intersection: from origins just off a
    vertex where six folded triangles meet (some facing the origin, some turned away from it), every ray marked
    crosses its triangle ahead of the origin, and every ray that crosses one clear of its edges' planes and its own
    plane by twice the margin is marked."""
    rng = np.random.default_rng(7)
    angles = np.linspace(0.0, 2 * np.pi, 7)[:-1] + rng.uniform(-0.2, 0.2, 6)
    rim = np.column_stack([np.cos(angles), np.sin(angles), rng.uniform(-0.6, 0.6, 6)])
    vertices = np.vstack([np.zeros(3), rim])
    triangles = np.array([[0, 1 + i, 1 + (i + 1) % 6] for i in range(6)])
    caster = bake.Occluders(vertices, triangles, vertices.copy(), engine=ENGINE).ray_caster()
    groups, rays = 40, 3000
    origins = rng.normal(size=(groups, 3)) * [0.02, 0.02, 0.01] + [0.0, 0.0, 0.02]
    origins -= caster.center  # the caster's frame
    directions = rng.normal(size=(groups, rays, 3))
    directions /= np.linalg.norm(directions, axis=2, keepdims=True)
    ring = np.tile(np.arange(6), (groups, 1))
    planes = rings.ring_planes(caster, origins, ring)
    marked = rings.surely_hit(planes, np.ascontiguousarray(directions.transpose(0, 2, 1)).astype(np.float32))
    corners_ = caster.vertices[caster.triangles[ring]]
    crosses = crossing(origins, directions, corners_)
    # clear: the ray's sines to the planes through the origin and each edge, and to the triangle's plane
    to_corners = corners_ - origins[:, None, None]
    edge_normals = np.cross(to_corners, np.roll(to_corners, -1, axis=2))
    edge_normals /= np.linalg.norm(edge_normals, axis=3, keepdims=True)
    face_normals = np.cross(corners_[:, :, 1] - corners_[:, :, 0], corners_[:, :, 2] - corners_[:, :, 0])
    face_normals /= np.linalg.norm(face_normals, axis=2, keepdims=True)
    sines = np.abs(np.concatenate([np.einsum("gnd,gfed->gnfe", directions, edge_normals),
                                   np.einsum("gnd,gfd->gnf", directions, face_normals)[..., None]], axis=3))
    clear = (sines > 2 * rings.RING_MARGIN).all(axis=3)
    assert (marked <= crosses.any(axis=2)).all()
    assert ((crosses & clear).any(axis=2) <= marked).all()
    assert 0.02 < marked.mean() < 0.98  # teeth: rays both ways
    heights = np.einsum("gfd,gfd->gf", face_normals, origins[:, None] - corners_[:, :, 0])
    assert (heights > 0).any() and (heights < 0).any()  # the origins see triangles from both sides


def test_rays_known_to_hit_the_vertexs_own_faces_are_not_cast_and_change_nothing(monkeypatch):
    """A V groove's crease points see the other wing, whose faces meet at their vertex: the rays that surely cross
    them count as blocked without a cast. The bake is bit for bit the one that casts them, with fewer rays."""
    occluders, crease, normals = v_groove(np.radians(40.0))
    inner = crease[5:-5]
    count = len(inner)

    def groove_points():
        return bake.Receiver("groove", np.repeat(inner, 2, axis=0), np.tile(normals, (count, 1)), 11, None,
                             np.repeat(np.arange(count) * 2, 2))

    known = bake_points(groove_points(), occluders, order=3, samples=64)
    monkeypatch.setattr(rings, "group_ring_planes", lambda shared, heads: None)
    cast = bake_points(groove_points(), bake.Occluders(occluders.vertices, occluders.triangles, occluders.hull,
                                                      engine=ENGINE), order=3, samples=64)
    np.testing.assert_array_equal(known.transfer, cast.transfer)
    np.testing.assert_array_equal(known.std_error, cast.std_error)
    assert known.rays.sum() < 0.9 * cast.rays.sum()  # teeth: the other wing takes a good share of the rays
