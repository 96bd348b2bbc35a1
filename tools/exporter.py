"""What the renderers' exporters (tools/mitsuba/export.py,
tools/cycles/export.py) share: their one-line error and the parsers of
their common flags."""
import argparse
import sys
import time


class ExportError(Exception):
    """A problem with the user's input, printed as one line."""


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
