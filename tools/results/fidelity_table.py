#!/usr/bin/env python3
"""The recommended images against the mean and OIDN on every dump of a
folder made by tools/results/dumps.sh: for each RENDERER-SCENE-SPP.pds (its
reference RENDERER-SCENE-ref.exr beside it), `filter` with METHODS and
the reference, and a table per metric of each method's score relative to
the mean's and to OIDN's (lower is better), with the worst and the
geometric mean over the dumps.

    python3 tools/results/fidelity_table.py DUMPS [--bin target/release/pathdensity]
        [--methods a,b,…] [--extra "--guide-z 2"] [--csv OUT.csv]
"""
import argparse, csv, glob, json, math, os, re, subprocess, sys, tempfile

p = argparse.ArgumentParser()
p.add_argument("dumps")
p.add_argument("--bin", default="target/release/pathdensity",
               help="OIDN is found as README's \"OIDN\" says: eval \"$(bash tools/oidn/setup.sh)\" first")
p.add_argument("--methods", default="filtered,filtered_energy,filtered_energy_bilateral_ci,oidn,oidn_ci,guided,guided_oidn")
p.add_argument("--extra", default="")
p.add_argument("--csv")
p.add_argument("--threads", default="2")
p.add_argument("--aux", action="store_true",
               help="give OIDN and statmc the dump's RENDERER-SCENE-albedo.exr and -normal.exr where they exist "
                    "(OIDN prefilters them: filter's default --aux-prefilter accurate; --extra to change it)")
a = p.parse_args()

rows = []
with tempfile.TemporaryDirectory() as tmp:
    for dump in sorted(glob.glob(os.path.join(a.dumps, "*.pds"))):
        m = re.match(r"(.+)-(\d+)\.pds$", os.path.basename(dump))
        if not m:
            continue
        scene, spp = m.group(1), int(m.group(2))
        ref = os.path.join(a.dumps, f"{scene}-ref.exr")
        if not os.path.exists(ref):
            print(f"{dump}: no {ref}, left out", file=sys.stderr)
            continue
        out = os.path.join(tmp, "out")
        aux = []
        albedo, normal = (os.path.join(a.dumps, f"{scene}-{n}.exr") for n in ("albedo", "normal"))
        if a.aux and os.path.exists(albedo) and os.path.exists(normal):
            aux = ["--albedo", albedo, "--normal", normal]
        subprocess.run([a.bin, "filter", dump, "-o", out, "--reference", ref, "--methods", a.methods,
                        "--no-html", "--threads", a.threads, *aux, *a.extra.split()],
                       check=True, stdout=subprocess.DEVNULL)
        r = json.load(open(os.path.join(out, "report.json")))
        for name, x in r["metrics"].items():
            rows.append(dict(scene=scene, spp=spp, method=name, rms=x["rms"], rms_display=x["rms_display"],
                             flip=x["flip"], hdr_flip=x["hdr_flip"], energy=x["energy_ratio"],
                             seconds=r["method_seconds"][name]))
        print(f"{scene} {spp}", file=sys.stderr)

if a.csv:
    with open(a.csv, "w", newline="") as f:
        w = csv.DictWriter(f, fieldnames=list(rows[0]))
        w.writeheader()
        w.writerows(rows)

by = {}
for r in rows:
    by.setdefault((r["scene"], r["spp"]), {})[r["method"]] = r
methods = list(dict.fromkeys(r["method"] for r in rows))
dumps = sorted(by, key=lambda k: (k[1], k[0]))
g = lambda v: math.exp(sum(map(math.log, v)) / len(v)) if v else float("nan")
for metric in ("rms", "rms_display", "flip", "hdr_flip"):
    for base in ("mean", "oidn"):
        if base not in methods:
            continue
        print(f"\n### {metric} / {base}'s (lower is better)\n")
        print("| dump | " + " | ".join(x for x in methods if x != base) + " |")
        print("|---|" + "---|" * (len(methods) - 1))
        ratios = {x: [] for x in methods}
        for k in dumps:
            b = by[k]
            cells = []
            for x in methods:
                if x == base:
                    continue
                v = b[x][metric] / b[base][metric] if b[base][metric] > 0 else float("nan")
                ratios[x].append(v)
                cells.append(f"{v:.3f}")
            print(f"| {k[0]} {k[1]} | " + " | ".join(cells) + " |")
        print("| **worst** | " + " | ".join(f"{max(ratios[x]):.3f}" for x in methods if x != base) + " |")
        print("| **geo. mean** | " + " | ".join(f"{g(ratios[x]):.3f}" for x in methods if x != base) + " |")
print("\n### energy (image / reference)\n")
print("| dump | " + " | ".join(methods) + " |")
print("|---|" + "---|" * len(methods))
for k in dumps:
    print(f"| {k[0]} {k[1]} | " + " | ".join(f"{by[k][x]['energy']:.3f}" for x in methods) + " |")
