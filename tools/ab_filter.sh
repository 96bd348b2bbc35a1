#!/usr/bin/env bash
# Same-period A/B of two pathdensity runs: `filter --no-html` with each
# side in turn (interleaved, so machine drift hits both alike); prints the
# median replay time (streaming + final pass, from report.json) and the
# ratio old/new.
#
#   tools/ab_filter.sh OLD_BIN NEW_BIN DUMP K THREADS RUNS
#
# THREADS is one count for both sides, or OLD,NEW: the same binary twice
# with THREADS 1,2 gives its 1 → 2 thread scaling.
set -euo pipefail
[ $# -eq 6 ] || { echo "usage: $0 OLD_BIN NEW_BIN DUMP K THREADS|OLD,NEW RUNS" >&2; exit 2; }
old=$1 new=$2 dump=$3 k=$4 threads=$5 runs=$6
t_old=${threads%,*} t_new=${threads#*,}
out=$(mktemp -d)
trap 'rm -rf "$out"' EXIT
# One uncounted run of each side first: right after a build the dump may
# have to be read back from disk.
for bin in "$old" "$new"; do
  "$bin" filter "$dump" -o "$out/warm" --k "$k" --threads 1 --no-html >/dev/null
done
for i in $(seq "$runs"); do
  # Alternate which side goes first, so neither always follows the other.
  order="old new"; [ $((i % 2)) -eq 0 ] && order="new old"
  for side in $order; do
    bin=$old t=$t_old
    [ "$side" = new ] && bin=$new t=$t_new
    "$bin" filter "$dump" -o "$out/$side" --k "$k" --threads "$t" --no-html >/dev/null
    python3 -c "import json,sys; t=json.load(open(sys.argv[1]))['timing']; print(sys.argv[2], t['streaming_seconds'] + t['final_pass_seconds'])" "$out/$side/report.json" "$side"
  done
done | python3 -c "
import sys, statistics
d = {'old': [], 'new': []}
for line in sys.stdin:
    side, v = line.split()
    d[side].append(float(v))
o, n = statistics.median(d['old']), statistics.median(d['new'])
print(f'k={sys.argv[1]} threads={sys.argv[2]}: old {o:.3f} s, new {n:.3f} s, old/new {o / n:.2f}x ({len(d[\"new\"])} runs each)')
" "$k" "$threads"
