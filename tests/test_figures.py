"""The manual's figures: docs/make_figures.py in its quick mode, in a fresh process, must write each PNG the README
shows, and each picture must show what its caption says, by the numbers the script measures on the two renders
(PRT's display against Cycles under the same band-limited light, the reference engine)."""

import re
import subprocess
import sys

from matplotlib.image import imread
import pytest

from conftest import ROOT

# The manual's pictures are made on one Blender, the newest: once per CI run, as the studies.
pytestmark = pytest.mark.study

NUMBER = r"([-+]?\d+(?:\.\d+)?)"
SHADOW_RATIO = 0.8  # (a): Cycles' floor at the shadow ≤ this × PRT's there; seen 0.55 (quick) to 0.6
# (b): the spheres 0.25 m from the edge, blended with a probe across it, differ from Cycles 10-13 % (quick); those
# 0.75 m or more away, between probes on their own side, within 3 %: the near ones must differ over twice as much.
NEAR, MARGIN = 0.25, 2.0


@pytest.fixture(scope="module")
def made(tmp_path_factory):
    folder = tmp_path_factory.mktemp("figures")
    done = subprocess.run([sys.executable, str(ROOT / "docs" / "make_figures.py"), "--quick", "--out", str(folder)],
                          cwd=ROOT, capture_output=True, text=True, timeout=900)
    assert done.returncode == 0, f"{done.stdout[-4000:]}\n{done.stderr[-4000:]}"
    return folder, done.stdout


def test_the_figure_is_written(made):
    folder, _ = made
    picture = imread(folder / "dynamic_limits.png")
    height, width = picture.shape[:2]
    assert width >= 480 and height >= 400, picture.shape  # two panels side by side, two renders and a plot each
    assert picture[..., :3].std() > 0.1  # not blank


def test_a_dynamic_object_casts_no_shadow_in_prt_but_does_in_cycles(made):
    _, printed = made
    ratio = float(re.search(rf"^\(a\) floor at the dynamic sphere's shadow: Cycles ÷ PRT {NUMBER}", printed,
                            re.MULTILINE).group(1))
    assert 0.0 < ratio <= SHADOW_RATIO, printed


def test_the_spheres_next_to_the_edge_get_light_blended_across_it(made):
    _, printed = made
    rows = [tuple(map(float, found)) for found in re.findall(
        rf"^\(b\) sphere at y {NUMBER} m, .*?: PRT {NUMBER}, Cycles {NUMBER}, differs by {NUMBER} %", printed,
        re.MULTILINE)]
    assert len(rows) == 6, printed
    near = [row for row in rows if abs(row[0]) == NEAR]
    far = [row for row in rows if abs(row[0]) > NEAR]
    assert len(near) == 2 and len(far) == 4
    assert min(row[3] for row in near) > MARGIN * max(row[3] for row in far), printed
    (lit, shaded) = sorted(near)  # y < 0 is in the open, y > 0 in the wall's shadow
    assert lit[1] < lit[2] and shaded[1] > shaded[2], printed  # PRT darker on the lit side, brighter in shadow
