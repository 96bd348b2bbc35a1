#!/usr/bin/env python3
"""Same-period A/B of two pathdensity binaries: the contenders run in turn,
the first of each round rotating so that none always follows another and
machine drift hits all alike; medians of each, and the ratios to old's.

    ab.py replay  OLD NEW [--runs R] [--k "5 10"] [--extra "--color-space cielab"] DUMP…
        the bare replay (`filter --no-html --methods mean`): streaming, final
        pass and whole process, new / old; the decision bytes must be equal.
    ab.py default OLD NEW [--runs R] [--k "5"] [--skip "sigma*.png"] DUMP…
        the run users make (every default image and the report) beside new's
        bare replay; every EXR and PNG old writes, new must write the same
        (patterns in --skip excepted); new / old and new / bare.
    ab.py threads OLD NEW --threads 2|1,2|1+2 [--runs R] [--k "5"] DUMP…
        replay seconds (streaming + final pass) at one thread count for
        both, OLD's count,NEW's count, or each binary at A and at B threads
        (its scaling A → B).
"""
import argparse, fnmatch, json, os, shlex, statistics, subprocess, sys, tempfile, time


def run(binary, dump, out, k, threads, args):
    cmd = [binary, "filter", dump, "-o", out, "--k", str(k), *args]
    if threads is not None:
        cmd += ["--threads", str(threads)]
    start = time.monotonic()
    subprocess.run(cmd, check=True, stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
    wall = time.monotonic() - start
    t = json.load(open(os.path.join(out, "report.json")))["timing"]
    return {"process": wall, "streaming": t["streaming_seconds"], "final": t["final_pass_seconds"],
            "replay": t["streaming_seconds"] + t["final_pass_seconds"]}


def same_images(a, b, skip):
    for name in sorted(os.listdir(a)):
        if not name.endswith((".exr", ".png")) or any(fnmatch.fnmatch(name, p) for p in skip):
            continue
        with open(os.path.join(a, name), "rb") as x, open(os.path.join(b, name), "rb") as y:
            if x.read() != y.read():
                return name
    return None


def main():
    p = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    p.add_argument("mode", choices=("replay", "default", "threads"))
    p.add_argument("old")
    p.add_argument("new")
    p.add_argument("dumps", nargs="+")
    p.add_argument("--runs", type=int, default=5)
    p.add_argument("--k", default="5", help="values of k, space-separated")
    p.add_argument("--extra", default="", help="more filter flags for every contender")
    p.add_argument("--skip", default="", help="file patterns `default` does not compare")
    p.add_argument("--threads", default=None)
    a = p.parse_args()
    extra = shlex.split(a.extra)
    bare = ["--no-html", "--methods", "mean", *extra]
    # (label, binary, flags, threads)
    if a.mode == "replay":
        sides = [("old", a.old, bare + ["--decisions", "DEC"], None),
                 ("new", a.new, bare + ["--decisions", "DEC"], None)]
    elif a.mode == "default":
        sides = [("old", a.old, extra, None), ("new", a.new, extra, None), ("bare", a.new, bare, None)]
    else:
        t = a.threads or "2"
        if "+" in t:
            x, y = t.split("+")
            sides = [("old", a.old, ["--no-html"], x), (f"old@{y}", a.old, ["--no-html"], y),
                     ("new", a.new, ["--no-html"], x), (f"new@{y}", a.new, ["--no-html"], y)]
        else:
            x, y = t.split(",") if "," in t else (t, t)
            sides = [("old", a.old, ["--no-html"], x), ("new", a.new, ["--no-html"], y)]
    with tempfile.TemporaryDirectory() as tmp:
        for dump in a.dumps:
            for k in a.k.split():
                times = {label: [] for label, *_ in sides}
                # One uncounted run each: the dump may have to be read from disk.
                for label, binary, flags, threads in sides:
                    run(binary, dump, os.path.join(tmp, label), k, threads,
                        [f.replace("DEC", os.path.join(tmp, label + ".dec")) for f in flags])
                for i in range(a.runs):
                    for j in range(len(sides)):
                        label, binary, flags, threads = sides[(i + j) % len(sides)]
                        flags = [f.replace("DEC", os.path.join(tmp, label + ".dec")) for f in flags]
                        times[label].append(run(binary, dump, os.path.join(tmp, label), k, threads, flags))
                    if a.mode == "replay":
                        dec = [open(os.path.join(tmp, s + ".dec"), "rb").read() for s in ("old", "new")]
                        if dec[0] != dec[1]:
                            sys.exit(f"decisions differ: {dump}, k = {k}")
                    if a.mode == "default":
                        differs = same_images(os.path.join(tmp, "old"), os.path.join(tmp, "new"), a.skip.split())
                        if differs:
                            sys.exit(f"differs: {differs} ({dump}, k = {k})")
                med = lambda label, key: statistics.median(r[key] for r in times[label])
                name = os.path.basename(dump)
                if a.mode == "replay":
                    r = [med("new", key) / med("old", key) for key in ("streaming", "final", "process")]
                    print(f"{name} k={k}: new/old streaming {r[0]:.2f}, final pass {r[1]:.2f}, "
                          f"process {r[2]:.2f} (old process {med('old', 'process'):.2f} s, {a.runs} runs)")
                elif a.mode == "default":
                    o, n, b = (med(s, "process") for s in ("old", "new", "bare"))
                    print(f"{name} k={k}: old default {o:.3f} s, new default {n:.3f} s, new/old {n / o:.2f}; "
                          f"bare {b:.3f} s, new default/bare {n / b:.2f} ({a.runs} runs)")
                else:
                    for label in times:
                        print(f"{name} k={k} {label} ({dict((s[0], s[3]) for s in sides)[label]} threads): "
                              f"replay {med(label, 'replay'):.3f} s")
                    if len(sides) == 2:
                        print(f"  old/new {med('old', 'replay') / med('new', 'replay'):.2f}x")
                    else:
                        for side in ("old", "new"):
                            print(f"  {side} scaling: {med(side, 'replay') / med(side + '@' + y, 'replay'):.2f}x")


if __name__ == "__main__":
    main()
