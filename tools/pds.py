"""Read and write pathdensity sample dumps (.pds, format version 1) with numpy.

A dump is: b"PDSDUMP1", u32 version = 1, u32 header_len, the header (bincode 2,
fixed-width little-endian integers, strings as u64 length + UTF-8), zero
padding up to a multiple of 64 bytes, then records of six little-endian f32:
x, y, t, r, g, b. See docs/format.md for the fields.

    import pds
    hdr, rec = pds.read("scene.pds")          # rec is a read-only np.memmap
    rec["r"].max()
    pds.write("out.pds", rec, width=hdr["width"], height=hdr["height"])

The writers replace a file only if it is a previous dump (or empty): any
other file, a folder, a FIFO or a link at the path is refused with
RefusedError, and nothing is written.

Run `python3 tools/pds.py FILE` to print a dump's header.
"""

import errno
import os
import secrets
import stat
import struct
import sys

import numpy as np

MAGIC = b"PDSDUMP1"
VERSION = 1
HEADER_LEN_MAX = 65536
RECORD = np.dtype([(c, "<f4") for c in ("x", "y", "t", "r", "g", "b")])
ORDERS = {"unspecified": 0, "pixel": 1, "pass": 2}


class RefusedError(FileExistsError):
    """The path holds something a writer must not replace (its `filename`,
    and `strerror` says what)."""

    def __str__(self):
        return f"{self.filename}: {self.strerror}"


def _kind(mode):
    """What a file that is not a regular file is, for a refusal."""
    for test, name in ((stat.S_ISLNK, "a symbolic link"), (stat.S_ISDIR, "a directory"),
                       (stat.S_ISFIFO, "a FIFO"), (stat.S_ISSOCK, "a socket"),
                       (stat.S_ISCHR, "a device"), (stat.S_ISBLK, "a device")):
        if test(mode):
            return name
    return "not a regular file"


def looks_like_dump(head):
    """Whether `head`, the start of a file, starts like a dump."""
    return head[:len(MAGIC)] == MAGIC


def refusal(path, ours=looks_like_dump, what="a dump"):
    """Why `path` must not be replaced by `what`, or None when it may: it
    does not exist, or is a regular file that is empty or whose first 4 KiB
    `ours` accepts (a previous output). Opens nothing but a regular file,
    and that without blocking, so a FIFO cannot hang it. A link is refused,
    as the Rust side does: the rename would replace the link, not the file
    it names."""
    try:
        mode = os.lstat(path).st_mode
    except FileNotFoundError:
        return None
    if not stat.S_ISREG(mode):
        return f"is {_kind(mode)}, not a regular file: refusing to replace it"
    fd = os.open(path, os.O_RDONLY | os.O_NONBLOCK | getattr(os, "O_NOFOLLOW", 0))
    try:
        if not stat.S_ISREG(os.fstat(fd).st_mode):  # swapped since the lstat
            return "is not a regular file: refusing to replace it"
        head = os.read(fd, 4096)
    finally:
        os.close(fd)
    if head and not ours(head):
        return (f"exists and is not {what} pathdensity wrote: refusing to replace it "
                "(remove it or choose another name)")
    return None


def _data_offset(header_len):
    return (16 + header_len + 63) // 64 * 64


def encode_header(width, height, frames=1, spp=0, sample_count=0, order=0,
                  scene="", seed=0, producer="tools/pds.py"):
    """The bincode 2 (fixed-int, little-endian) encoding of the header."""
    if isinstance(order, str):
        order = ORDERS[order]
    s, p = scene.encode(), producer.encode()
    return (struct.pack("<IIIIQB", width, height, frames, spp, sample_count, order)
            + struct.pack("<Q", len(s)) + s + struct.pack("<Q", seed)
            + struct.pack("<Q", len(p)) + p)


def decode_header(buf):
    """Decodes a header body; raises ValueError unless it spans buf exactly."""
    width, height, frames, spp, count, order = struct.unpack_from("<IIIIQB", buf, 0)
    o = 25
    (n,) = struct.unpack_from("<Q", buf, o)
    scene = bytes(buf[o + 8:o + 8 + n]).decode()
    o += 8 + n
    (seed,) = struct.unpack_from("<Q", buf, o)
    o += 8
    (n,) = struct.unpack_from("<Q", buf, o)
    producer = bytes(buf[o + 8:o + 8 + n]).decode()
    o += 8 + n
    if o != len(buf):
        raise ValueError(f"header decodes from {o} bytes, header_len is {len(buf)}")
    if order > 2:
        raise ValueError(f"unknown record order {order}")
    return dict(width=width, height=height, frames=frames, spp=spp,
                sample_count=count, order=order, scene=scene, seed=seed,
                producer=producer)


def read(path):
    """Returns (header dict, records) with records a read-only np.memmap of RECORD."""
    size = os.path.getsize(path)
    with open(path, "rb") as f:
        fixed = f.read(16)
        if len(fixed) < 16 or fixed[:8] != MAGIC:
            raise ValueError(f"{path}: not a pathdensity dump")
        version, header_len = struct.unpack("<II", fixed[8:])
        if version != VERSION:
            raise ValueError(f"{path}: unsupported version {version}")
        if header_len > HEADER_LEN_MAX:
            raise ValueError(f"{path}: header_len {header_len} exceeds {HEADER_LEN_MAX}")
        off = _data_offset(header_len)
        head = f.read(off - 16)
    if len(head) != off - 16:
        raise ValueError(f"{path}: file too short for its header")
    hdr = decode_header(head[:header_len])
    if any(head[header_len:]):
        raise ValueError(f"{path}: non-zero padding")
    expected = off + 24 * hdr["sample_count"]
    if size != expected:
        raise ValueError(f"{path}: file size is {size} bytes, expected {expected}")
    if hdr["sample_count"] == 0:
        return hdr, np.zeros(0, RECORD)
    return hdr, np.memmap(path, RECORD, "r", offset=off, shape=(hdr["sample_count"],))


class Presized:
    """A dump of a known record count, filled by index and renamed into place.

        with pds.Presized("out.pds", n, width=w, height=h, spp=s, order="pass") as rec:
            rec[i:j] = chunk          # any (k, 6) float array or RECORD array

    The records are a writable np.memmap of RECORD under a temporary name; the
    file appears under its own name only when the block ends without an
    exception, and is removed otherwise. Entering the block raises
    RefusedError, writing nothing, when `path` holds anything but a dump."""

    def __init__(self, path, sample_count, width, height, frames=1, spp=0,
                 order=0, scene="", seed=0, producer="tools/pds.py"):
        body = encode_header(width, height, frames, spp, sample_count, order,
                             scene, seed, producer)
        if len(body) > HEADER_LEN_MAX:
            raise ValueError("header too long")
        prefix = MAGIC + struct.pack("<II", VERSION, len(body)) + body
        self._prefix = prefix + b"\0" * (_data_offset(len(body)) - len(prefix))
        self._path, self._count = path, sample_count
        self._tmp = None
        self._records = None

    def __enter__(self):
        problem = refusal(self._path)
        if problem:
            raise RefusedError(errno.EEXIST, problem, self._path)
        fd, self._tmp = temp_beside(self._path)
        try:
            with os.fdopen(fd, "wb") as f:
                f.write(self._prefix)
                f.truncate(len(self._prefix) + 24 * self._count)
            if self._count:
                self._records = _RecordView(np.memmap(
                    self._tmp, RECORD, "r+", offset=len(self._prefix), shape=(self._count,)))
            else:
                self._records = _RecordView(np.zeros(0, RECORD))
        except BaseException:
            # The block never runs, so its exit would not remove it.
            os.remove(self._tmp)
            raise
        return self._records

    def __exit__(self, kind, value, tb):
        records, self._records = self._records, None
        if kind is None and isinstance(records.array, np.memmap):
            records.array.flush()
        del records
        if kind is None:
            os.replace(self._tmp, self._path)
        elif os.path.exists(self._tmp):
            os.remove(self._tmp)
        return False


def temp_beside(path):
    """A new file, created exclusively beside `path` (so renaming it into
    place is atomic), named `.NAME.XXXXXXXX.tmp`: a name no existing
    file has, unlike one made from the process id. Its mode is an
    ordinary file's (0666 less the umask, which the kernel applies).
    Returns (fd, name); an error names `path`."""
    folder, name = os.path.split(os.path.abspath(path))
    flags = os.O_RDWR | os.O_CREAT | os.O_EXCL | os.O_NOFOLLOW | os.O_CLOEXEC
    for _ in range(100):
        tmp = os.path.join(folder, f".{name}.{secrets.token_hex(4)}.tmp")
        try:
            return os.open(tmp, flags, 0o666), tmp
        except FileExistsError:
            continue
        except OSError as e:
            raise OSError(e.errno, e.strerror, path) from None
    raise FileExistsError(errno.EEXIST, "no free temporary name beside it", path)


class _RecordView:
    """Index assignment that takes (k, 6) float arrays as well as RECORD arrays."""

    def __init__(self, array):
        self.array = array

    def __len__(self):
        return len(self.array)

    def __setitem__(self, index, values):
        self.array[index] = _as_records(values)


def _as_records(values):
    values = np.asarray(values)
    if values.dtype == RECORD:
        return values
    return np.ascontiguousarray(values, dtype="<f4").reshape(-1, 6).view(RECORD).ravel()


def write(path, records, width, height, frames=1, spp=0, order=0, scene="",
          seed=0, producer="tools/pds.py"):
    """Writes records (anything convertible to RECORD, or an (n, 6) float
    array) to path, under a temporary name renamed into place; raises
    RefusedError when path holds anything but a dump."""
    records = _as_records(records)
    with Presized(path, len(records), width, height, frames, spp, order, scene,
                  seed, producer) as out:
        out[:] = records


if __name__ == "__main__":
    for p in sys.argv[1:]:
        h, r = read(p)
        print(p, h, f"{len(r)} records")
