#!/usr/bin/env bash
# OIDN and clamping against the filter, on every scene of our
# renderer and the Mitsuba exporter's scenes, at SPPS (default "16 64") spp,
# SIZE² (default 128) pixels: mean, filtered, filtered_energy, clamp at each
# of CLAMPS (default "3 10 30"), oidn, the two recommended images
# (oidn_ci, filtered_energy_bilateral_ci), and METHOD+oidn for each. Needs the
# OIDN library (bash tools/oidn/setup.sh; this script sets OIDN_DIR) and
# Mitsuba (bash tools/mitsuba/setup.sh). Writes OUT/oidn.csv (default
# out/oidn) and prints a markdown table per spp.
set -euo pipefail
cd "$(dirname "$0")/../.."
threads=${THREADS:-2}
size=${SIZE:-128}
spps=${SPPS:-"16 64"}
clamps=${CLAMPS:-"3 10 30"}
ours=${SCENES:-"glossy-room diffuse-room two-lights indirect-room sky moving"}
theirs=${MITSUBA_SCENES:-"caustic glossy-highlight indirect-room"}
ref_spp=${REF_SPP:-1024}
mi_ref_spp=${MI_REF_SPP:-4096}
out=${OUT:-out/oidn}
eval "$(bash tools/oidn/setup.sh)"
cargo build --release --quiet --bin render
cargo build --release --quiet --bin pathdensity
pd=target/release/pathdensity
py=tools/mitsuba/.venv/bin/python
mkdir -p "$out"
csv="$out/oidn.csv"
echo "renderer,scene,spp,method,rms,rms_display,energy,seconds" > "$csv"

measure() { # renderer scene spp dump ref
    local d="$out/$1-$2-$3"
    local first=1
    for c in $clamps; do
        mkdir -p "$d/c$c"
        local methods=clamp,oidn
        [ $first = 1 ] && methods=filtered_energy,filtered_energy_bilateral_ci,clamp,oidn,oidn_ci
        $pd filter "$4" -o "$d/c$c" --reference "$5" --methods "$methods" --denoise oidn \
            --clamp "$c" --no-html --threads "$threads" > /dev/null
        python3 - "$d/c$c/report.json" "$1" "$2" "$3" "$c" "$first" >> "$csv" <<'PY'
import json, sys
r = json.load(open(sys.argv[1]))
renderer, scene, spp, c, first = sys.argv[2:]
for m, x in r["metrics"].items():
    if m.startswith("clamp"):
        m = m.replace("clamp", f"clamp C={c}")
    elif first != "1":
        continue
    print(f"{renderer},{scene},{spp},{m},{x['rms']},{x['rms_display']},{x['energy_ratio']},{r['method_seconds'][m.replace(f'clamp C={c}', 'clamp')]}")
PY
        first=0
    done
}

for s in $ours; do
    frames=()
    [ "$s" = moving ] && frames=(--frames 4)
    for spp in $spps; do
        ref="$out/ours-$s-ref.exr"
        refargs=()
        [ -f "$out/ours-$s-ref.done" ] || refargs=(--reference-spp "$ref_spp" --reference-out "$ref")
        ./target/release/render --scene "$s" --width "$size" --height "$size" --spp "$spp" \
            "${frames[@]}" --order pass --threads "$threads" -o "$out/dump.pds" "${refargs[@]}" > /dev/null
        touch "$out/ours-$s-ref.done"
        measure ours "$s" "$spp" "$out/dump.pds" "$ref"
        echo "ours $s $spp spp done" >&2
    done
done
for s in $theirs; do
    for spp in $spps; do
        ref="$out/mitsuba-$s-ref.exr"
        refargs=()
        [ -f "$ref" ] || refargs=(--reference-spp "$mi_ref_spp" --reference-out "$ref")
        $py tools/mitsuba/export.py "tools/mitsuba/scenes/$s.xml" -o "$out/dump.pds" \
            --size "${size}x${size}" --spp "$spp" --seed 1 --quiet "${refargs[@]}"
        measure mitsuba "$s" "$spp" "$out/dump.pds" "$ref"
        echo "mitsuba $s $spp spp done" >&2
    done
done
rm -f "$out/dump.pds"
python3 - "$csv" <<'PY'
import csv, sys
from collections import defaultdict
rows = list(csv.DictReader(open(sys.argv[1])))
by = defaultdict(dict)
order = []
for r in rows:
    key = (r["renderer"], r["scene"], r["spp"])
    by[key][r["method"]] = r
    if r["method"] not in order:
        order.append(r["method"])
for spp in sorted({k[2] for k in by}, key=int):
    print(f"\n### {spp} spp: RMS / RMS_display (energy), each relative to the mean's RMS and RMS_display\n")
    keys = [k for k in by if k[2] == spp]
    print("| method | " + " | ".join(f"{k[0][0]}:{k[1]}" for k in keys) + " |")
    print("|---|" + "---|" * len(keys))
    for m in order:
        cells = []
        for k in keys:
            x, mean = by[k].get(m), by[k]["mean"]
            if x is None:
                cells.append("")
                continue
            r = float(x["rms"]) / float(mean["rms"])
            d = float(x["rms_display"]) / float(mean["rms_display"])
            cells.append(f"{r:.2f} / {d:.2f} ({float(x['energy']):.2f})")
        print(f"| {m} | " + " | ".join(cells) + " |")
    print("\n| scene | mean RMS | mean RMS_display | oidn s | filtered s | filtered+oidn s |")
    print("|---|---|---|---|---|---|")
    for k in keys:
        b = by[k]
        print(f"| {k[0]}:{k[1]} | {float(b['mean']['rms']):.4f} | {float(b['mean']['rms_display']):.4f} | "
              f"{float(b['oidn']['seconds']):.3f} | {float(b['filtered']['seconds']):.3f} | {float(b['filtered+oidn']['seconds']):.3f} |")
print("\n### The recommended images, linear RMS / RMS_display relative to the mean's (energy)\n")
print("| dump | oidn | oidn_ci | filtered_energy | filtered_energy_bilateral_ci | oidn_ci / oidn |")
print("|---|---|---|---|---|---|")
import math
g = lambda v: math.exp(sum(map(math.log, v)) / len(v))
ratios = defaultdict(lambda: ([], []))
for k in by:
    b = by[k]
    if "oidn_ci" not in b:
        continue
    q = lambda a, c, f: float(b[a][f]) / float(b[c][f])
    cells = []
    for m in ("oidn", "oidn_ci", "filtered_energy", "filtered_energy_bilateral_ci"):
        lin, disp = q(m, "mean", "rms"), q(m, "mean", "rms_display")
        ratios[m][0].append(lin); ratios[m][1].append(disp)
        cells.append(f"{lin:.2f} / {disp:.2f} ({float(b[m]['energy']):.3f})")
    lin, disp = q("oidn_ci", "oidn", "rms"), q("oidn_ci", "oidn", "rms_display")
    ratios["oidn_ci / oidn"][0].append(lin); ratios["oidn_ci / oidn"][1].append(disp)
    print(f"| {k[0]}:{k[1]} {k[2]} spp | " + " | ".join(cells) + f" | {lin:.3f} / {disp:.3f} |")
print()
for m, (lin, disp) in ratios.items():
    print(f"{m}: linear geometric mean {g(lin):.3f}, worst {max(lin):.3f}; "
          f"display geometric mean {g(disp):.3f}, worst {max(disp):.3f} ({len(lin)} dumps)")
PY
