"""Uncompressed float32 scanline EXR, read and written with numpy.

Blender's Python module has no EXR reader of its own that gives every
channel of a multilayer file (`Image.pixels` shows one pass, and never for
the Render Result in background mode), and no OpenImageIO bindings. The
exporter makes Cycles write its multilayer EXR with `exr_codec = 'NONE'`
and 32-bit floats, which this reads exactly; it refuses anything else
(compression, tiles, deep data, half floats) rather than guess.

    channels, (w, h) = exrio.read("render.exr")   # {name: (h, w) float32}
    exrio.write_rgb("out.exr", image)             # image: (h, w, 3) float32

Every EXR the exporters write goes through `write_rgb`, which marks it with
the `pathdensity` string attribute the Rust side writes too: an existing
EXR is replaced only if it has it (`written_by_us`), so a user's own image
at an output's name is never overwritten.
"""

import os
import struct
import sys

import numpy as np

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
import pds  # noqa: E402

MAGIC = 20000630
# The header attribute (a string) that says pathdensity wrote the file.
WRITER_ATTRIBUTE = "pathdensity"
FLOAT, HALF, UINT = 2, 1, 0
TILED, LONG_NAMES, NON_IMAGE, MULTIPART = 0x200, 0x400, 0x800, 0x1000


class ExrError(Exception):
    pass


def _cstring(buf, o):
    end = buf.index(b"\0", o)
    return buf[o:end].decode("latin-1"), end + 1


def _header(buf, o):
    attrs = {}
    while buf[o] != 0:
        name, o = _cstring(buf, o)
        kind, o = _cstring(buf, o)
        (size,) = struct.unpack_from("<i", buf, o)
        o += 4
        attrs[name] = (kind, buf[o:o + size])
        o += size
    return attrs, o + 1


def written_by_us(head):
    """Whether `head`, the start of a file, is an EXR whose header (within
    `head`) holds WRITER_ATTRIBUTE; a truncated or malformed one is not."""
    if len(head) < 8 or struct.unpack_from("<i", head)[0] != MAGIC:
        return False
    try:
        attrs, _ = _header(head, 8)
    except (ValueError, IndexError, struct.error):
        return False
    return attrs.get(WRITER_ATTRIBUTE, ("",))[0] == "string"


def _channels(path, attrs):
    chlist = attrs["channels"][1]
    names, c = [], 0
    while chlist[c] != 0:
        name, c = _cstring(chlist, c)
        ptype, _linear, xs, ys = struct.unpack_from("<iB3xii", chlist, c)
        c += 16
        if ptype != FLOAT or xs != 1 or ys != 1:
            raise ExrError(f"{path}: channel {name!r} is not full-resolution float32 "
                           f"(type {ptype}); the exporter renders color_depth '32'")
        names.append(name)
    return names


def read(path):
    """Returns ({channel name: (h, w) float32 array}, (w, h)). A multi-part
    file (Blender 5 writes a multilayer EXR as one part per pass) gives its
    parts' channels, each named PART.CHANNEL unless the name has a dot."""
    with open(path, "rb") as f:
        buf = f.read()
    magic, version = struct.unpack_from("<ii", buf, 0)
    if magic != MAGIC:
        raise ExrError(f"{path}: not an EXR")
    if version & (TILED | NON_IMAGE):
        raise ExrError(f"{path}: tiled or deep EXR (flags {version:#x})")
    multipart = bool(version & MULTIPART)
    o, parts = 8, []
    while True:
        attrs, o = _header(buf, o)
        parts.append(attrs)
        if not multipart or buf[o] == 0:
            break
    if multipart:
        o += 1
    data, size = {}, None
    tables = []
    for attrs in parts:
        x0, y0, x1, y1 = struct.unpack("<iiii", attrs["dataWindow"][1])
        w, h = x1 - x0 + 1, y1 - y0 + 1
        if size not in (None, (w, h)):
            raise ExrError(f"{path}: parts of different sizes")
        size = (w, h)
        if attrs["compression"][1][0] != 0:
            raise ExrError(f"{path}: compressed EXR (compression {attrs['compression'][1][0]}); "
                           "the exporter writes exr_codec NONE")
        if "type" in attrs and attrs["type"][1].rstrip(b"\0") != b"scanlineimage":
            raise ExrError(f"{path}: part of type {attrs['type'][1]!r}, not scanlineimage")
        tables.append(np.frombuffer(buf, "<u8", h, o))
        o += 8 * h
    w, h = size
    for index, (attrs, table) in enumerate(zip(parts, tables)):
        names = _channels(path, attrs)
        prefix = ""
        if multipart and "name" in attrs:
            prefix = attrs["name"][1].rstrip(b"\0").decode("latin-1")
        full = [n if not prefix or "." in n else f"{prefix}.{n}" for n in names]
        planes = {n: np.empty((h, w), np.float32) for n in full}
        line = 4 * w
        y0 = struct.unpack("<iiii", attrs["dataWindow"][1])[1]
        for off in table:
            off = int(off)
            if multipart:
                (part,) = struct.unpack_from("<i", buf, off)
                if part != index:
                    raise ExrError(f"{path}: chunk of part {part} in part {index}'s table")
                off += 4
            y, nbytes = struct.unpack_from("<ii", buf, off)
            if nbytes != line * len(names):
                raise ExrError(f"{path}: scanline {y} holds {nbytes} bytes, expected "
                               f"{line * len(names)}")
            row = np.frombuffer(buf, "<f4", w * len(names), off + 8).reshape(len(names), w)
            for i, n in enumerate(full):
                planes[n][y - y0] = row[i]
        data.update(planes)
    return data, size


def _attr(name, kind, value):
    return name.encode() + b"\0" + kind.encode() + b"\0" + struct.pack("<i", len(value)) + value


def write_rgb(path, image):
    """Writes an (h, w, 3) image as an uncompressed float32 RGB EXR, under a
    temporary name renamed into place."""
    image = np.ascontiguousarray(image, dtype="<f4")
    h, w, _ = image.shape
    chlist = b"".join(n.encode() + b"\0" + struct.pack("<iB3xii", FLOAT, 0, 1, 1)
                      for n in ("B", "G", "R")) + b"\0"
    box = struct.pack("<iiii", 0, 0, w - 1, h - 1)
    header = (struct.pack("<ii", MAGIC, 2)
              + _attr("channels", "chlist", chlist)
              + _attr("compression", "compression", b"\0")
              + _attr("dataWindow", "box2i", box)
              + _attr("displayWindow", "box2i", box)
              + _attr("lineOrder", "lineOrder", b"\0")
              + _attr("pixelAspectRatio", "float", struct.pack("<f", 1.0))
              + _attr("screenWindowCenter", "v2f", struct.pack("<ff", 0.0, 0.0))
              + _attr("screenWindowWidth", "float", struct.pack("<f", 1.0))
              + _attr(WRITER_ATTRIBUTE, "string", b"written by pathdensity")
              + b"\0")
    line = 8 + 12 * w
    start = len(header) + 8 * h
    offsets = np.arange(h, dtype="<u8") * line + start
    body = bytearray()
    for y in range(h):
        body += struct.pack("<ii", y, 12 * w)
        body += image[y, :, ::-1].T.tobytes()  # B, G, R: channels in name order
    fd, tmp = pds.temp_beside(path)
    try:
        with os.fdopen(fd, "wb") as f:
            f.write(header + offsets.tobytes() + bytes(body))
        os.replace(tmp, path)
    finally:
        if os.path.exists(tmp):
            os.remove(tmp)
