"""What the renderers' exporters (tools/mitsuba/export.py,
tools/cycles/export.py) share: their one-line error, the check of their
outputs and the parsers of their common flags."""
import argparse
import os
import sys
import time

import exrio
import pds

# How a previous output of each kind is told apart: an existing file at an
# output's name is replaced only if it is one.
KINDS = {"dump": (pds.looks_like_dump, "a dump"), "exr": (exrio.written_by_us, "an EXR")}


class ExportError(Exception):
    """A problem with the user's input, printed as one line."""


def check_outputs(inputs, outputs):
    """Refuses, before any work, an output that would destroy what the user
    did not hand us: one that is an input or another output (by identity,
    links resolved), or that exists and is not a previous output of its
    kind (pds.refusal). `outputs` are (path, kind) pairs, kind "dump" or
    "exr"; a path of None (a flag not given) is skipped, as is an input
    that does not exist (it cannot be harmed)."""
    given = {}
    for p in inputs:
        key = _identity(p)
        if key[0] == "file":
            given.setdefault(key, p)
    taken = {}
    for path, kind in outputs:
        if path is None:
            continue
        key = _identity(path)
        if key in given:
            what = ("an input of this export" if given[key] == path
                    else f"the same file as the input {given[key]}")
            raise ExportError(f"{path}: is {what}: refusing to overwrite it")
        if key in taken:
            what = ("is named by two outputs" if taken[key] == path
                    else f"is the same file as the output {taken[key]}")
            raise ExportError(f"{path}: {what}: two outputs cannot share one file")
        taken[key] = path
        problem = pds.refusal(path, *KINDS[kind]) or _unwritable(path)
        if problem:
            raise ExportError(f"{path}: {problem}")


def _unwritable(path):
    """Why `path` cannot be written in its folder, checked now rather than
    found after a render."""
    folder = os.path.dirname(os.path.abspath(path))
    if not os.path.isdir(folder):
        return f"its folder {folder} does not exist"
    if not os.access(folder, os.W_OK | os.X_OK):
        return f"its folder {folder} is not writable"
    return None


def _identity(path):
    """Device and inode when `path` names an existing file (links
    followed); else the name it resolves to, so two new outputs of one
    name, or a dangling link to the other's name, still compare equal."""
    try:
        st = os.stat(path)
        return ("file", st.st_dev, st.st_ino)
    except OSError:
        return ("name", os.path.realpath(path))


def parse_size(text):
    """`--size WxH`: a film of 1x1 to 8192x8192 pixels."""
    try:
        w, h = (int(v) for v in text.lower().split("x"))
    except ValueError:
        raise argparse.ArgumentTypeError(f"expected WxH, e.g. 128x128, got {text!r}")
    if not (1 <= w <= 8192 and 1 <= h <= 8192):
        raise argparse.ArgumentTypeError(f"film size {w}x{h} is outside 1x1..8192x8192")
    return w, h


def positive(text):
    """A count of at least 1 (`--spp`, `--threads`)."""
    value = int(text)
    if value < 1:
        raise argparse.ArgumentTypeError(f"must be at least 1, got {value}")
    return value


class Progress:
    """A bar on stderr when it is a terminal (and not `quiet`), else silent."""

    def __init__(self, label, total, quiet=False):
        self.label, self.total, self.done = label, total, 0
        self.on = not quiet and sys.stderr.isatty()
        self.start = time.monotonic()

    def advance(self, n=1):
        self.done += n
        if self.on:
            frac = self.done / self.total
            sys.stderr.write(f"\r{self.label} [{'#' * int(30 * frac):<30}] {self.done}/{self.total} "
                             f"{time.monotonic() - self.start:6.1f} s")
            if self.done >= self.total:
                sys.stderr.write("\n")
            sys.stderr.flush()
