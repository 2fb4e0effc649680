"""Property-based checks (hypothesis) of what must hold for every input, not just the examples we thought of."""

import numpy as np
from hypothesis import given, settings, strategies as st

from prt_addon.core import bake, job, lights, lobes, rotation, sh, shading
from test_bake_core import disc

unit_vectors = st.tuples(*[st.floats(-1.0, 1.0, allow_nan=False)] * 3).filter(
    lambda v: np.linalg.norm(v) > 1e-3).map(lambda v: np.array(v) / np.linalg.norm(v))
quaternions = st.tuples(*[st.floats(-1.0, 1.0, allow_nan=False)] * 4).filter(lambda q: np.linalg.norm(q) > 1e-3)


@settings(max_examples=80, deadline=None)
@given(unit_vectors, st.integers(1, 30))
def test_addition_theorem_holds_in_every_direction(direction, order):
    """Σ_m Y_lm(d)² = (2l+1)/4π for every band, wherever d points (poles included)."""
    values = sh.evaluate(order, direction)
    bands = sh.coefficient_bands(order)
    per_band = np.bincount(bands, values ** 2, minlength=order)
    np.testing.assert_allclose(per_band, (2 * np.arange(order) + 1) / (4 * np.pi), rtol=1e-11)


@settings(max_examples=60, deadline=None)
@given(unit_vectors, quaternions)
def test_rotating_the_unshadowed_transfer_is_the_transfer_of_the_rotated_normal(normal, q):
    matrix = rotation.quaternion_to_matrix(q)
    turned = rotation.rotate(lobes.cosine_transfer(6, normal[None])[0], matrix)
    np.testing.assert_allclose(turned, lobes.cosine_transfer(6, (matrix @ normal)[None])[0], atol=1e-12)


@settings(max_examples=20, deadline=None)
@given(st.floats(-4.0, 4.0), st.tuples(*[st.floats(-1e5, 1e5)] * 3))
def test_a_scaled_and_moved_scene_bakes_the_same(log_scale, offset):
    """Scale 1e-4..1e4 and offsets up to 1e5 change nothing beyond float rounding."""
    scale, offset = 10.0 ** log_scale, np.array(offset)
    occluders = disc(1.0, 1.0, segments=64)
    probe = bake.Receiver("p", np.array([[0.3, -0.2, 0.0], [0.9, 0.7, 0.0]]), np.array([[0, 0, 1.0]] * 2), 3)
    settings_ = bake.BakeSettings(order=3, samples=64)
    (reference,) = job.TransferJob([probe], occluders, settings_).run()
    moved_occluders = bake.Occluders(occluders.vertices * scale + offset, occluders.triangles,
                                     occluders.hull * scale + offset, engine=occluders.engine)
    moved_probe = bake.Receiver("p", probe.positions * scale + offset, probe.normals, 3)
    (moved,) = job.TransferJob([moved_probe], moved_occluders, settings_).run()
    np.testing.assert_allclose(moved.transfer, reference.transfer, atol=1e-6)


@settings(max_examples=60, deadline=None)
@given(st.floats(1e-6, 1e6), st.floats(1e-6, 1e6), unit_vectors, st.floats(0.0, np.pi / 2))
def test_shading_is_linear_in_the_lights(a, b, direction, radius):
    """Σ_k L_k T_k: any two lights shade as the sum of their shadings, at any strengths."""
    normals = np.array([[0.0, 0.0, 1.0], [0.6, 0.0, 0.8], [0.0, -1.0, 0.0]])
    transfer = lobes.cosine_transfer(4, normals)
    first = lights.LightCache().totals([lights.Sun(tuple(direction), radius, (a, a, a))], {4})[4]
    second = lights.LightCache().totals([lights.Sky((b, b, b))], {4})[4]
    both = lights.LightCache().totals([lights.Sun(tuple(direction), radius, (a, a, a)), lights.Sky((b, b, b))],
                                      {4})[4]
    np.testing.assert_allclose(shading.shade(transfer, both).astype(np.float64),
                               shading.shade(transfer, first) + shading.shade(transfer, second).astype(np.float64),
                               rtol=1e-5, atol=1e-6 * (a + b))
