"""Every benchmark's smoke run: each script in benchmarks/ runs in a fresh process in its quick mode, on a tiny scene,
and must end with exit 0 and print its goal and figure lines, with real numbers in them and each PASS or MISS
agreeing with the number beside it. The goals themselves are for the full runs (a smoke run's figures mean
nothing): what fails here is a benchmark that no longer runs against the engine and pipeline it measures."""

import json
import math
from pathlib import Path
import re
import shutil
import subprocess
import sys

import numpy as np
import pytest

from conftest import ROOT

NUMBER = r"[-+]?\d[\d,]*(?:\.\d+)?(?:[eE][-+]?\d+)?"
# the scripts, not the modules some of them import (benchmarks/engine_answers.py, engine_bakes.py, engine_curves.py)
# nor benchmarks/results.py, which writes and tabulates their results (tests/test_benchmark_results.py)
ALL_SCRIPTS = {path.stem for path in (ROOT / "benchmarks").glob("*.py") if "__main__" in path.read_text()} - {"results"}


def run_benchmark(script: str, *arguments, timeout=600) -> str:
    """`python benchmarks/SCRIPT.py ARGUMENTS` from the repository root; its standard output, once it exits 0."""
    done = subprocess.run([sys.executable, str(ROOT / "benchmarks" / f"{script}.py"), *map(str, arguments)],
                          cwd=ROOT, capture_output=True, text=True, timeout=timeout)
    assert done.returncode == 0, f"{script}.py exited {done.returncode}:\n{done.stdout[-4000:]}\n{done.stderr[-4000:]}"
    return done.stdout


def found(pattern: str, text: str) -> re.Match:
    """The first line matching `pattern` (with {n} standing for a number), which must be there."""
    match = re.search(pattern.replace("{n}", f"({NUMBER})"), text, re.MULTILINE)
    assert match, f"no line matching {pattern!r} in:\n{text}"
    return match


def number(text: str, positive=True) -> float:
    """A printed figure, which must be finite (and positive)."""
    value = float(text.replace(",", ""))
    assert math.isfinite(value) and (value > 0 or not positive and value >= 0), text
    return value


def judged(value: float, relation: str, goal: float, verdict: str):
    """The printed verdict is the one the printed figure and goal give; a figure printed equal to its goal was rounded
    there from either side of it, so either verdict is the figure's."""
    if value == goal:
        return
    met = {"<=": value <= goal, "≤": value <= goal, ">=": value >= goal, "≥": value >= goal}[relation]
    assert verdict == ("PASS" if met else "MISS"), (value, relation, goal, verdict)


def goal_line(pattern: str, text: str, relation: str, goal: float) -> float:
    """The figure of a goal line whose pattern holds one {n} and ends with its verdict, checked against `goal`."""
    match = found(pattern + r".*?(PASS|MISS)", text)
    value = number(match.group(1))
    judged(value, relation, goal, match.group(2))
    return value


def small_obj(path: Path) -> Path:
    """A flat-shaded torus as an OBJ without normals (16 × 8 vertices): an asset that shadows itself."""
    major, minor = np.meshgrid(np.arange(16) * 2 * np.pi / 16, np.arange(8) * 2 * np.pi / 8, indexing="ij")
    ring = 1.0 + 0.4 * np.cos(minor)
    points = np.stack([ring * np.cos(major), ring * np.sin(major), 0.4 * np.sin(minor)], axis=-1).reshape(-1, 3)
    i, j = np.meshgrid(np.arange(16), np.arange(8), indexing="ij")
    quads = np.stack([i * 8 + j, (i + 1) % 16 * 8 + j, (i + 1) % 16 * 8 + (j + 1) % 8, i * 8 + (j + 1) % 8],
                     axis=-1).reshape(-1, 4) + 1
    path.parent.mkdir(parents=True, exist_ok=True)
    path.write_text("".join(f"v {x:.6f} {y:.6f} {z:.6f}\n" for x, y, z in points)
                    + "".join(f"f {a} {b} {c} {d}\n" for a, b, c, d in quads))
    return path


def test_every_benchmark_has_a_smoke_run_here():
    """A benchmark added without a smoke run fails here."""
    tested = {name[len("test_"):].split("_smoke")[0] for name in globals() if name.endswith("_smoke_run")}
    assert tested == ALL_SCRIPTS


def test_bake_smoke_run():
    out = run_benchmark("bake", "--quick")
    rows = re.findall(r"^   (.+?)\s+(True|False|" + NUMBER + r")  (>=|<=|==) (\S+)\s+(PASS|MISS)$", out, re.MULTILINE)
    assert [row[0] for row in rows] == ["ray-cast efficiency (bake ÷ bare)", "error ours ÷ seed at 256 rays",
                                        "demo bake wall time, s", "demo bake actual RMS rel. error",
                                        "time 2 workers ÷ 1 worker", "2 workers bit-identical to 1"], out
    for label, value, relation, goal, verdict in rows[:-1]:
        judged(number(value), relation, float(goal), verdict)
    assert rows[-1][1:] == ("True", "==", "True", "PASS")  # forked workers bake the same bits, even here
    rays = number(found(r"^1\. Ray-cast efficiency \(\d+ floor and torus vertices, {n} rays", out).group(1))
    assert rays > 1000


@pytest.mark.study  # two minutes of both engines' bakes, the same script on every Blender: once per CI run
def test_engines_smoke_run(tmp_path):
    out = run_benchmark("engines", "--quick", "--plot", tmp_path / "curves.png")
    for case in ("sphere flat", "cylinder"):
        match = found(rf"^   {case}\s+\d+ faces\s+{{n}} rays  occlusion\s+{{n}} %  face\s+{{n}} %", out)
        assert number(match.group(1)) > 1000 and 99.0 <= number(match.group(3)) <= number(match.group(2)) <= 100.0
    worst = goal_line(r"^   agreement on the face hit, worst case {n} %  goal >= 99\.99:", out, ">=", 99.99)
    assert worst <= 100.0
    for scene in ("demo", "dense"):
        match = found(rf"^   {scene}\s+\d+ faces\s+{{n}} rays: Embree\s+{{n}} M rays/s, BVHTree\s+{{n}} M rays/s, "
                      rf"bare ray_cast loop\s+{{n}} M rays/s; Embree ÷ bare loop\s+{{n}}×, Embree ÷ BVHTree\s+{{n}}×  "
                      rf"goal >= 15: (PASS|MISS)", out)
        rays, embree, tree, bare, to_bare, ratio = (number(group) for group in match.groups()[:6])
        assert ratio == pytest.approx(embree / tree, rel=0.01) and rays > 1000
        assert to_bare == pytest.approx(embree / bare, rel=0.01)
        judged(ratio, ">=", 15, match.group(7))
    for engine in ("embree", "bvhtree"):
        match = found(rf"^   {engine}\s+2 workers\s+{{n}} s; one process\s+{{n}} s: casting\s+{{n}} s, contact search"
                      rf"\s+{{n}} s, the rest\s+{{n}} s", out)
        total, casting, contact, rest = (number(group) for group in match.groups()[1:])
        assert casting + contact + rest == pytest.approx(total, abs=0.02)
    goal_line(r"^   BVHTree ÷ Embree wall time {n}×  goal >= 5:", out, ">=", 5)
    number(found(r"^4\. Memory over the dense scene \(\d+ faces\): BVHTree {n} MB, Embree engine {n} MB", out).group(2))
    for engine in ("Embree", "BVHTree"):  # each bake's own curve: rounds of more rays and less error
        line = found(rf"^   {engine}\s+round 1 .*$", out).group(0)
        rows = re.findall(rf"(round \d+|bounces)\s+({NUMBER}) s\s+({NUMBER}) M rays RMS ({NUMBER})", line)
        assert len(rows) >= 2 and all(float(b[2]) >= float(a[2]) and float(b[3]) <= float(a[3])
                                      for a, b in zip(rows, rows[1:])), line
    assert (tmp_path / "curves.png").read_bytes().startswith(b"\x89PNG")
    for case in ("sphere flat", "cylinder"):
        match = found(rf"^   {case}\s+{{n}} points, transfers differ at\s+(\d+): \|z\| > 3 at {{n}} % \(allowed "
                      rf"{{n}} %\), max \|z\| {{n}}  (PASS|MISS)\n\s+against Cycles \({{n}} s\): RMS Embree {{n}} %, "
                      rf"BVHTree {{n}} %, Δ {{n}} points  (PASS|MISS)", out)
        points, differ, share, allowed, worst = (number(match.group(k), positive=False) for k in range(1, 6))
        assert points > 100 and differ <= points and 0.27 < allowed < 100 and share <= 100
        assert match.group(6) == ("PASS" if share <= allowed and worst <= 6 else "MISS")
        embree, tree, move = number(match.group(8)), number(match.group(9)), float(match.group(10))
        assert embree < 100 and move == pytest.approx(tree - embree, abs=0.002)
        judged(abs(move), "<=", 0.1, match.group(11))
    match = found(r"^   largest move of the RMS against Cycles {n} points  goal <= 0\.1: (PASS|MISS)", out)
    judged(number(match.group(1), positive=False), "<=", 0.1, match.group(2))  # the engines may agree to the bit
    for engine in ("embree", "bvhtree"):
        match = found(rf"^   {engine}\s+2 workers\s+{{n}} s \(of [\d. ]+\); one process\s+{{n}} s: casting\s+{{n}} s, "
                      rf"contact search\s+{{n}} s, the rest\s+{{n}} s  \(load average", out)
        total, casting, contact, rest = (number(group, positive=False) for group in match.groups()[1:])
        assert casting + contact + rest == pytest.approx(total, abs=0.2) and total > 0
    goal_line(r"^   BVHTree ÷ Embree wall time {n}×  goal >= 3:", out, ">=", 3)


def test_estimator_study_smoke_run():
    out = run_benchmark("estimator_study", "--quick")
    seed_error = number(found(r"seed's estimator at 256 rays: RMS error {n}", out).group(1))
    for replicates in (2, 4, 8):
        match = found(rf"^\s+{replicates}\s+{{n}}\s+{{n}}\s+{{n}}$", out)
        assert number(match.group(3)) == pytest.approx(number(match.group(1)) / seed_error, abs=1e-3)
    slope = float(found(r"error ∝ rays\^{n}; ours reaches 1/10 of the seed's 256-ray error at about {n} rays",
                        out).group(1))
    assert -2.0 < slope < 0.0  # more rays, less error
    assert len(re.findall(r"n ∝ error\^[\d.]+: mean \d+ rays, actual RMS " + NUMBER, out)) == 3
    for replicates in (2, 4):
        number(found(rf"R = {replicates}: actual RMS rel\. {{n}}, estimated {{n}}, actual ÷ estimated {{n}}",
                     out).group(3))


def test_memory_smoke_run():
    out = run_benchmark("memory", "--quick")
    assert number(found(r"^vertices {n}, order 4", out).group(1)) == 100 * 100
    number(found(r"^peak memory / transfer size = {n}$", out).group(1))


def written_result(folder: Path, benchmark: str, out: str) -> dict:
    """The one result file a run with `--json folder` wrote, named by its date and benchmark, as it printed."""
    (path,) = folder.glob(f"????-??-??-{benchmark}.json")
    assert f"wrote {path}" in out
    return json.loads(path.read_text(encoding="utf-8"))


def test_relight_smoke_run(tmp_path):
    out = run_benchmark("relight", "--quick", "--texels", "--json", tmp_path)
    goal_line(r"^texels 128 × 128, order 4, median of 5 updates: light change to shaded image {n} ms", out, "<=", 33)
    goal_line(r"^per update at 10,000 vertices: {n} ms   goal <= 33 ms", out, "<=", 33)
    for vertices in ("100", "1,024", "10,000"):
        goal_line(rf"^8 lights ÷ 1 light at {vertices} vertices \(one moving\): {{n}}   goal <= 1\.1", out, "<=", 1.1)
    for order in (4, 8, 16):
        number(found(rf"^order +{order} at 10,000 vertices: {{n}} ms per update", out).group(1))
    result = written_result(tmp_path, "relight", out)  # the goals as printed, with where and how they were measured
    assert result["benchmark"] == "relight" and result["quick"] is True and result["machine"]["cores"] >= 1
    assert result["command"].startswith("benchmarks/relight.py --quick --texels --json ")
    assert len(result["commit"]) >= 12 and result["blender"][0].isdigit()
    assert [entry["name"] for entry in result["goals"]] == [
        "light change to shaded image, 128² texels", "light change to colours written, 10,000 vertices",
        "8 lights ÷ 1 light, 100 vertices", "8 lights ÷ 1 light, 1,024 vertices", "8 lights ÷ 1 light, 10,000 vertices"]
    printed = [float(value) for value in re.findall(rf"(?:shaded image|update at [\d,]+ vertices:|light at [\d,]+ "
                                                    rf"vertices \(one moving\):) ({NUMBER})", out)]
    for entry, value in zip(result["goals"], printed, strict=True):
        assert entry["figure"] == pytest.approx(value, abs=0.051) and entry["relation"] == "<="
        assert entry["verdict"] == ("PASS" if entry["figure"] <= entry["bound"] else "MISS")
    assert result["rows"]["ms_by_vertices"]["10000"]["one"] == result["goals"][1]["figure"]


@pytest.mark.study  # a minute of probe bakes and Cycles, the same script on every Blender: once per CI run
def test_probes_smoke_run():
    out = run_benchmark("probes", "--quick")
    found(r"^Suzanne \(7,958 vertices, dynamic, lit per vertex\) in the demo room", out)
    for resolution in ("2×2×1", "4×4×2"):
        row = found(rf"^ +{resolution} +{{n}} +{{n}}m +{{n}}s(( +{{n}}%){{5}}) +{{n}}%$", out)
        assert len(re.findall(NUMBER, row.group(4))) == 5
    stale = found(r"^ +baked static at open, moved \(stale\)(( +{n}%){5})$", out)
    assert all(number(value) > 0 for value in re.findall(NUMBER, stale.group(1)))
    goal_line(r"^worst placement at the finest spacing: {n} % RMS   goal <= 5 %", out, "<=", 5)
    number(found(r"^  parts \(CPU time\): the probes' product {n} ms, per-vertex shading {n} ms", out).group(2))
    goal_line(r"^per update at 482 vertices and 64 probes: {n} ms   goal <= 33 ms", out, "<=", 33)
    goal_line(r"^8 lights ÷ 1 light \(one moving\): {n}   goal <= 1\.1", out, "<=", 1.1)


def test_texels_smoke_run():
    out = run_benchmark("texels", "--quick")
    goal_line(r"^room: floor and walls at 64 × 64 .*: {n} s \(gathering and checks included\)   goal <= 60 s", out,
              "<=", 60)
    match = found(r"^room: actual RMS rel\. error of the texel maps .*: {n}; the bake estimated {n}.*"
                  r"goal <= 0\.01   (PASS|MISS)$", out)
    judged(number(match.group(1)), "<=", 0.01, match.group(3))
    number(match.group(2))
    error = goal_line(r"^image: sphere over a one-quad floor: image RMS error {n} % with Auto .*goal <= 2 %", out,
                      "<=", 2.0)
    assert error < 50  # a per cent of a lit picture


def test_lights_smoke_run():
    out = run_benchmark("lights", "--quick")
    rows = re.findall(r"^\| sunrise\.exr \| (.+?) \| (\d+) \| (" + NUMBER + r") \| (" + NUMBER + r") % \| (—|"
                      + NUMBER + r" %) \| (" + NUMBER + r") % \|$", out, re.MULTILINE)
    assert [row[0] for row in rows] == ["PRT only", "PRT only, recommended", "hybrid"], out
    for row in rows:
        number(row[2]), number(row[3]), number(row[5])
    median = goal_line(r"^median image error at the proposed defaults over 1 HDRIs: {n} % \(goal ≤ 5 %\)", out,
                       "<=", 5)
    sunrise = goal_line(r"^sunrise\.exr, hybrid: image error {n} % \(goal ≤ 8 %\)", out, "<=", 8)
    assert median == sunrise == number(rows[-1][5])  # one HDRI: its hybrid row is the proposed default


def test_farm_smoke_run():
    out = run_benchmark("farm", "--quick")
    for label in (r"\(a\) whole processes, 16 rays", r"\(c\) whole processes, 32 rays"):
        match = found(rf"^   {label}\s+{{n}} s ÷\s+{{n}} s = {{n}}", out)
        assert number(match.group(3)) == pytest.approx(number(match.group(1)) / number(match.group(2)), rel=0.02)
    goal_line(r"^   \(b\) bake commands, 16 rays\s+[\d.]+ s ÷\s+[\d.]+ s = {n}", out, "<=", 1.15)
    number(found(r"Python \+ bpy start-up alone\s+{n} s CPU per process", out).group(1))
    goal_line(r"^2\. Dask LocalCluster, 2 workers ÷ one process, wall \(0\.65 goal\), median of 1 pairs: {n}", out,
              "<=", 0.65)
    assert found(r"bit-identical: (True|False)$", out).group(1) == "True"  # Dask stores one process's bits


@pytest.mark.skipif(shutil.which("chromium") is None or not (ROOT / "viewer" / "node_modules" / "three").is_dir(),
                    reason="the viewer needs Debian's chromium and three.js in viewer/node_modules (setup.sh)")
def test_viewer_smoke_run():
    out = run_benchmark("viewer", "--quick")
    one = number(found(r"^  1 light:  {n} fps", out).group(1))
    eight = number(found(r"^  8 lights: {n} fps", out).group(1))
    ratio = goal_line(r"^  8 ÷ 1 lights: {n} \(rounds: .*\); goal ≥ 0\.9:", out, ">=", 0.9)
    assert ratio == pytest.approx(eight / one, rel=0.5)  # the median of rounds' ratios, near the medians' ratio


def test_assets_smoke_run(tmp_path):
    out = run_benchmark("assets", "--quick", "--cases", "sphere flat,cylinder", "--json", tmp_path)
    rows = {}
    for name in ("sphere flat", "cylinder"):
        match = found(rf"^{name}\s+\d+\s+\d+\s+\d+\s+{{n}}\s+{{n}}\s+\d+\s+{{n}}\s+{{n}}\s+{{n}}\s+{{n}}"
                      r"\s+(?:exact|{n})", out)
        rows[name] = [None if g is None else number(g, positive=False) for g in match.groups()]
    rms_met = all(row[2] <= 2.0 for row in rows.values())
    p99_met = all(row[3] <= 10.0 for row in rows.values())
    assert found(r"^goal RMS ≤ 2 % against Cycles, every asset: (PASS|MISS)", out).group(1) == (
        "PASS" if rms_met else "MISS")
    assert found(r"^goal p99 ≤ 10 % against Cycles, every asset: (PASS|MISS)", out).group(1) == (
        "PASS" if p99_met else "MISS")
    found(r"^goal actual ÷ estimated error within 1/1\.5\.\.1\.5, every case: (PASS|MISS)", out)
    number(found(r"^sphere flat baked with its smooth vertex normals instead, .*: RMS {n} %", out).group(1))
    goals = {entry["name"]: entry for entry in written_result(tmp_path, "assets", out)["goals"]}
    assert set(goals) == {"RMS against Cycles, worst asset", "p99 against Cycles, worst asset",
                          "actual ÷ estimated error, farthest from 1 either way"}  # no demo case in this run
    assert goals["RMS against Cycles, worst asset"]["figure"] == pytest.approx(max(row[2] for row in rows.values()),
                                                                               abs=0.006)
    assert goals["RMS against Cycles, worst asset"]["verdict"] == ("PASS" if rms_met else "MISS")


def test_dynamic_smoke_run():
    """Two rotations of the dynamic Suzanne: at rest turning the light changes nothing, so both columns agree; the
    goals judge the worst rotation; the display wrote the colours validation compared."""
    out = run_benchmark("dynamic", "--quick")
    rows = {}
    for label in ("rest", "(-1,2,0.5) 250°"):
        match = found(rf"^{re.escape(label)}" + r"\s+{n}" * 8 + "$", out)
        rows[label] = [number(group, positive=False) for group in match.groups()]
    assert rows["rest"][0] == rows["rest"][4] and rows["rest"][1] == rows["rest"][5]  # RMS, p99: turned = static
    assert rows["rest"][3] == rows["(-1,2,0.5) 250°"][3] > 0  # one bake, one estimate
    worst_rms = goal_line(r"^goal RMS ≤ 2 % against Cycles, every rotation: worst {n} %", out, "<=", 2.0)
    assert worst_rms == pytest.approx(max(row[0] for row in rows.values()), abs=0.006)
    goal_line(r"^goal p99 ≤ 10 % against Cycles, every rotation: worst {n} %", out, "<=", 10.0)
    found(r"^not turning the light: RMS {n}\.\.\.{n} % once turned", out)
    match = found(r"^display colours × albedo = validation's within {n} of the largest.*?(PASS|MISS)$", out)
    judged(number(match.group(1), positive=False), "<=", 1e-5, match.group(2))
    assert match.group(2) == "PASS"  # the same light turned the same way: float32 rounding at most


def test_messy_assets_smoke_run():
    out = run_benchmark("messy_assets", "--quick", "--cases", "boxes crossing")
    match = found(r"^boxes crossing\s+\d+\s+\d+\s+\d+\s+{n}\s+{n}\s+(\d+)\s+{n}\s+{n}\s+{n}\s+{n}\s+(?:exact|{n})", out)
    rms, p99 = (number(g, positive=False) for g in match.groups()[3:5])
    assert match.group(3) == "0"  # the boxes have no face narrower than Cycles' corner nudge: none compared apart
    assert found(r"^goal RMS ≤ 2 % against Cycles, every asset: (PASS|MISS)", out).group(1) == (
        "PASS" if rms <= 2.0 else "MISS")
    assert found(r"^goal p99 ≤ 10 % against Cycles, every asset: (PASS|MISS)", out).group(1) == (
        "PASS" if p99 <= 10.0 else "MISS")
    found(r"^Where each case differs", out)


def test_corners_smoke_run(tmp_path):
    out = run_benchmark("corners", "--quick", "--asset", small_obj(tmp_path / "torus.obj"))
    goal_line(r"^   flat ÷ smooth at equal estimated error {n} \(median pair; fastest bakes [\d.]+\)   goal <= 1\.5", out,
              "<=", 1.5)
    match = found(r"^   after ÷ before {n} \(median pair; fastest bakes [\d.]+\)   goal within 5%\s+(PASS|MISS)", out)
    judged(abs(number(match.group(1)) - 1.0), "<=", 0.05, match.group(2))
    assert "rays" in found(r"^   smooth at 256: .*", out).group(0)


def test_convergence_smoke_run(tmp_path, sample_scene_files):
    table, plot = tmp_path / "convergence.csv", tmp_path / "convergence.png"
    out = run_benchmark("convergence", sample_scene_files / "demo_torus.blend", "--quick", "--objects", "Floor",
                        "--csv", table, "--plot", plot)
    number(found(r"^reference, a bake of 256 samples: {n} s, est\. RMS rel\. error {n}", out).group(2))
    for samples in (16, 32):
        match = found(rf"^{samples} samples: {{n}} s, {{n}} rays, est\. {{n}}, actual {{n}}$", out)
        assert number(match.group(2)) >= samples * 1369 * 0.5  # rays cast over the floor's 1369 vertices
        number(match.group(3)), number(match.group(4))
    assert len(table.read_text().splitlines()) == 3 and plot.stat().st_size > 0


def test_same_bake_smoke_run(tmp_path):
    """A quick capture of the texel scene and of the farm's two shards merged (on a small stand-in for the cow);
    compared with itself it is the same bake, exit 0; a copy with one value changed, or one array left out,
    differs there, exit 1."""
    small_obj(tmp_path / "assets" / "cow.obj")
    capture = tmp_path / "capture.npz"
    out = run_benchmark("same_bake", capture, "--quick", "--scenes", "texel,farm", "--assets", tmp_path / "assets")
    with np.load(capture) as data:
        arrays = {name: data[name] for name in data.files}
    assert number(found(r"^same_bake: wrote {n} arrays to ", out).group(1)) == len(arrays)
    for name in ("texel/Floor/metadata", "texel/Ball/_prt_t00", "texel/image/_prt_Floor_t00", "farm/Cow/_prt_r00",
                 "farm/Cow/_prt_point", "farm/Floor/_prt_b05"):
        assert name in arrays, sorted(arrays)
    same = run_benchmark("same_bake", "--compare", capture, capture)
    assert f"same_bake: {len(arrays)} of {len(arrays)} arrays equal; SAME bake" in same
    changed = dict(arrays)
    changed["farm/Cow/_prt_r00"] = arrays["farm/Cow/_prt_r00"].copy()
    changed["farm/Cow/_prt_r00"][3, 1] = np.nextafter(changed["farm/Cow/_prt_r00"][3, 1], np.float32(np.inf))
    del changed["texel/Ball/_prt_t00"]
    other = tmp_path / "other.npz"
    np.savez(other, **changed)
    compared = subprocess.run([sys.executable, str(ROOT / "benchmarks" / "same_bake.py"), "--compare", str(capture),
                               str(other)], cwd=ROOT, capture_output=True, text=True, timeout=60)
    assert compared.returncode == 1, compared.stdout + compared.stderr
    lines = dict(line.split(": ", 1) for line in compared.stdout.splitlines() if not line.startswith("same_bake:"))
    assert lines.pop("farm/Cow/_prt_r00").startswith("DIFFERS: 1 of ")
    assert lines.pop("texel/Ball/_prt_t00") == f"only in {capture}"
    assert set(lines.values()) == {"equal"}
    assert f"{len(arrays) - 2} of {len(arrays)} arrays equal; 2 DIFFER" in compared.stdout



def test_mesh_faults_smoke_run():
    out = run_benchmark("mesh_faults", "--quick")
    assert number(found(r"^scene: {n} triangles in {n} parts", out).group(1)) > 5000
    found(r"^found: {n} crossing triangle pairs, 1 parts inside others", out)
    goal_line(r"^checks of [\d,]+ triangles: {n} s   goal <= 1 s", out, "<=", 1.0)
