#!/usr/bin/env python3
"""The default run against the bare replay on small dumps, where
tools/bench/hd.sh's memory sampling would blur the wall time: per dump,
R rounds (default 5) of, in turn, the bare run (`--no-html --methods
mean`), the default images without the report (`--no-html`), the default
run and every image (`--methods all`), the first of each round rotating;
whole-process wall seconds, medians, and each over the bare run's.

    python3 tools/bench/default_set.py [--bin target/release/pathdensity] [--runs 5] DUMP…
"""
import argparse, os, statistics, subprocess, sys, tempfile, time

RUNS = {
    "bare": ["--no-html", "--methods", "mean"],
    "nohtml": ["--no-html"],
    "default": [],
    "all": ["--methods", "all"],
}

p = argparse.ArgumentParser()
p.add_argument("--bin", default="target/release/pathdensity")
p.add_argument("--runs", type=int, default=5)
p.add_argument("dumps", nargs="+")
a = p.parse_args()

names = list(RUNS)
print("| dump | " + " | ".join(f"{n} s" for n in names) + " | "
      + " | ".join(f"{n} / bare" for n in names[1:]) + " |")
print("|---" * (2 * len(names)) + "|")
ratios = {n: [] for n in names[1:]}
with tempfile.TemporaryDirectory() as tmp:
    for dump in a.dumps:
        walls = {n: [] for n in names}
        for r in range(a.runs):
            for n in names[r % len(names):] + names[:r % len(names)]:
                out = os.path.join(tmp, n)
                start = time.monotonic()
                subprocess.run([a.bin, "filter", dump, "-o", out, "--threads", "2", *RUNS[n]],
                               check=True, stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
                walls[n].append(time.monotonic() - start)
        med = {n: statistics.median(w) for n, w in walls.items()}
        for n in names[1:]:
            ratios[n].append(med[n] / med["bare"])
        print(f"| {os.path.basename(dump)} | " + " | ".join(f"{med[n]:.3f}" for n in names) + " | "
              + " | ".join(f"{med[n] / med['bare']:.2f}" for n in names[1:]) + " |", flush=True)
print("| **geo. mean** | " + " | " * len(names) + " | ".join(
    f"{statistics.geometric_mean(ratios[n]):.2f}" for n in names[1:]) + " |")
