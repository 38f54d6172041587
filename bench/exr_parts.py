"""Read every part of a multi-part scanline OpenEXR file into numpy arrays.

Blender 5's multilayer EXR puts each render pass in a part of its own ("ViewLayer.Combined",
"ViewLayer.Debug Sample Count", ...); Mitsuba's Bitmap, our other EXR reader, reads the
first part only. This reads scanline parts stored uncompressed, ZIPS or ZIP (zlib), of
FLOAT or HALF channels: what Blender writes with its default or "NONE" codec. Anything
else (tiles, deep data, other codecs, subsampled channels) is refused, not guessed at.
"""

import struct
import zlib

import numpy as np

_MAGIC = 20000630
_MULTIPART = 0x1000
_TILED, _DEEP = 0x200, 0x800
_LINES_PER_BLOCK = {0: 1, 2: 1, 3: 16}  # NONE, ZIPS, ZIP
_DTYPES = {1: np.dtype("<f2"), 2: np.dtype("<f4")}  # HALF, FLOAT


class ExrError(Exception):
    pass


def _cstring(data, pos):
    end = data.index(b"\0", pos)
    return data[pos:end].decode("latin-1"), end + 1


def _header(data, pos):
    """One header's attributes as {name: (type, raw bytes)}; returns it and the next pos."""
    attrs = {}
    while data[pos] != 0:
        name, pos = _cstring(data, pos)
        kind, pos = _cstring(data, pos)
        (size,) = struct.unpack_from("<i", data, pos)
        pos += 4
        attrs[name] = (kind, data[pos:pos + size])
        pos += size
    return attrs, pos + 1


def _channels(raw):
    out, pos = [], 0
    while raw[pos] != 0:
        name, pos = _cstring(raw, pos)
        pixel_type, _plinear, xs, ys = struct.unpack_from("<iB3xii", raw, pos)
        pos += 16
        if pixel_type not in _DTYPES or (xs, ys) != (1, 1):
            raise ExrError(f"channel {name!r}: pixel type {pixel_type} or sampling "
                           f"{xs}x{ys} not supported")
        out.append((name, _DTYPES[pixel_type]))
    return out  # the file's order: sorted by name, as the format requires


def _unzip(block):
    """EXR's ZIP: zlib, then a byte-delta predictor, then two interleaved halves."""
    t = np.frombuffer(zlib.decompress(block), dtype=np.uint8).astype(np.int32)
    # Undo the predictor: t[i] = t[i-1] + t[i] - 128 (mod 256) from i = 1 on.
    t = ((np.cumsum(t - 128) + 128) % 256).astype(np.uint8)
    half = (len(t) + 1) // 2
    out = np.empty_like(t)
    out[0::2], out[1::2] = t[:half], t[half:]
    return out.tobytes()


def read_parts(path):
    """{part name: {channel name: float32 array (H, W)}}, row 0 at the top."""
    with open(path, "rb") as f:
        data = f.read()
    magic, version = struct.unpack_from("<ii", data, 0)
    if magic != _MAGIC:
        raise ExrError(f"{path}: not an OpenEXR file")
    if version & (_TILED | _DEEP):
        raise ExrError(f"{path}: tiled or deep EXR not supported")
    pos = 8
    headers = []
    while True:
        attrs, pos = _header(data, pos)
        headers.append(attrs)
        if not version & _MULTIPART or data[pos] == 0:
            break
    if version & _MULTIPART:
        pos += 1  # the empty header that ends the list
    parts = []
    for i, attrs in enumerate(headers):
        xmin, ymin, xmax, ymax = struct.unpack("<4i", attrs["dataWindow"][1])
        compression = attrs["compression"][1][0]
        if compression not in _LINES_PER_BLOCK:
            raise ExrError(f"{path}: compression {compression} not supported")
        lines = _LINES_PER_BLOCK[compression]
        h, w = ymax - ymin + 1, xmax - xmin + 1
        if "chunkCount" in attrs:
            (chunks,) = struct.unpack("<i", attrs["chunkCount"][1])
        else:
            chunks = (h + lines - 1) // lines
        offsets = struct.unpack_from(f"<{chunks}Q", data, pos)
        pos += 8 * chunks
        name = attrs["name"][1].decode("latin-1").rstrip("\0") if "name" in attrs else str(i)
        parts.append((name, _channels(attrs["channels"][1]), w, h, ymin, compression,
                      offsets))
    out = {}
    multipart = bool(version & _MULTIPART)
    for name, channels, w, h, ymin, compression, offsets in parts:
        planes = {c: np.zeros((h, w), np.float32) for c, _ in channels}
        for off in offsets:
            p = off + (4 if multipart else 0)
            y, size = struct.unpack_from("<ii", data, p)
            block = data[p + 8:p + 8 + size]
            n_lines = min(_LINES_PER_BLOCK[compression], ymin + h - y)
            raw_size = n_lines * w * sum(dt.itemsize for _, dt in channels)
            if compression != 0 and size < raw_size:
                block = _unzip(block)
            if len(block) != raw_size:
                raise ExrError(f"{path}: part {name!r}: block at y={y} has {len(block)} "
                               f"bytes, expected {raw_size}")
            q = 0
            for line in range(n_lines):
                for c, dt in channels:
                    n = w * dt.itemsize
                    planes[c][y - ymin + line] = np.frombuffer(block[q:q + n], dt)
                    q += n
        out[name] = planes
    return out
