"""Write the sample .blend files, in the file format of the Blender that runs this (setup.sh runs it, so any
supported Blender opens them; they are not committed).

From the repo root:  .venv/bin/python sample_scenes/make_scenes.py [FOLDER]
or inside Blender:   blender -b --python sample_scenes/make_scenes.py -- [FOLDER]
FOLDER defaults to this script's folder.
"""

import sys
from pathlib import Path

import bpy

HERE = Path(__file__).resolve().parent
sys.path.insert(0, str(HERE.parent))  # so the package imports without being installed

from prt_addon.blender import sample_scenes  # noqa: E402

SAMPLE_SCENES = {
    "demo_torus.blend": sample_scenes.build_demo_scene,
    "suzanne.blend": sample_scenes.build_suzanne_scene,
}


def write_scene(path: Path, build) -> Path:
    """Builds a scene into an empty file and saves it at `path`."""
    bpy.ops.wm.read_homefile(use_empty=True)
    build()
    path.parent.mkdir(parents=True, exist_ok=True)
    bpy.ops.wm.save_as_mainfile(filepath=str(path), compress=True)
    return path


def main(argv):
    folder = Path(argv[0]) if argv else HERE
    for filename, build in SAMPLE_SCENES.items():
        path = write_scene(folder / filename, build)
        print(f"wrote {path} ({path.stat().st_size / 1024:.0f} KiB) with Blender {bpy.app.version_string}")


if __name__ == "__main__":
    main(sys.argv[sys.argv.index("--") + 1:] if "--" in sys.argv else sys.argv[1:])
