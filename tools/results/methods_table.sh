#!/usr/bin/env bash
# Every method on every scene: each still scene rendered at
# SIZE² (default 128) and SPPS (default "16 64") spp with a REF_SPP (default
# 1024) reference, the moving scene at 4 frames; `filter` with every method.
# Writes OUT/methods.csv (default out/methods) and prints, per scene and
# spp, the winner on RMS, RMS_display, relMSE and energy (closest to 1),
# and a markdown table of every method.
set -euo pipefail
cd "$(dirname "$0")/../.."
threads=${THREADS:-2}
size=${SIZE:-128}
spps=${SPPS:-"16 64"}
ref_spp=${REF_SPP:-1024}
scenes=${SCENES:-"glossy-room diffuse-room two-lights indirect-room sky moving"}
out=${OUT:-out/methods}
cargo build --release --quiet
mkdir -p "$out"
csv="$out/methods.csv"
echo "scene,spp,method,rms,rms_display,rel_mse,energy,seconds" > "$csv"
for s in $scenes; do
    frames=()
    [ "$s" = moving ] && frames=(--frames 4)
    for spp in $spps; do
        d="$out/$s-$spp"
        mkdir -p "$d"
        ref="$out/$s-ref.exr"
        refargs=()
        [ -f "${ref%.exr}.done" ] || refargs=(--reference-spp "$ref_spp" --reference-out "$ref")
        ./target/release/render --scene "$s" --width "$size" --height "$size" --spp "$spp" \
            "${frames[@]}" --threads "$threads" -o "$d/dump.pds" "${refargs[@]}" > /dev/null
        touch "${ref%.exr}.done"
        ./target/release/pathdensity filter "$d/dump.pds" -o "$d" --reference "$ref" \
            --no-html --methods all --threads "$threads" > /dev/null
        rm "$d/dump.pds"
        python3 - "$d/report.json" "$s" "$spp" >> "$csv" <<'PY'
import json, sys
r = json.load(open(sys.argv[1]))
for m, x in r["metrics"].items():
    print(f"{sys.argv[2]},{sys.argv[3]},{m},{x['rms']},{x['rms_display']},{x['rel_mse']},{x['energy_ratio']},{r['method_seconds'][m]}")
PY
        echo "$s $spp spp done" >&2
    done
done
python3 - "$csv" <<'PY'
import csv, sys
from collections import defaultdict
rows = list(csv.DictReader(open(sys.argv[1])))
by = defaultdict(list)
for r in rows:
    by[(r["scene"], r["spp"])].append(r)
print("| scene | spp | best RMS | best RMS_display | best relMSE | energy closest to 1 (excl. mean) |")
print("|---|---:|---|---|---|---|")
for (s, spp), rs in by.items():
    best = lambda f: min(rs, key=lambda r: float(r[f]))
    e = min((r for r in rs if r["method"] != "mean"), key=lambda r: abs(float(r["energy"]) - 1))
    print(f"| {s} | {spp} | {best('rms')['method']} {float(best('rms')['rms']):.4f} "
          f"| {best('rms_display')['method']} {float(best('rms_display')['rms_display']):.4f} "
          f"| {best('rel_mse')['method']} {float(best('rel_mse')['rel_mse']):.4f} "
          f"| {e['method']} {float(e['energy']):.3f} |")
print()
methods = list(dict.fromkeys(r["method"] for r in rows))
print("| scene | spp | " + " | ".join(methods) + " |")
print("|---|---:|" + "---:|" * len(methods))
for (s, spp), rs in by.items():
    m = {r["method"]: r for r in rs}
    print(f"| {s} | {spp} | " + " | ".join(
        f"{float(m[k]['rms']):.3f} / {float(m[k]['rms_display']):.3f} / {float(m[k]['energy']):.2f}" for k in methods) + " |")
PY
