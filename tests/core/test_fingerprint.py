"""The fingerprint's digests: the same for the same values however they are held, different when a value changes
by more than float32 rounding."""

import numpy as np

from prt_addon.core import fingerprint
from prt_addon.core.bake import CONVENTION_VERSION, BakeSettings

POSITIONS = np.arange(12, dtype=np.float64).reshape(4, 3) * 0.37 - 1.0
TRIANGLES = np.array([[0, 1, 2], [0, 2, 3]], dtype=np.int32)


def test_digest_is_pinned_so_it_is_the_same_on_every_run_and_machine():
    # blake2b-128 of b"f(4, 3)", the float32 little-endian bytes, b"i(2, 3)", the int64 bytes (computed by hand
    # once): a process-seeded hash or a platform's byte order would not reproduce it.
    assert fingerprint.array_digest(POSITIONS, TRIANGLES) == "2791bfb67091282bb05f63d095a5d5b8"


def test_digest_does_not_depend_on_how_the_arrays_are_held():
    expected = fingerprint.array_digest(POSITIONS, TRIANGLES)
    transposed_copy = np.asfortranarray(POSITIONS.copy())
    assert fingerprint.array_digest(transposed_copy, TRIANGLES.astype(np.int64)) == expected
    assert fingerprint.array_digest(POSITIONS.astype(np.float32), TRIANGLES.tolist()) == expected
    strided = np.zeros((4, 6))[:, ::2]
    strided[:] = POSITIONS
    assert fingerprint.array_digest(strided, TRIANGLES) == expected
    assert fingerprint.array_digest(POSITIONS * -0.0 + 0.0, TRIANGLES) == \
        fingerprint.array_digest(POSITIONS * -0.0, TRIANGLES)  # −0.0 is 0.0


def test_one_float_changed_beyond_float32_rounding_changes_the_digest_and_below_it_does_not():
    expected = fingerprint.array_digest(POSITIONS, TRIANGLES)
    value = np.float32(POSITIONS[2, 1])
    moved, nudged = POSITIONS.copy(), POSITIONS.copy()
    moved[2, 1] = np.nextafter(value, np.float32(np.inf))      # one float32 step
    nudged[2, 1] = float(value) + 0.25 * float(np.spacing(value))  # rounds back to the same float32
    assert fingerprint.array_digest(moved, TRIANGLES) != expected
    assert fingerprint.array_digest(nudged, TRIANGLES) == expected


def test_shape_and_kind_are_part_of_the_digest():
    assert fingerprint.array_digest(POSITIONS) != fingerprint.array_digest(POSITIONS.reshape(3, 4))
    assert fingerprint.array_digest(POSITIONS, TRIANGLES) != fingerprint.array_digest(POSITIONS, TRIANGLES.ravel())
    assert fingerprint.array_digest(np.array([1.0])) != fingerprint.array_digest(np.array([1]))


def test_values_digest_ignores_dict_order_and_set_digest_ignores_order_but_counts_duplicates():
    assert fingerprint.values_digest({"order": 4, "mode": "shadowed"}) == \
        fingerprint.values_digest({"mode": "shadowed", "order": 4})
    assert fingerprint.values_digest({"order": 4}) != fingerprint.values_digest({"order": 5})
    a, b = fingerprint.array_digest([1.0]), fingerprint.array_digest([2.0])
    assert fingerprint.set_digest([a, b]) == fingerprint.set_digest([b, a])
    assert fingerprint.set_digest([a, b]) != fingerprint.set_digest([a, a, b])
    assert fingerprint.set_digest([a]) != fingerprint.set_digest([b])


def test_settings_values_keep_what_the_mode_reads():
    shadowed = fingerprint.settings_values(BakeSettings(mode="shadowed", samples=64))
    assert shadowed["samples"] == 64 and shadowed["convention"] == CONVENTION_VERSION
    assert "bounces" not in shadowed and "max_samples" not in shadowed  # no target error: no budget
    assert "max_samples" in fingerprint.settings_values(BakeSettings(target_error=0.01))
    unshadowed = fingerprint.settings_values(BakeSettings(mode="unshadowed", samples=64))
    assert unshadowed == fingerprint.settings_values(BakeSettings(mode="unshadowed", samples=1024, seed=3))
    auto = fingerprint.settings_values(BakeSettings(mode="interreflected", bounces=None, bounce_tolerance=1e-4))
    fixed = fingerprint.settings_values(BakeSettings(mode="interreflected", bounces=2, bounce_tolerance=1e-4))
    assert auto["bounces"] is None and auto["bounce_tolerance"] == 1e-4 and "bounce_tolerance" not in fixed


def test_changes_are_told_in_words_in_the_order_of_the_parts():
    current = {part: f"{part}-now" for part in fingerprint.PARTS}
    assert fingerprint.changes(dict(current), current) == []
    stored = dict(current, settings="old", transform="old", occluders="old")
    assert fingerprint.changes(stored, current) == ["moved", "occluders changed", "settings changed"]
    assert fingerprint.changes({}, current) == list(fingerprint.CHANGES.values())  # a part not stored changed
