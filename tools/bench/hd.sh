#!/usr/bin/env bash
# A production frame: a synthetic 1920 × 1080 × 64-spp pass-major dump
# (132.7 M samples, 3.2 GB; made once at DUMP, default out/hd/hd.pds; any
# existing dump at DUMP is used as it is), then
# ROUNDS (default 2) rounds of, in turn, the bare run (`--no-html --methods
# mean`), the default images without the report (`--no-html`), the default
# run (its images and the report), the default run without the held-out
# halves (`--held-out false`: the recommended image made once) and every
# image (`--methods all`, the comparison), 2 threads. Prints each run's wall seconds, report.json's phases
# and peak anonymous memory apart from the mapped dump (tools/bench/peak_rss.sh),
# then each median over the bare run's.
#
#   bash tools/bench/hd.sh
set -euo pipefail
cd "$(dirname "$0")/../.."
dump=${DUMP:-out/hd/hd.pds}
rounds=${ROUNDS:-2}
cargo build --release --quiet --bin pathdensity
pd=target/release/pathdensity
mkdir -p "$(dirname "$dump")"
[ -f "$dump" ] || $pd synth -o "$dump" --width 1920 --height 1080 --spp 64 --order pass >/dev/null
tmp=$(mktemp -d)
trap 'rm -rf "$tmp"' EXIT
declare -A args=([bare]="--no-html --methods mean" [nohtml]="--no-html" [default]=""
    [once]="--held-out false" [all]="--methods all")
for r in $(seq "$rounds"); do
    for run in bare nohtml default once all; do
        start=$(date +%s.%N)
        # shellcheck disable=SC2086
        mem=$(bash tools/bench/peak_rss.sh $pd filter "$dump" -o "$tmp/$run" --threads 2 ${args[$run]})
        wall=$(awk -v a="$start" -v b="$(date +%s.%N)" 'BEGIN { printf "%.3f", b - a }')
        phases=$(python3 -c "import json,sys; r=json.load(open(sys.argv[1])); t=r['timing']; \
print('%d streaming %.2f final %.2f reconstruct %.2f' % (r['counts']['records'], t['streaming_seconds'], t['final_pass_seconds'], t['reconstruct_seconds']))" "$tmp/$run/report.json")
        echo "$run $wall $phases $mem" | tee -a "$tmp/log"
    done
done
python3 - "$tmp/log" <<'PY'
import statistics, sys
walls, records = {}, 0
for line in open(sys.argv[1]):
    f = line.split()
    walls.setdefault(f[0], []).append(float(f[1]))
    records = int(f[2])
bare = statistics.median(walls["bare"])
for run, w in walls.items():
    m = statistics.median(w)
    print(f"{run:8} median {m:7.2f} s  {m / bare:.2f}x bare  {records / m / 1e6:.2f} M samples/s")
PY
