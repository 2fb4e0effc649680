"""Write the sample .blend files next to this script.

From the repo root:  .venv/bin/python sample_scenes/make_scenes.py
or inside Blender:   blender -b --python sample_scenes/make_scenes.py
"""

import sys
from pathlib import Path

import bpy

HERE = Path(__file__).resolve().parent
sys.path.insert(0, str(HERE.parent))  # so the package imports without being installed

from prt_addon import scenes  # noqa: E402

SAMPLE_SCENES = {
    "demo_torus.blend": scenes.build_demo_scene,
    "suzanne.blend": scenes.build_suzanne_scene,
}


def write_scene(filename, build):
    bpy.ops.wm.read_homefile(use_empty=True)
    scenes.clear_scene()
    build()
    path = HERE / filename
    bpy.ops.wm.save_as_mainfile(filepath=str(path), compress=True)
    print(f"wrote {path} ({path.stat().st_size / 1024:.0f} KiB)")


def main():
    for filename, build in SAMPLE_SCENES.items():
        write_scene(filename, build)


if __name__ == "__main__":
    main()
