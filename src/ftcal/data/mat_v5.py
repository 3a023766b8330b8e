"""A bounded walk over the element tags of a MATLAB v5 file, before scipy reads it.

A v5 MAT-file is a 128-byte header followed by data elements, each an 8-byte
tag (type, byte count) and its bytes; a variable is a ``miMATRIX`` element
(flags, dimensions, name, then its data or, for structs and cells, more
``miMATRIX`` elements), or a ``miCOMPRESSED`` element holding one zlib-deflated
``miMATRIX``. scipy trusts the declared dimensions and byte counts: a few bytes
declaring a 10¹² × 1 struct make it allocate and loop over 10¹² elements, and a
small deflated stream can expand to terabytes. This walk reads only the tags,
dimensions and names (skipping the data) and refuses, naming the file and the
variable, any array declaring more than
:data:`~ftcal.core.limits.MAX_DECLARED_ELEMENTS` values, any element larger
than what encloses it (a truncated file), a deflated variable larger than its
declaration, and nesting deeper than :data:`~ftcal.core.limits.MAX_NESTING`.
Deflated data is expanded incrementally (``zlib.decompressobj`` with
``max_length``), never more than the declaration allows.
"""

from __future__ import annotations

import math
import struct
import zlib
from pathlib import Path

from ..core.limits import MAX_DECLARED_ELEMENTS, MAX_HEADER_BYTES, MAX_MAT_ARRAYS, MAX_NESTING
from ..runtime.errors import FtcalError

HEADER_BYTES = 128
MI_INT8, MI_INT32, MI_UINT32, MI_MATRIX, MI_COMPRESSED = 1, 5, 6, 14, 15
MX_CELL, MX_STRUCT, MX_OBJECT, MX_SPARSE = 1, 2, 3, 5
# The data types a numeric, char, logical or sparse array's data may have (miINT8 .. miUINT64, the UTF
# types). scipy indexes a table with the type and crashes the interpreter on others (11, say).
MAX_DIMS = 32  # scipy's _MAT_MAXDIMS: a MAT-file array has 2 to 32 dimensions
DATA_TYPES = frozenset((1, 2, 3, 4, 5, 6, 7, 9, 12, 13, 16, 17, 18))
_BLOCK = 1 << 20  # bytes skipped or inflated per step


class _Short(Exception):
    """The bytes ran out before an element's declared end."""


class _FileBytes:
    """An element's bytes read straight from the file."""

    def __init__(self, fh):
        self.fh = fh

    def read(self, n: int) -> bytes:
        data = self.fh.read(n)
        if len(data) < n:
            raise _Short
        return data

    def skip(self, n: int) -> None:
        if n < 0:
            raise _Short
        self.fh.seek(n, 1)


class _InflatedBytes:
    """A ``miCOMPRESSED`` element's bytes, inflated as they are asked for (never more)."""

    def __init__(self, fh, compressed: int):
        self.fh, self.left = fh, compressed
        self.inflate = zlib.decompressobj()

    def read(self, n: int) -> bytes:
        out, need = [], n
        while need:
            source = self.inflate.unconsumed_tail
            if not source:
                if self.inflate.eof or not self.left:
                    raise _Short
                source = self.fh.read(min(self.left, _BLOCK))
                if not source:
                    raise _Short
                self.left -= len(source)
            chunk = self.inflate.decompress(source, min(need, _BLOCK))
            out.append(chunk)
            need -= len(chunk)
        return b"".join(out)

    def skip(self, n: int) -> None:
        if n < 0:
            raise _Short
        while n:
            n -= len(self.read(min(n, _BLOCK)))


def check_v5(path: Path) -> None:
    """Refuse a MATLAB v5 file whose declared sizes or structure could exhaust memory or time.

    Parameters
    ----------
    path : a file that is not HDF5 (so not v7.3)

    Raises
    ------
    FtcalError
        Not a v5 MAT-file, truncated, corrupt deflated data, an array declaring more than
        ``MAX_DECLARED_ELEMENTS`` values, an element larger than its enclosure, or nesting
        deeper than ``MAX_NESTING``; the message names the file and the variable.
    """
    size = path.stat().st_size
    with open(path, "rb") as fh:
        header = fh.read(HEADER_BYTES)
        if len(header) < HEADER_BYTES or header[126:128] not in (b"IM", b"MI"):
            short = "; the file is shorter than one" if len(header) < HEADER_BYTES else ""
            raise FtcalError(f"Recording {path}: not a MATLAB v5 or v7.3 MAT-file (no v5 header{short}).")
        walk = _Walk(path, "<" if header[126:128] == b"IM" else ">")
        position = HEADER_BYTES
        while position < size:
            walk.current = f"the variable at byte {position:,}"
            try:
                kind, nbytes, taken, _ = walk.tag(_FileBytes(fh), size - position, walk.current, whole=False)
                if kind == MI_COMPRESSED:
                    walk.compressed(_InflatedBytes(fh, min(nbytes, size - position - 8)), nbytes > size - position - 8)
                elif kind == MI_MATRIX:
                    walk.matrix(_FileBytes(fh), min(nbytes, size - position - 8), "", 1, declared=nbytes)
            except _Short:
                raise FtcalError(f"Recording {path}: the MATLAB file is truncated or corrupt: {walk.current} "
                                 "ends before its declared size.") from None
            except zlib.error as exc:
                raise FtcalError(f"Recording {path}: the compressed data of {walk.current} is corrupt "
                                 f"({exc}).") from None
            except FtcalError:
                raise
            except (ValueError, struct.error, OverflowError) as exc:  # a field no check above foresaw
                raise FtcalError(f"Recording {path}: {walk.current} is corrupt ({exc}).") from None
            if 8 + nbytes > size - position:  # an element whose name could not be reached
                raise FtcalError(f"Recording {path}: the MATLAB file is truncated: {walk.current} declares "
                                 f"{nbytes:,} bytes but only {size - position - 8:,} remain.")
            position += 8 + nbytes if kind == MI_COMPRESSED else taken
            fh.seek(position)


class _Walk:
    """The walk over one file: its byte order, the innermost variable named so far, the arrays seen."""

    def __init__(self, path: Path, order: str):
        self.path, self.order = path, order
        self.current = "the first variable"  # the innermost variable named so far, for messages
        self.arrays = 0

    def tag(self, src, room: int, where: str, whole: bool = True) -> tuple[int, int, int, bytes]:
        """(type, byte count, bytes taken with tag and padding, data of a small element).

        With ``whole``, an element larger than ``room`` (what is left of its enclosure) is refused.
        """
        if room < 8:
            raise FtcalError(f"Recording {self.path}: the MATLAB file is truncated or corrupt: {where} has no "
                             f"room for its 8-byte tag ({room} bytes left).")
        raw = src.read(8)
        first, nbytes = struct.unpack(self.order + "II", raw)
        if first >> 16:  # the small element format: type, count and up to 4 bytes of data in 8 bytes
            if first >> 16 > 4:
                raise FtcalError(f"Recording {self.path}: {where}: a small data element declares {first >> 16} "
                                 "bytes (at most 4 fit); the MATLAB file is corrupt.")
            return first & 0xFFFF, first >> 16, 8, raw[4:4 + (first >> 16)]
        if whole and 8 + nbytes > room:
            raise FtcalError(f"Recording {self.path}: the MATLAB file is truncated or corrupt: {where} declares "
                             f"{nbytes:,} bytes but only {room - 8:,} remain.")
        return first, nbytes, min(8 + nbytes + (-nbytes % 8), max(room, 8 + nbytes)), b""

    def small(self, src, room: int, where: str, what: str, kind: int) -> tuple[bytes, int]:
        """A metadata subelement (flags, dimensions, name, field names) of type ``kind``: its bytes and room."""
        found, nbytes, taken, inline = self.tag(src, room, where)
        if found != kind:
            raise FtcalError(f"Recording {self.path}: {where}: the {what} subelement has type {found}, not {kind}; "
                             "the MATLAB file is corrupt.")
        if taken == 8 and nbytes <= 4:
            return inline, 8
        if nbytes > MAX_HEADER_BYTES:
            raise FtcalError(f"Recording {self.path}: {where}: the {what} subelement takes {nbytes:,} bytes, more "
                             f"than the limit of {MAX_HEADER_BYTES:,}; not a robot-logger recording.")
        data = src.read(nbytes)
        src.skip(taken - 8 - nbytes)
        return data, taken

    def compressed(self, src: _InflatedBytes, truncated: bool) -> None:
        """Walk a ``miCOMPRESSED`` variable; ``truncated``: the file ends before its compressed bytes do."""
        first, nbytes = struct.unpack(self.order + "II", src.read(8))
        if first != MI_MATRIX:
            if truncated:
                raise _Short
            return  # scipy skips anything but a matrix too
        if nbytes > 8 * MAX_DECLARED_ELEMENTS:
            raise FtcalError(f"Recording {self.path}: {self.current} declares {nbytes:,} bytes once decompressed, "
                             f"more than the limit of {8 * MAX_DECLARED_ELEMENTS:,}; not a robot-logger recording.")
        self.matrix(src, nbytes, "", 1)
        if truncated:
            raise _Short

    def matrix(self, src, room: int, prefix: str, depth: int, declared: int | None = None) -> None:
        """Walk one ``miMATRIX`` of ``room`` bytes (after its tag); ``prefix``: the enclosing variable's path.

        ``declared``: the byte count a top-level tag claims, checked once the variable's name is known.
        """
        where = prefix or self.current
        self.arrays += 1
        if self.arrays > MAX_MAT_ARRAYS:
            raise FtcalError(f"Recording {self.path}: more than {MAX_MAT_ARRAYS:,} arrays (at {where}); "
                             "not a robot-logger recording.")
        if depth > MAX_NESTING:
            raise FtcalError(f"Recording {self.path}: {where} nests arrays more than {MAX_NESTING} levels deep; "
                             "not a robot-logger recording.")
        if room == 0:  # an empty array
            return
        flags, used = self.small(src, room, where, "array flags", MI_UINT32)
        mx_class = struct.unpack(self.order + "I", flags[:4])[0] & 0xFF if len(flags) >= 4 else 0
        raw_dims, taken = self.small(src, room - used, where, "dimensions", MI_INT32)
        used += taken
        if len(raw_dims) < 8 or len(raw_dims) % 4 or len(raw_dims) > 4 * MAX_DIMS:
            raise FtcalError(f"Recording {self.path}: {where}: {len(raw_dims)} bytes of dimensions (2 to {MAX_DIMS} "
                             "4-byte numbers in a MAT-file); the MATLAB file is corrupt.")
        dims = struct.unpack(f"{self.order}{len(raw_dims) // 4}i", raw_dims)
        name, taken = self.small(src, room - used, where, "name", MI_INT8)
        used += taken
        if not prefix:
            where = _printable(name) or where
        self.current = where
        if declared is not None and declared > room:
            raise FtcalError(f"Recording {self.path}: the MATLAB file is truncated: the variable {where} declares "
                             f"{declared:,} bytes but only {room:,} remain.")
        count = math.prod(max(d, 0) for d in dims)
        if mx_class != MX_SPARSE and count > MAX_DECLARED_ELEMENTS:
            raise FtcalError(f"Recording {self.path}: the MATLAB variable {where} declares {count:,} values "
                             f"(dimensions {'x'.join(map(str, dims))}), more than the limit of "
                             f"{MAX_DECLARED_ELEMENTS:,}; not a robot-logger recording.")
        fields: list[str] = []
        if mx_class == MX_CELL:
            fields = [""]
        elif mx_class in (MX_STRUCT, MX_OBJECT):
            if mx_class == MX_OBJECT:
                used += self.small(src, room - used, where, "class name", MI_INT8)[1]
            length, taken = self.small(src, room - used, where, "field name length", MI_INT32)
            used += taken
            names, taken = self.small(src, room - used, where, "field names", MI_INT8)
            used += taken
            width = struct.unpack(self.order + "i", length[:4])[0] if len(length) >= 4 else 0
            fields = [f".{_printable(names[i:i + width])}" for i in range(0, len(names), width)] if width > 0 else []
        for i in range(count if fields else 0):  # each child takes at least its 8-byte tag: bounded by room
            for field in fields:
                child = f"{where}{field or f'{{{i + 1}}}'}"
                kind, nbytes, taken, _ = self.tag(src, room - used, child)
                if kind != MI_MATRIX or (taken == 8 and nbytes):  # a matrix is never a small element
                    raise FtcalError(f"Recording {self.path}: {child} is not a MATLAB array (element type {kind}).")
                self.matrix(src, nbytes, child, depth + 1)
                src.skip(taken - 8 - nbytes)
                used += taken
        self.current = where
        if mx_class in (MX_CELL, MX_STRUCT, MX_OBJECT):
            src.skip(room - used)
            return
        for seen in range(4):  # the data subelements (real, imaginary; sparse: ir, jc, pr, pi) must fit in the array
            if used >= room:
                if seen < (3 if mx_class == MX_SPARSE else 1):  # scipy would read the next array as this one's data
                    raise FtcalError(f"Recording {self.path}: {where} has no data; the MATLAB file is corrupt.")
                return
            kind, _, taken, _ = self.tag(src, room - used, where)
            if kind not in DATA_TYPES:
                raise FtcalError(f"Recording {self.path}: {where}: its data has element type {kind}, which is no "
                                 "MATLAB data type; the MATLAB file is corrupt.")
            src.skip(taken - 8)
            used += taken
        src.skip(room - used)


def _printable(raw: bytes) -> str:
    """A name from the file, for messages: up to its NUL, printable ASCII only, at most MATLAB's 63 characters."""
    text = "".join(c if " " <= c <= "~" else "?" for c in raw.split(bytes(1))[0].decode("latin-1"))
    return text if len(text) <= 63 else text[:60] + "..."
