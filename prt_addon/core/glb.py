"""The binary glTF container (GLB): its JSON and binary chunks read and written, and data appended as a buffer view,
so an export can add what Blender's glTF exporter does not write (extras, data textures) after it ran."""

import json
import struct

MAGIC, VERSION = b"glTF", 2
JSON_CHUNK, BIN_CHUNK = 0x4E4F534A, 0x004E4942


def read(data: bytes) -> tuple[dict, bytearray]:
    """(the JSON document, the binary chunk, empty where there is none)."""
    magic, version, _ = struct.unpack_from("<4sII", data, 0)
    if magic != MAGIC or version != VERSION:
        raise ValueError("not a glTF 2.0 binary file")
    document, binary, offset = None, bytearray(), 12
    while offset < len(data):
        length, kind = struct.unpack_from("<II", data, offset)
        chunk = data[offset + 8: offset + 8 + length]
        if kind == JSON_CHUNK:
            document = json.loads(chunk.decode("utf-8"))
        elif kind == BIN_CHUNK:
            binary = bytearray(chunk)
        offset += 8 + length
    return document, binary


def write(document: dict, binary: bytes) -> bytes:
    """The GLB of a document and its binary chunk; both chunks padded to 4 bytes as the format requires."""
    text = json.dumps(document, separators=(",", ":")).encode("utf-8")
    text += b" " * (-len(text) % 4)
    chunks = struct.pack("<II", len(text), JSON_CHUNK) + text
    if binary:
        padded = bytes(binary) + b"\0" * (-len(binary) % 4)
        chunks += struct.pack("<II", len(padded), BIN_CHUNK) + padded
    return struct.pack("<4sII", MAGIC, VERSION, 12 + len(chunks)) + chunks


def append_buffer_view(document: dict, binary: bytearray, data: bytes) -> int:
    """Appends `data` to the binary chunk (aligned to 16 bytes, enough for any float view) as a new buffer view of
    buffer 0; returns the view's index."""
    binary.extend(b"\0" * (-len(binary) % 16))
    views = document.setdefault("bufferViews", [])
    views.append({"buffer": 0, "byteOffset": len(binary), "byteLength": len(data)})
    binary.extend(data)
    buffers = document.setdefault("buffers", [{}])
    buffers[0]["byteLength"] = len(binary)
    return len(views) - 1
