"""Table 1 of the paper on our scenes, from tools/bench/table1.sh's CSV.

Prints a markdown table (render time, filter time, filter overhead over
render time, stored samples per million samples) and least-squares fits:
  time  ~ N^a   at each k       (paper: near-linear in samples)
  |T|   ~ N^b   at each k, and |T| = c + d·ln N  (paper: roughly logarithmic)
  time  ~ k^e, |T| ~ k^f at the largest N (paper: sublinear / near-linear in k)
"""
import csv
import sys
from collections import defaultdict

import numpy as np

rows = list(csv.DictReader(open(sys.argv[1])))
for r in rows:
    for f in ("spp", "samples", "k", "stored"):
        r[f] = int(r[f])
    for f in ("render_seconds", "filter_seconds"):
        r[f] = float(r[f])

print("| scene | samples | render s | k | filter s | render + filter s | overhead | stored |T| | |T| per M samples |")
print("|---|---:|---:|---:|---:|---:|---:|---:|---:|")
for r in rows:
    print(
        f"| {r['scene']} | {r['samples']:,} | {r['render_seconds']:.2f} | {r['k']} "
        f"| {r['filter_seconds']:.2f} | {r['render_seconds'] + r['filter_seconds']:.2f} "
        f"| {100 * r['filter_seconds'] / r['render_seconds']:.0f}% | {r['stored']:,} "
        f"| {r['stored'] / (r['samples'] / 1e6):,.0f} |"
    )


def slope(x, y):
    return np.polyfit(np.log(x), np.log(y), 1)[0]


by = defaultdict(list)
for r in rows:
    by[(r["scene"], r["k"])].append(r)
print()
print("| scene | k | time ~ N^a: a | render ~ N^a: a | |T| ~ N^b: b | |T| = c + d ln N: d (per ×4 N) |")
print("|---|---:|---:|---:|---:|---:|")
for (scene, k), rs in sorted(by.items()):
    n = [r["samples"] for r in rs]
    t = [r["filter_seconds"] for r in rs]
    rt = [r["render_seconds"] for r in rs]
    st = [r["stored"] for r in rs]
    d = np.polyfit(np.log(n), st, 1)[0] * np.log(4)
    print(f"| {scene} | {k} | {slope(n, t):.2f} | {slope(n, rt):.2f} | {slope(n, st):.2f} | {d:,.0f} |")

top = max(r["samples"] for r in rows)
print()
print(f"At N = {top:,}:")
print("| scene | time ~ k^e: e | |T| ~ k^f: f |")
print("|---|---:|---:|")
for scene in dict.fromkeys(r["scene"] for r in rows):
    rs = [r for r in rows if r["scene"] == scene and r["samples"] == top]
    ks = [r["k"] for r in rs]
    print(
        f"| {scene} | {slope(ks, [r['filter_seconds'] for r in rs]):.2f} "
        f"| {slope(ks, [r['stored'] for r in rs]):.2f} |"
    )
