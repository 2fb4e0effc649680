"""Writes the manual's reference pages from the add-on's code, so that they cannot drift from it:

    .venv/bin/python docs/gen_reference.py           # writes them
    .venv/bin/python docs/gen_reference.py --check   # exit 1, naming each page that differs from the code

docs/reference/settings.md (the saved settings), commands.md (every command's options), stored-layout.md (what a
bake stores in the .blend file) and gltf-extras.md with gltf-extras.schema.json (what the glTF export adds).
tests/test_docs.py runs the check. One module per page in docs/gen/."""

import argparse
from pathlib import Path
import sys

ROOT = Path(__file__).resolve().parents[1]
sys.path[:0] = [str(ROOT), str(ROOT / "docs")]  # this checkout's add-on, and docs/gen

import bpy  # noqa: E402,F401  (before mathutils, which the add-on's core uses)

from gen import commands_page, gltf_page, gltf_schema, layout_page, settings_page  # noqa: E402
from prt_addon.core.outputs import replacing  # noqa: E402

REFERENCE = ROOT / "docs" / "reference"


def pages() -> dict[Path, str]:
    """{path: the text the code gives it}."""
    return {REFERENCE / "settings.md": settings_page.text(),
            REFERENCE / "commands.md": commands_page.text(),
            REFERENCE / "stored-layout.md": layout_page.text(),
            REFERENCE / "gltf-extras.md": gltf_page.text(),
            REFERENCE / gltf_schema.FILE_NAME: gltf_schema.text()}


def stale(written: dict[Path, str]) -> list[Path]:
    """The pages whose file is missing or says something else."""
    return [path for path, text in written.items()
            if not path.is_file() or path.read_text(encoding="utf-8") != text]


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(description="Write the manual's reference pages from the add-on's code.")
    parser.add_argument("--check", action="store_true",
                        help="write nothing; exit 1 naming each page that differs from what the code gives")
    args = parser.parse_args(argv)
    written = pages()
    outdated = stale(written)
    if args.check:
        for path in outdated:
            print(f"gen_reference: {path.relative_to(ROOT)} is stale: run .venv/bin/python docs/gen_reference.py",
                  file=sys.stderr)
        return 1 if outdated else 0
    for path in outdated:
        with replacing(str(path)) as temporary:  # whole or not at all, as every file the add-on writes
            Path(temporary).write_text(written[path], encoding="utf-8")
        print(f"gen_reference: wrote {path.relative_to(ROOT)}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
