#!/usr/bin/env bash
# Same-period A/B of two pathdensity runs: `filter --no-html` with each
# side in turn (interleaved, so machine drift hits both alike); prints the
# median replay time (streaming + final pass, from report.json) and the
# ratio old/new.
#
#   tools/bench/ab_filter.sh OLD_BIN NEW_BIN DUMP K THREADS RUNS
#
# THREADS is one count for both sides; or OLD,NEW: the same binary twice
# with 1,2 gives its 1 → 2 thread scaling; or A+B: each binary on A and on
# B threads, four contenders in rotation, and each binary's scaling A → B.
set -euo pipefail
[ $# -eq 6 ] || { echo "usage: $0 OLD_BIN NEW_BIN DUMP K THREADS|OLD,NEW|A+B RUNS" >&2; exit 2; }
old=$1 new=$2 dump=$3 k=$4 threads=$5 runs=$6
case $threads in
  *+*) a=${threads%+*} b=${threads#*+}
       contenders=("old $old $a" "old@$b $old $b" "new $new $a" "new@$b $new $b") ;;
  *,*) contenders=("old $old ${threads%,*}" "new $new ${threads#*,}") ;;
  *)   contenders=("old $old $threads" "new $new $threads") ;;
esac
out=$(mktemp -d)
trap 'rm -rf "$out"' EXIT
# One uncounted run of each side first: right after a build the dump may
# have to be read back from disk.
for bin in "$old" "$new"; do
  "$bin" filter "$dump" -o "$out/warm" --k "$k" --threads 1 --no-html >/dev/null
done
n=${#contenders[@]}
for i in $(seq "$runs"); do
  # Rotate which contender goes first, so none always follows another.
  for j in $(seq 0 $((n - 1))); do
    read -r label bin t <<<"${contenders[$(((i + j) % n))]}"
    "$bin" filter "$dump" -o "$out/run" --k "$k" --threads "$t" --no-html >/dev/null
    python3 -c "import json,sys; t=json.load(open(sys.argv[1]))['timing']; print(sys.argv[2], t['streaming_seconds'] + t['final_pass_seconds'])" "$out/run/report.json" "$label"
  done
done | python3 -c "
import sys, statistics
d = {}
for line in sys.stdin:
    label, v = line.split()
    d.setdefault(label, []).append(float(v))
m = {label: statistics.median(v) for label, v in d.items()}
runs = len(d['new'])
k, threads = sys.argv[1], sys.argv[2]
if '+' in threads:
    a, b = threads.split('+')
    for side in ('old', 'new'):
        s, f = m[side], m[side + '@' + b]
        print(f'k={k} {side}: {a} thread(s) {s:.3f} s, {b} threads {f:.3f} s, {a} -> {b}: {s / f:.2f}x ({runs} runs each)')
else:
    o, n = m['old'], m['new']
    print(f'k={k} threads={threads}: old {o:.3f} s, new {n:.3f} s, old/new {o / n:.2f}x ({runs} runs each)')
" "$k" "$threads"
