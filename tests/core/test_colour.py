"""core.colour against IEC 61966-2-1's own figures: its encoding of middle grey and of half, the two branches meeting
at the breakpoint, and decoding undoing encoding."""

import numpy as np

from prt_addon.core.colour import linear_to_srgb, srgb_to_linear


def test_linear_to_srgb_gives_the_standards_values():
    # 0.18 (middle grey) encodes to 0.46136 (118/255), 0.5 to 0.73536 (188/255); 0 and 1 stay.
    np.testing.assert_allclose(linear_to_srgb(np.array([0.0, 0.18, 0.5, 1.0])), [0.0, 0.461356, 0.735357, 1.0],
                               atol=1e-6)
    np.testing.assert_allclose(linear_to_srgb(np.array([0.0031308])), [0.04045], atol=1e-6)  # the breakpoint


def test_srgb_to_linear_undoes_it():
    values = np.linspace(0.0, 1.0, 1001)
    np.testing.assert_allclose(srgb_to_linear(linear_to_srgb(values)), values, atol=1e-12)
