#!/usr/bin/env bash
# The paper's Table 1 on our scenes: three scenes at three sample counts
# growing ×4 (W × H at SPPS, default 256 × 256 at 16 64 256), pixel-major,
# THREADS threads (default 2). For each: render time, then the filter
# (mean + filtered only, no report) at k = 10, 50, 200: filter time,
# render + filter time, stored samples |T|. Writes OUT/table1.csv (default
# out/table1) and prints the markdown table and the fitted exponents
# (tools/bench/table1_fit.py).
set -euo pipefail
cd "$(dirname "$0")/../.."
threads=${THREADS:-2}
size=${SIZE:-256}
spps=${SPPS:-"16 64 256"}
scenes=${SCENES:-"glossy-room indirect-room sky"}
out=${OUT:-out/table1}
cargo build --release --quiet
mkdir -p "$out"
tmp=$(mktemp -d)
trap 'rm -rf "$tmp"' EXIT
csv="$out/table1.csv"
echo "scene,spp,samples,render_seconds,k,filter_seconds,stored" > "$csv"
for s in $scenes; do
    for spp in $spps; do
        line=$(./target/release/render --scene "$s" --width "$size" --height "$size" \
            --spp "$spp" --threads "$threads" -o "$tmp/d.pds")
        count=$(sed -E 's/.*, ([0-9]+) samples in.*/\1/' <<<"$line")
        rsecs=$(sed -E 's/.* in ([0-9.]+) s .*/\1/' <<<"$line")
        for k in 10 50 200; do
            ./target/release/pathdensity filter "$tmp/d.pds" -o "$tmp/f" --k "$k" \
                --methods mean,filtered --no-html --threads "$threads" > /dev/null
            fsecs=$(python3 -c 'import json,sys; print(json.load(open(sys.argv[1]))["timing"]["total_seconds"])' "$tmp/f/report.json")
            stored=$(python3 -c 'import json,sys; print(json.load(open(sys.argv[1]))["counts"]["stored"])' "$tmp/f/report.json")
            echo "$s,$spp,$count,$rsecs,$k,$fsecs,$stored" >> "$csv"
            echo "$s $spp spp k=$k: render $rsecs s, filter $fsecs s, |T| $stored" >&2
        done
    done
done
python3 tools/bench/table1_fit.py "$csv"
