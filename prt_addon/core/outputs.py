"""The rules every file a command writes follows, in one place: nothing is lost, and a file is written whole or not
at all.

- An output is never an input, nor another output of the same command: it is refused, before any work, when it is
  the same file under another name (relative or absolute, through `..` or symbolic links, a hard link, or another
  case on a file system that ignores case).
- It can be written: it is no folder, the nearest folder on its path that exists is a folder that takes new files
  (the missing folders below it are created when writing), and a file already there is not read-only (no write
  permission for anyone, which also holds for root, who may write anything).
- It is written to a temporary file beside it, then renamed over it (os.replace, atomic within a folder): a
  failure (a full disk, a crash, Ctrl+C) leaves no partial file and the previous file as it was. The new file gets
  the previous file's permissions, else the usual ones for a new file (the umask's), never a temporary file's 0600.
"""

from contextlib import contextmanager
import errno
import json
import os
import secrets
import stat
import struct
import zlib

from .errors import InputError

TEMPORARY_PREFIX = ".prt-"  # no '#': Blender reads a run of them in a path it writes as a frame number
TEMPORARY_TAG = ".partial"
PNG_SIGNATURE = b"\x89PNG\r\n\x1a\n"
JPEG_START, JPEG_END = b"\xff\xd8", b"\xff\xd9"
ZSTD_MAGIC = b"\x28\xb5\x2f\xfd"         # a compressed .blend: zstd frames,
SEEKABLE_FOOTER = b"\xb1\xea\x92\x8f"    # then the seek table, whose footer ends the file
BLEND_HEADER, BLEND_END = b"BLENDER", b"ENDB"  # an uncompressed .blend: blocks up to the ENDB block


def same_file(first: str, second: str) -> bool:
    """Whether two paths name one file: the same inode where both exist (links, a case-insensitive file system),
    else the same path once made absolute with every link resolved."""
    try:
        return os.path.samefile(first, second)
    except OSError:
        return os.path.normcase(os.path.realpath(first)) == os.path.normcase(os.path.realpath(second))


def unwritable(path: str) -> str | None:
    """Why `path` cannot be written, in one line naming it, or None when it can."""
    target = os.path.realpath(path)
    if os.path.isdir(target):
        return f"cannot write {path}: it is a folder"
    folder = os.path.dirname(target)
    while not os.path.lexists(folder):
        folder = os.path.dirname(folder)
    if not os.path.isdir(folder):
        return f"cannot write {path}: {folder} is not a folder"
    if not os.access(folder, os.W_OK | os.X_OK):
        return f"cannot write {path}: no permission to write in the folder {folder}"
    if os.path.exists(target) and (not os.stat(target).st_mode & 0o222 or not os.access(target, os.W_OK)):
        return f"cannot write {path}: the file there is read-only"
    return None


def refusals(outputs, inputs) -> list[str]:
    """Each problem of the outputs, one line each: (what, path) pairs, `what` naming the option (or the file's
    role); an output is checked against every input and every output before it, then for writability."""
    problems = []
    for index, (what, path) in enumerate(outputs):
        clash = next((f"{what} {path} would replace {role} {other}" for role, other in inputs
                      if same_file(path, other)), None)
        clash = clash or next((f"{what} {path} is the same file as {role}" for role, other in outputs[:index]
                               if same_file(path, other)), None)
        problem = clash or unwritable(path)
        if problem:
            problems.append(problem)
    return problems


def check(outputs, inputs=()):
    """Raises InputError with every problem of the outputs in one line (refusals); pairs with no path are left
    out."""
    problems = refusals([pair for pair in outputs if pair[1]], [pair for pair in inputs if pair[1]])
    if problems:
        raise InputError("; ".join(problems) + "; nothing was done")


def check_suffix(path: str, option: str, suffixes):
    """Refuses, before any work, a path whose suffix (which the file's format follows) is none of `suffixes`,
    naming them."""
    if os.path.splitext(path)[1].lower() not in suffixes:
        raise InputError(f"{option} {path}: the file's format follows its suffix, which must be "
                         f"{' or '.join(suffixes)}; nothing was done")


@contextmanager
def replacing(path: str):
    """Yields a temporary path beside `path`, ending as it does (writers that choose a format by the suffix see
    the same one), for the body to write; renames it over `path` once the body succeeds, and removes it when the
    body fails, leaving any previous file at `path` untouched (an OSError becomes an InputError naming `path`).
    A symbolic link at `path` is written through: its target is replaced. Missing folders are created."""
    target = os.path.realpath(path)
    folder = os.path.dirname(target)
    os.makedirs(folder, exist_ok=True)
    temporary = _new_temporary(folder, os.path.splitext(target)[1])
    try:
        yield temporary
        if os.path.exists(target):
            os.chmod(temporary, stat.S_IMODE(os.stat(target).st_mode))
        _flush(temporary)
        os.replace(temporary, target)
    except BaseException as failure:
        if os.path.lexists(temporary):
            os.unlink(temporary)
        if isinstance(failure, OSError):  # a full disk, a quota, a vanished folder: said in one line naming the file
            raise InputError(f"cannot write {path}: {failure.strerror or failure}; any previous file there is as "
                             f"it was") from failure
        raise


def _new_temporary(folder: str, suffix: str) -> str:
    """An empty file of a name no other process has, created with the umask's permissions."""
    while True:
        path = os.path.join(folder, f"{TEMPORARY_PREFIX}{secrets.token_hex(6)}{TEMPORARY_TAG}{suffix}")
        try:
            os.close(os.open(path, os.O_WRONLY | os.O_CREAT | os.O_EXCL, 0o666))
            return path
        except FileExistsError:
            continue


def _flush(path: str):
    """The file's bytes on the disk before the rename makes them the output's (a power cut leaves old or new)."""
    handle = os.open(path, os.O_RDONLY)
    try:
        os.fsync(handle)
    except OSError as failure:  # a file system that cannot sync (some network ones) still gets its rename
        if failure.errno not in (errno.EINVAL, errno.ENOTSUP):
            raise
    finally:
        os.close(handle)


def image_is_whole(path: str) -> bool:
    """Whether an image file ends as its format says: a PNG's chunks whole (CRC) up to IEND, a JPEG's end-of-image
    marker; any other file is whole when it is not empty. Blender's PNG writer (renders, image saves) does not
    report a full disk: it leaves the file cut short."""
    with open(path, "rb") as handle:
        data = handle.read()
    if data.startswith(PNG_SIGNATURE):
        at = len(PNG_SIGNATURE)
        while at + 12 <= len(data):
            length, kind = struct.unpack(">I4s", data[at: at + 8])
            end = at + 12 + length
            if end > len(data) or zlib.crc32(data[at + 4: end - 4]) != struct.unpack(">I", data[end - 4: end])[0]:
                return False
            if kind == b"IEND":
                return True
            at = end
        return False
    if data.startswith(JPEG_START):
        return data.endswith(JPEG_END)
    return bool(data)


def blend_is_whole(path: str) -> bool:
    """Whether a .blend file ends as Blender ends one: compressed, with the seek table's footer; uncompressed, with
    the ENDB block's header (24 bytes before Blender 5, 32 since). Blender 5.2 does not report a full disk when
    saving: it leaves the file cut short."""
    with open(path, "rb") as handle:
        start = handle.read(len(BLEND_HEADER))
        handle.seek(0, os.SEEK_END)
        size = handle.tell()
        handle.seek(max(0, size - 32))
        tail = handle.read()
    if start.startswith(ZSTD_MAGIC):
        return tail.endswith(SEEKABLE_FOOTER)
    return start == BLEND_HEADER and BLEND_END in (tail[-32:-28], tail[-24:-20])


def write_json(path: str, data):
    """`data` as indented JSON at `path`, whole or not at all."""
    with replacing(path) as temporary, open(temporary, "w", encoding="utf-8") as handle:
        json.dump(data, handle, indent=2)
