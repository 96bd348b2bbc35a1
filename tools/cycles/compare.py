#!/usr/bin/env python3
"""A dump against Cycles' own render of the same samples (`export.py
--film-out`): how far the per-pixel mean is from it, and where the records
lie in their pixels.

    compare.py DUMP.pds FILM.exr

Prints the worst |mean - film| / (|film| + the image's mean |film|) (what
tests/cycles.rs bounds by 1e-5), the same over the image's largest |film|,
whether every record floors to its own pixel, and the mean and standard
deviation of the fractional positions of samples 1.. (uniform: 0.5, 0.2887).
Needs only numpy.
"""

import os
import sys

import numpy as np

sys.path.insert(0, os.path.join(os.path.dirname(os.path.abspath(__file__)), ".."))
sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
import exrio  # noqa: E402
import pds  # noqa: E402


def main(dump, film_path):
    h, rec = pds.read(dump)
    if h["frames"] != 1 or h["spp"] == 0 or h["order"] == 0:
        sys.exit(f"compare.py: {dump}: needs a still with a uniform spp and a known order")
    channels, (w, hh) = exrio.read(film_path)
    if (w, hh) != (h["width"], h["height"]):
        sys.exit(f"compare.py: {film_path} is {w}x{hh}, the dump {h['width']}x{h['height']}")
    film = np.stack([channels[c] for c in "RGB"], -1).reshape(-1, 3).astype(np.float64)
    n, pixels = h["spp"], w * hh
    rec = np.asarray(rec)
    shape = (n, pixels) if h["order"] == 2 else (pixels, n)
    grid = {c: rec[c].reshape(shape) if h["order"] == 2 else rec[c].reshape(shape).T
            for c in ("x", "y", "r", "g", "b")}
    mean = np.stack([grid[c].astype(np.float64).mean(0) for c in "rgb"], -1)
    floor = np.abs(film).mean()
    worst = float((np.abs(mean - film) / (np.abs(film) + floor)).max())
    over_max = float(np.abs(mean - film).max() / np.abs(film).max())
    pixel = np.arange(pixels)
    inside = bool(np.all(np.floor(grid["x"]) == pixel % w) and np.all(np.floor(grid["y"]) == pixel // w))
    fx, fy = (grid[c][1:] - np.floor(grid[c][1:]) for c in "xy")
    print(f"{dump}: mean vs {film_path}: worst relative {worst:.2e} (over the largest pixel "
          f"{over_max:.2e}); every record in its pixel: {inside}; fractional x, y of samples 1..: "
          f"mean {fx.mean():.4f} {fy.mean():.4f}, std {fx.std():.4f} {fy.std():.4f}")


if __name__ == "__main__":
    if len(sys.argv) != 3:
        sys.exit(__doc__.strip().splitlines()[3].strip())
    main(*sys.argv[1:])
