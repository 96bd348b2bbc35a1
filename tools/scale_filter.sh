#!/usr/bin/env bash
# Same-period 1 → 2 thread scaling of one pathdensity build: runs
# `filter --no-html` on 1 and 2 threads in turn (interleaved, so machine
# drift hits both alike) and prints the median replay times (streaming +
# final pass, from report.json) and their ratio.
#
#   tools/scale_filter.sh BIN DUMP K RUNS
set -euo pipefail
[ $# -eq 4 ] || { echo "usage: $0 BIN DUMP K RUNS" >&2; exit 2; }
bin=$1 dump=$2 k=$3 runs=$4
out=$(mktemp -d)
trap 'rm -rf "$out"' EXIT
for _ in $(seq "$runs"); do
  for threads in 1 2; do
    "$bin" filter "$dump" -o "$out/o" --k "$k" --threads "$threads" --no-html >/dev/null
    python3 -c "import json,sys; t=json.load(open(sys.argv[1]))['timing']; print(sys.argv[2], t['streaming_seconds'] + t['final_pass_seconds'])" "$out/o/report.json" "$threads"
  done
done | python3 -c "
import sys, statistics
d = {'1': [], '2': []}
for line in sys.stdin:
    threads, v = line.split()
    d[threads].append(float(v))
a, b = statistics.median(d['1']), statistics.median(d['2'])
print(f'k={sys.argv[1]}: 1 thread {a:.3f} s, 2 threads {b:.3f} s, ratio {a / b:.2f}x ({len(d[\"2\"])} runs each)')
" "$k"
