"""Hostile part files for the merge's tests: .npy members of any header, zip archives of any members (a name twice,
any compression), and a zip bomb: a real deflate stream of a gigabyte of zeros in a few hundred kilobytes."""

import io
import struct
import warnings
import zipfile
import zlib

import numpy as np


def npy(array, allow_pickle=False) -> bytes:
    out = io.BytesIO()
    np.lib.format.write_array(out, np.asanyarray(array), allow_pickle=allow_pickle)
    return out.getvalue()


def npy_header(shape, dtype="<f8") -> bytes:
    """An .npy header claiming any shape; its data is whatever follows."""
    out = io.BytesIO()
    np.lib.format.write_array_header_1_0(out, {"descr": dtype, "fortran_order": False, "shape": shape})
    return out.getvalue()


def archive(members, compression=zipfile.ZIP_STORED) -> bytes:
    """A zip of (name, bytes) members, name.npy each, stored or compressed as asked; names may repeat."""
    out = io.BytesIO()
    with warnings.catch_warnings(), zipfile.ZipFile(out, "w") as written:
        warnings.simplefilter("ignore")  # a repeated name
        for name, data in members:
            written.writestr(zipfile.ZipInfo(name + ".npy"), data, compress_type=compression)
    return out.getvalue()


def with_bomb(part: bytes, name: str, gigabytes: int = 1) -> bytes:
    """The part with member `name`.npy replaced by a zip bomb: an .npy of that many GiB of zeros, deflated (each
    16 MiB block flushed whole, so every block after the first compresses to the same bytes) into a few hundred
    kB, with its true size and CRC."""
    zeros = bytes(16 << 20)
    header = npy_header((gigabytes << 27,))
    compressor = zlib.compressobj(9, zlib.DEFLATED, -15)
    first = compressor.compress(header) + compressor.flush(zlib.Z_FULL_FLUSH)
    block = compressor.compress(zeros) + compressor.flush(zlib.Z_FULL_FLUSH)
    blocks = (gigabytes << 30) // len(zeros)
    crc = zlib.crc32(header)
    for _ in range(blocks):
        crc = zlib.crc32(zeros, crc)
    bomb = (name + ".npy", zipfile.ZIP_DEFLATED, crc, len(header) + blocks * len(zeros),
            first + block * blocks + compressor.flush())
    with zipfile.ZipFile(io.BytesIO(part)) as source:
        members = [bomb if entry.filename == bomb[0] else
                   (entry.filename, zipfile.ZIP_STORED, entry.CRC, entry.file_size, source.read(entry))
                   for entry in source.infolist()]
    return raw_zip(members)


def raw_zip(members) -> bytes:
    """A zip of (name, method, CRC, size, data as stored) members: data already compressed is written as it is."""
    out, directory = bytearray(), bytearray()
    for name, method, crc, size, data in members:
        encoded = name.encode()
        directory += struct.pack("<4s6H3L5H2L", b"PK\x01\x02", 20, 20, 0, method, 0, 0, crc, len(data), size,
                                 len(encoded), 0, 0, 0, 0, 0, len(out)) + encoded
        out += struct.pack("<4s5H3L2H", b"PK\x03\x04", 20, 0, method, 0, 0, crc, len(data), size, len(encoded),
                           0) + encoded + data
    end = struct.pack("<4s4H2LH", b"PK\x05\x06", 0, 0, len(members), len(members), len(directory), len(out), 0)
    return bytes(out + directory + end)
