"""Where Blender itself writes an output, under core.outputs' rules: the .blend file, and images (renders, heat
maps, texel maps) in the format their suffix names; and the files an open .blend reads, which no output may
replace."""

from contextlib import contextmanager
import os

import bpy

from ..core.errors import InputError
from ..core.outputs import blend_is_whole, image_is_whole, replacing, same_file

IMAGE_FORMATS = {".png": "PNG", ".jpg": "JPEG", ".jpeg": "JPEG"}  # suffix → Blender's file format


def image_format(path: str) -> str:
    """Blender's file format for an image path's suffix (checked before any work: core.outputs.check_suffix)."""
    return IMAGE_FORMATS[os.path.splitext(path)[1].lower()]


def used_files() -> list[str]:
    """Every file the open .blend reads (images, libraries, sounds, fonts, caches...), absolute; packed ones are in
    the .blend itself."""
    return bpy.utils.blend_paths(absolute=True, packed=False)


def save_blend(path: str):
    """Saves the session's data at `path`, creating its folder. Blender writes `path@` and renames it over `path`
    (the previous file becoming `path1` where Save Versions asks for it); a failure it reports, such as a full disk
    on Blender 5.3, leaves the previous file as it was. A file it cut short without a word (Blender 5.2 on a full
    disk) is found by its end (core.outputs.blend_is_whole) and taken back: the previous `path` and `path1` are
    kept aside as hard links, which need no space, and put back. Elsewhere than the open file it saves a copy, its
    relative paths remapped to its folder, and the session keeps the file it has open."""
    path = os.path.abspath(path)
    os.makedirs(os.path.dirname(path), exist_ok=True)
    copy = not (bpy.data.filepath and same_file(path, bpy.data.filepath))
    aside = {name: _linked_aside(name) for name in (path, path + "1")}
    try:
        try:
            bpy.ops.wm.save_as_mainfile(filepath=path, copy=copy)
        except RuntimeError as failure:
            raise InputError(f"cannot save {path}: {_first_line(failure)}; any previous file there is as it "
                             f"was") from None
        if not blend_is_whole(path):
            for name, kept in aside.items():
                if kept is not None:
                    os.replace(kept, name)
                elif os.path.exists(name):
                    os.remove(name)
            raise InputError(f"cannot save {path}: the file was cut short (is the disk full?); any previous file "
                             f"there is as it was")
    finally:
        for kept in aside.values():
            if kept is not None and os.path.exists(kept):
                os.remove(kept)


def _linked_aside(path: str) -> str | None:
    """A hard link to the file at `path` beside it, or None where there is no file (or the folder's file system
    has no hard links)."""
    kept = f"{path}.{os.getpid()}.kept"
    try:
        os.link(path, kept)
    except OSError:
        return None
    return kept


@contextmanager
def writing_image(path: str):
    """core.outputs.replacing for an image Blender writes: one it cut short (a full disk, which its PNG writer does
    not report) is refused, naming `path`, and the previous file stays."""
    with replacing(path) as temporary:
        try:
            yield temporary
        except RuntimeError as failure:  # Blender's report, on lines of its own
            raise InputError(f"cannot write {path}: {_first_line(failure)}; any previous file there is as it "
                             f"was") from None
        if not image_is_whole(temporary):
            raise InputError(f"cannot write {path}: the image was cut short (is the disk full?); any previous file "
                             f"there is as it was")


def _first_line(failure: Exception) -> str:
    return str(failure).strip().splitlines()[0].removeprefix("Error: ")


def save_image(image, path: str):
    """Writes `image` at `path` in its own file format, whole or not at all."""
    with writing_image(path) as temporary:
        image.save(filepath=temporary)
