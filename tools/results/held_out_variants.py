#!/usr/bin/env python3
"""How the held-out halves' rule was chosen (docs/RESULTS.md, "The guided
image"): variants of the rule measured on every dump of a folder made by
tools/results/dumps.sh, outside the Rust code.

For each RENDERER-SCENE-SPP.pds the dump is filtered whole and, split by
the ordinal of each sample within its pixel (even, odd), as two dumps of
its own (so each half has its own replay); the recommended image of each
half stands for G_a and G_b. Each variant picks per pixel the whole dump's
mean or its recommended image, and is scored like fidelity_table.py:
linear RMS, RMS_display, FLIP and HDR-FLIP (NVIDIA's flip_evaluator)
against the smaller of the mean's and OIDN(mean)'s (KEY=guided: the
mean's; display error against OIDN's). Variants also decide every pixel
in display space (the half means' difference standing for their error),
or blend the image a fixed fraction of the way to the mean everywhere.
Prints the counts at the targets and the geometric means. Whole white
pixels only: `guided`'s shipped rule, each white channel on its own, is
not modelled. The Rust rule's guard for pixels holding a
rejected sample is not modelled here.

Needs the Python module and OIDN (README), flip-evaluator, and OpenEXR for
our renderer's (tiled) references:

    bash tools/python/setup.sh && eval "$(bash tools/oidn/setup.sh)"
    tools/python/.venv/bin/pip install flip-evaluator OpenEXR
    KEY=guided_oidn tools/python/.venv/bin/python tools/results/held_out_variants.py DUMPS
"""
import glob, math, os, re, sys

import numpy as np

sys.path.insert(0, os.path.join(os.path.dirname(os.path.abspath(__file__)), ".."))
import exrio  # noqa: E402
import flip_evaluator as flip  # noqa: E402
import pathdensity  # noqa: E402

KEY = os.environ.get("KEY", "guided_oidn")
# (name, decide only white pixels, estimate, window radius, z of a t-test on the window's δ)
VARIANTS = [
    ("all pixels, 5 x 5", False, "var", 2, None),
    ("all pixels, 7 x 7", False, "var", 3, None),
    ("white, 7 x 7", True, "var", 3, None),
    ("white, 17 x 17 (shipped for guided_oidn)", True, "var", 8, None),
    ("white, 33 x 33", True, "var", 16, None),
    ("white, whole film", True, "var", 10**6, None),
    ("white, 17 x 17, t-test z = 1", True, "var", 8, 1.0),
    ("white, 17 x 17, no s2 (half difference)", True, "diff", 8, None),
    ("all pixels, display-space half difference, 7 x 7", False, "display diff", 3, None),
    ("all pixels, display-space half difference, 17 x 17", False, "display diff", 8, None),
    ("all pixels, display-space half difference, 33 x 33", False, "display diff", 16, None),
]
# Fractions of the way from the image to the mean, everywhere.
BLENDS = [0.25, 0.5]


def rgb(path):
    try:
        ch, _ = exrio.read(path)
        return np.stack([ch[c] for c in "RGB"], -1).astype(np.float32)
    except exrio.ExrError:
        import OpenEXR
        with OpenEXR.File(path) as f:
            ch = f.channels()
            if "RGB" in ch:
                return np.asarray(ch["RGB"].pixels, dtype=np.float32)[..., :3]
            return np.stack([np.asarray(ch[c].pixels, dtype=np.float32) for c in "RGB"], -1)


def display(v, e):
    v = np.clip(v * e, 0.0, 1.0)
    return np.where(v <= 0.0031308, 12.92 * v, 1.055 * np.power(v, 1 / 2.4) - 0.055).astype(np.float32)


def metrics(img, ref, e):
    rms = math.sqrt(np.mean((img.astype(np.float64) - ref) ** 2))
    rd = math.sqrt(np.mean((display(img, e).astype(np.float64) - display(ref, e)) ** 2))
    _, ldr, _ = flip.evaluate(display(ref, e), display(img, e), "LDR", applyMagma=False)
    _, hdr, _ = flip.evaluate(ref, img.astype(np.float32), "HDR", applyMagma=False)
    return np.array([rms, rd, float(ldr), float(hdr)])


def pixel_of(rec, w, h):
    x = np.clip(np.floor(np.nan_to_num(rec[:, 0])).astype(np.int64), 0, w - 1)
    y = np.clip(np.floor(np.nan_to_num(rec[:, 1])).astype(np.int64), 0, h - 1)
    return x + w * y


def ordinals(rec, w, h):
    """Each record's ordinal among its pixel's records, in file order."""
    px = pixel_of(rec, w, h)
    order = np.argsort(px, kind="stable")
    start = np.r_[0, np.flatnonzero(np.diff(px[order])) + 1]
    first = np.repeat(start, np.diff(np.r_[start, len(px)]))
    rank = np.empty(len(px), np.int64)
    rank[order] = np.arange(len(px)) - first
    return rank


def mean_and_se2(rec, w, h):
    """Per pixel the mean of the valid samples and its own s²/n (∞ below two)."""
    c = rec[:, 3:6].astype(np.float64)
    ok = np.isfinite(rec).all(1)
    px, c = pixel_of(rec, w, h)[ok], c[ok]
    n = np.bincount(px, minlength=w * h).astype(np.float64)
    s = np.stack([np.bincount(px, c[:, k], minlength=w * h) for k in range(3)], -1)
    s2 = np.stack([np.bincount(px, c[:, k] ** 2, minlength=w * h) for k in range(3)], -1)
    m = s / np.maximum(n, 1)[:, None]
    var = np.maximum(s2 - n[:, None] * m * m, 0) / np.maximum(n - 1, 1)[:, None]
    se2 = np.where(n[:, None] >= 2, var / np.maximum(n, 1)[:, None], np.inf)
    return m.reshape(h, w, 3), se2.reshape(h, w, 3)


def box(a, r):
    """Per pixel the sum of `a` over the (2r + 1)² window, clipped at the film's edge."""
    r = min(r, max(a.shape))
    c = np.pad(np.cumsum(np.cumsum(a, 0), 1), ((1, 0), (1, 0)))
    hh, ww = a.shape
    y0, y1 = np.clip(np.arange(hh) - r, 0, hh), np.clip(np.arange(hh) + r + 1, 0, hh)
    x0, x1 = np.clip(np.arange(ww) - r, 0, ww), np.clip(np.arange(ww) + r + 1, 0, ww)
    return c[y1][:, x1] - c[y0][:, x1] - c[y1][:, x0] + c[y0][:, x0]


def main(folder):
    scores = {name: [] for name, *_ in VARIANTS}
    scores["shipped without halves"] = []
    for dump in sorted(glob.glob(os.path.join(folder, "*.pds"))):
        m = re.match(r"(.+)-(\d+)\.pds$", os.path.basename(dump))
        if not m or not os.path.exists(os.path.join(folder, f"{m.group(1)}-ref.exr")):
            continue
        scene = m.group(1)
        hdr, rec = pathdensity.read_dump(dump)
        w, h = hdr["width"], hdr["height"]
        ref = rgb(os.path.join(folder, f"{scene}-ref.exr"))
        aux = {}
        if os.path.exists(os.path.join(folder, f"{scene}-albedo.exr")):
            aux = {k: rgb(os.path.join(folder, f"{scene}-{k}.exr")) for k in ("albedo", "normal")}
        run = lambda r, hd: pathdensity.filter(r, header=hd, methods=f"mean,oidn,{KEY}",
                                               held_out=False, threads=2, **aux)
        full = run(rec, hdr)
        e = full.config["exposure"]
        recs = np.asarray(rec)
        rank = ordinals(recs, w, h)
        g, x, se2 = [], [], []
        for parity in (0, 1):
            half = np.ascontiguousarray(recs[rank % 2 == parity])
            g.append(run(half, dict(hdr, spp=hdr["spp"] // 2, sample_count=len(half))).images[KEY][0])
            mk, vk = mean_and_se2(half, w, h)
            x.append(mk)
            se2.append(vk)
        bad = ~(np.isfinite(se2[0]).all(-1) & np.isfinite(se2[1]).all(-1))
        v = [np.where(np.isfinite(s), s, 0) for s in se2]
        held = ((g[0] - x[1]) ** 2 + (g[1] - x[0]) ** 2) / 2
        # In display space the half means' difference stands for their
        # error (no variance passes through the display transform).
        t = lambda a: display(a, e).astype(np.float64)
        shown = ((t(g[0]) - t(x[1])) ** 2 + (t(g[1]) - t(x[0])) ** 2) / 2
        delta = {"var": (held - v[0] - v[1]).sum(-1),
                 "diff": (held - (x[0] - x[1]) ** 2).sum(-1),
                 "display diff": (shown - (t(x[0]) - t(x[1])) ** 2).sum(-1)}
        X, G, O = (full.images[k][0] for k in ("mean", KEY, "oidn"))
        base = metrics(X, ref, e), metrics(O, ref, e)
        white = (G >= 1 / e).all(-1) & (X >= 1 / e).all(-1)

        def score(img):
            s = metrics(img, ref, e)
            if KEY == "guided":
                return [s[0] / base[0][0], s[1] / base[1][1], s[2] / base[0][2], s[3] / base[0][3]]
            low = np.minimum(*base)
            return [s[0] / low[0], s[1] / base[1][1], s[2] / low[2], s[3] / low[3]]

        scores["shipped without halves"].append(score(G))
        for a in BLENDS:
            scores.setdefault(f"{a} of the way to the mean, everywhere", []).append(score(G + a * (X - G)))
        for name, only_white, estimate, r, z in VARIANTS:
            decided = ~bad & (white if only_white else True)
            d = np.where(decided, delta[estimate], 0.0)
            total = box(d, r)
            if z is None:
                pick = decided & (total > 0)
            else:
                n = box(decided.astype(float), r)
                sd = np.sqrt(np.maximum(box(d * d, r) - total ** 2 / np.maximum(n, 1), 0)
                             * n / np.maximum(n - 1, 1))
                pick = decided & (total > z * sd)
            scores[name].append(score(np.where(pick[..., None], X, G)))
        print(f"{scene} {m.group(2)}", file=sys.stderr)
    target = [1.0, 1.25 if KEY == "guided" else 1.05, 1.0, 1.0]
    print(f"{KEY}: at the targets (RMS, RMS_display, FLIP, HDR-FLIP) and geometric means")
    for name, rows in scores.items():
        r = np.array(rows)
        at = [int((r[:, i] <= target[i] + 1e-12).sum()) for i in range(4)]
        geo = np.exp(np.log(r).mean(0))
        print(f"  {name:52s} {at} of {len(r)}   {' '.join(f'{g:.3f}' for g in geo)}")


if __name__ == "__main__":
    main(sys.argv[1] if len(sys.argv) > 1 else "out/fid")
