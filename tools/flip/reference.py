#!/usr/bin/env python3
"""Mean FLIP of image pairs by NVIDIA's reference implementation.

Reads pairs of raw little-endian float32 RGB images (HEIGHT x WIDTH x 3,
linear values) named on the command line as
    WIDTH HEIGHT EXPOSURE REFERENCE.f32 TEST.f32
and prints one JSON line per pair: {"ldr": mean LDR-FLIP of the display
transform (clamp(exposure * v, 0, 1), sRGB-encoded), "hdr": mean HDR-FLIP of
the linear values with FLIP's own exposure range}. Used by tests/flip.rs.
"""
import json
import sys

import flip_evaluator as flip
import numpy as np


def load(path, w, h):
    return np.fromfile(path, dtype="<f4").reshape(h, w, 3)


def display(v, exposure):
    v = np.clip(v * exposure, 0.0, 1.0)
    return np.where(v <= 0.0031308, 12.92 * v, 1.055 * np.power(v, 1 / 2.4) - 0.055).astype(np.float32)


args = sys.argv[1:]
while args:
    w, h, exposure, ref_path, test_path = args[:5]
    args = args[5:]
    w, h, exposure = int(w), int(h), float(exposure)
    ref, test = load(ref_path, w, h), load(test_path, w, h)
    _, ldr, _ = flip.evaluate(display(ref, exposure), display(test, exposure), "LDR", applyMagma=False)
    _, hdr, params = flip.evaluate(ref, test, "HDR", applyMagma=False)
    print(json.dumps({"ldr": float(ldr), "hdr": float(hdr), "params": {k: str(v) for k, v in params.items()}}))
