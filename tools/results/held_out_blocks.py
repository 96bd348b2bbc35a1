#!/usr/bin/env python3
"""A prototype, not shipped (docs/RESULTS.md, "Held-out halves over blocks
of every pixel"): `guided_oidn` or the mean, chosen per block of B × B
pixels by the held-out halves, on every dump of a folder made by
tools/results/dumps.sh.

Each RENDERER-SCENE-SPP.pds is split by the ordinal of each sample within
its pixel (even: half a, odd: half b) into two dumps of its own
(tools/pds.py); the whole dump gives the mean X, OIDN(mean) and
`guided_oidn` G, each half its mean X_a, X_b and OIDN's image of it D_a,
D_b (each with the renderer's albedo and normal). On display values d(·)
and per block, with

    e_D = mean of ((d(D_a) − d(X_b))² + (d(D_b) − d(X_a))²) / 2
    e_X = mean of (d(X_a) − d(X_b))²

e_D − e_X/2 estimates the denoised half's squared error (the halves'
noise is independent) and e_X/4 the whole mean's variance. The block
takes X where e_X/4 < C · (e_D − e_X/2), else G; with BLEND=1 it takes
w·X + (1 − w)·G instead, w = E/(E + e_X/4), E = C · (e_D − e_X/2) (at
least 0). The outputs are kept in WORK for the next run, with the
binary's size and time: a run with another binary refuses WORK. Prints each dump's
ratios (RMS / min(mean, OIDN), RMS_display / OIDN's, FLIP and HDR-FLIP /
min) for G and the choice, then counts at `guided_oidn`'s targets,
geometric means and worst.

Needs OIDN (README), numpy, flip-evaluator and OpenEXR (our outputs are
tiled):

    eval "$(bash tools/oidn/setup.sh)"
    python3 -m venv VENV && VENV/bin/pip install numpy flip-evaluator OpenEXR
    B=8 C=0.1 VENV/bin/python tools/results/held_out_blocks.py DUMPS WORK
"""
import glob, math, os, re, subprocess, sys

import numpy as np

here = os.path.dirname(os.path.abspath(__file__))
sys.path.insert(0, os.path.join(here, ".."))
import pds  # noqa: E402
import flip_evaluator as flip  # noqa: E402
import OpenEXR  # noqa: E402

BIN = os.environ.get("BIN", os.path.join(here, "..", "..", "target", "release", "pathdensity"))
B, C = int(os.environ.get("B", 8)), float(os.environ.get("C", 0.1))
BLEND = os.environ.get("BLEND") == "1"


def rgb(path):
    with OpenEXR.File(path) as f:
        ch = f.channels()
        if "RGB" in ch:
            return np.asarray(ch["RGB"].pixels, dtype=np.float64)[..., :3]
        return np.stack([np.asarray(ch[c].pixels, dtype=np.float64) for c in "RGB"], -1)


def display(v):
    v = np.clip(v, 0.0, 1.0)  # the tables' exposure, 1
    return np.where(v <= 0.0031308, 12.92 * v, 1.055 * np.power(v, 1 / 2.4) - 0.055)


def metrics(img, ref):
    rms = math.sqrt(np.mean((img - ref) ** 2))
    shown = math.sqrt(np.mean((display(img) - display(ref)) ** 2))
    _, ldr, _ = flip.evaluate(display(ref).astype(np.float32), display(img).astype(np.float32), "LDR",
                              applyMagma=False)
    _, hdr, _ = flip.evaluate(ref.astype(np.float32), img.astype(np.float32), "HDR", applyMagma=False)
    return np.array([rms, shown, ldr, hdr])


def filtered(dump, out, methods, dumps, scene):
    """`filter` once into OUT (kept between runs of the script)."""
    if os.path.exists(os.path.join(out, "report.json")):
        return
    aux = []
    albedo, normal = (os.path.join(dumps, f"{scene}-{n}.exr") for n in ("albedo", "normal"))
    if os.path.exists(albedo) and os.path.exists(normal):
        aux = ["--albedo", albedo, "--normal", normal]
    subprocess.run([BIN, "filter", dump, "-o", out, "--methods", methods, "--no-html", "--threads", "2", *aux],
                   check=True, stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)


def halves(dump, stem):
    """The dump's two halves by each sample's ordinal within its pixel."""
    a, b = f"{stem}-a.pds", f"{stem}-b.pds"
    if os.path.exists(b):
        return a, b
    h, r = pds.read(dump)
    w, ht = h["width"], h["height"]
    px = (np.clip(np.floor(r["y"]).astype(np.int64), 0, ht - 1) * w
          + np.clip(np.floor(r["x"]).astype(np.int64), 0, w - 1))
    order = np.argsort(px, kind="stable")
    starts = np.r_[0, np.flatnonzero(np.diff(px[order])) + 1]
    rank = np.arange(len(order)) - np.repeat(starts, np.diff(np.r_[starts, len(order)]))
    ordinal = np.empty_like(rank)
    ordinal[order] = rank
    for path, keep in ((a, ordinal % 2 == 0), (b, ordinal % 2 == 1)):
        pds.write(path, np.array(r[keep]), w, ht, spp=max(h["spp"] // 2, 1), order=h["order"])
    return a, b


def choose(g, x, xa, xb, da, db):
    """G with the blocks the halves say the mean is nearer taken from X."""
    e_d = ((display(da) - display(xb)) ** 2 + (display(db) - display(xa)) ** 2) / 2
    e_x = (display(xa) - display(xb)) ** 2
    out = g.copy()
    for y in range(0, g.shape[0], B):
        for x0 in range(0, g.shape[1], B):
            block = np.s_[y:y + B, x0:x0 + B]
            ed, ex = e_d[block].mean(), e_x[block].mean()
            err = C * max(ed - ex / 2, 0.0)
            if BLEND:
                w = err / (err + ex / 4) if err + ex / 4 > 0 else 0.0
                out[block] = w * x[block] + (1 - w) * g[block]
            elif ex / 4 < err:
                out[block] = x[block]
    return out


def main(dumps, work):
    os.makedirs(work, exist_ok=True)
    st = os.stat(BIN)
    stamp, stamp_path = f"{BIN} {st.st_size} {st.st_mtime_ns}\n", os.path.join(work, "binary")
    if os.path.exists(stamp_path) and open(stamp_path).read() != stamp:
        sys.exit(f"{work}: made by another binary than {BIN}; give an empty folder")
    if os.listdir(work) and not os.path.exists(stamp_path):
        sys.exit(f"{work}: not empty and not this script's; give an empty folder")
    with open(stamp_path, "w") as f:
        f.write(stamp)
    ratios = {"guided_oidn": [], "blocks": []}
    for dump in sorted(glob.glob(os.path.join(dumps, "*.pds"))):
        m = re.match(r"(.+)-(\d+)\.pds$", os.path.basename(dump))
        ref_path = os.path.join(dumps, f"{m.group(1)}-ref.exr") if m else ""
        if not m or not os.path.exists(ref_path):
            continue
        scene, stem = m.group(1), os.path.join(work, os.path.basename(dump)[:-4])
        a, b = halves(dump, stem)
        for src, out, methods in ((dump, stem, "mean,oidn,guided_oidn"), (a, stem + "-a", "mean,oidn"),
                                  (b, stem + "-b", "mean,oidn")):
            filtered(src, out, methods, dumps, scene)
        im = lambda out, name: rgb(os.path.join(out, f"{name}.exr"))  # noqa: E731
        ref = rgb(ref_path)
        x, o, g = im(stem, "mean"), im(stem, "oidn"), im(stem, "guided_oidn")
        new = choose(g, x, im(stem + "-a", "mean"), im(stem + "-b", "mean"), im(stem + "-a", "oidn"),
                     im(stem + "-b", "oidn"))
        mx, mo = metrics(x, ref), metrics(o, ref)
        base = np.array([min(mx[0], mo[0]), mo[1], min(mx[2], mo[2]), min(mx[3], mo[3])])
        line = f"{os.path.basename(dump)[:-4]:32s}"
        for name, img in (("guided_oidn", g), ("blocks", new)):
            r = metrics(img, ref) / base
            ratios[name].append(r)
            line += f" {name}: " + " ".join(f"{v:.3f}" for v in r)
        print(line, flush=True)
    targets = np.array([1.0, 1.05, 1.0, 1.0])
    for name, rs in ratios.items():
        r = np.array(rs)
        print(f"{name}: at the targets {[int(c) for c in (r <= targets).sum(0)]} of {len(r)}, geometric means "
              f"{np.round(np.exp(np.log(r).mean(0)), 3).tolist()}, worst {np.round(r.max(0), 3).tolist()}")


if __name__ == "__main__":
    main(*sys.argv[1:3])
