"""NumPy ``.npz`` bytes, compressed, the same every time for the same arrays.

The files are what ``numpy.savez_compressed`` writes and ``numpy.load`` reads: a zip archive of
one ``NAME.npy`` per array, each DEFLATE-compressed (zlib level 6). The compression runs through
zlib-ng, five to six times faster than the zlib that ``numpy.savez_compressed`` uses on the
mostly empty arrays of occupancy grids and map rasters, to files of the same size. Every member
is dated 1980-01-01 00:00 (the zip format's earliest date), so the same arrays give the same
bytes; ``numpy.savez_compressed`` stamps the time of writing.
"""

from __future__ import annotations

import io
import struct

import numpy as np
import numpy.typing as npt
from zlib_ng import zlib_ng

from gtgen.errors import SinkError

LEVEL = 6
_DEFLATE = 8
_VERSION = 20  # the zip format's version 2.0: DEFLATE, no zip64
_MADE_BY = (3 << 8) | _VERSION  # made on Unix: the external attributes hold a file mode
_DOS_DATE = (0 << 9) | (1 << 5) | 1  # 1980-01-01
_DOS_TIME = 0
_LIMIT = 0xFFFFFFFF  # sizes and offsets beyond this need zip64


def npz_bytes(**arrays: npt.ArrayLike) -> bytes:
    """The ``.npz`` archive of ``arrays`` (names as keyword names), compressed, as bytes."""
    out = io.BytesIO()
    directory = []
    for name, value in arrays.items():
        header, data = _npy(name, value)
        deflate = zlib_ng.compressobj(LEVEL, zlib_ng.DEFLATED, -15)
        packed = deflate.compress(header) + deflate.compress(data) + deflate.flush()
        crc = zlib_ng.crc32(data, zlib_ng.crc32(header))
        raw_size = len(header) + data.nbytes
        filename = f"{name}.npy".encode()
        offset = out.tell()
        if max(raw_size, len(packed), offset) > _LIMIT:
            raise SinkError(f"npz member {name}: {raw_size} bytes, more than a zip without zip64 holds (4 GiB)")
        sizes = struct.pack("<IIIHH", crc, len(packed), raw_size, len(filename), 0)
        out.write(struct.pack("<IHHHHH", 0x04034B50, _VERSION, 0, _DEFLATE, _DOS_TIME, _DOS_DATE) + sizes + filename)
        out.write(packed)
        directory.append(
            struct.pack("<IHHHHHH", 0x02014B50, _MADE_BY, _VERSION, 0, _DEFLATE, _DOS_TIME, _DOS_DATE)
            + sizes
            + struct.pack("<HHHII", 0, 0, 0, 0o644 << 16, offset)
            + filename
        )
    start = out.tell()
    for entry in directory:
        out.write(entry)
    size = out.tell() - start
    if start > _LIMIT or len(directory) > 0xFFFF:
        raise SinkError(f"npz of {len(directory)} arrays, {start} bytes: more than a zip without zip64 holds")
    out.write(struct.pack("<IHHHHIIH", 0x06054B50, 0, 0, len(directory), len(directory), size, start, 0))
    return out.getvalue()


def _npy(name: str, value: npt.ArrayLike) -> tuple[bytes, npt.NDArray[np.uint8]]:
    """The ``.npy`` file of ``value`` as its header and its data's bytes (C order, not copied when
    the array is already C-contiguous), as ``numpy.lib.format.write_array`` writes them."""
    array = np.asarray(value)
    if array.dtype.hasobject:
        raise SinkError(f"npz member {name}: an array of Python objects cannot be written ({array.dtype})")
    if not array.flags.c_contiguous:
        array = np.ascontiguousarray(array)
    header = io.BytesIO()
    np.lib.format.write_array_header_1_0(header, np.lib.format.header_data_from_array_1_0(array))
    data = array.reshape(-1).view(np.uint8) if array.size and array.itemsize else np.zeros(0, np.uint8)
    return header.getvalue(), data
