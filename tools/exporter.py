"""What the renderers' exporters (tools/mitsuba/export.py,
tools/cycles/export.py) share: their one-line error and the parsers of
their common flags."""
import argparse


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
