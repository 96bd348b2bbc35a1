#!/usr/bin/env bash
# Same-period A/B of two pathdensity binaries over several dumps and k:
# the bare replay (`filter --no-html --methods mean`, plus EXTRA flags),
# each side in turn, RUNS rounds; checks that both write the same decision
# bytes and prints, per dump and k, the median new/old ratio of the
# streaming pass, the final pass and the whole process, and old's seconds.
#
#   EXTRA="--color-space cielab" tools/bench/ab_dumps.sh OLD_BIN NEW_BIN RUNS "K…" DUMP…
set -euo pipefail
[ $# -ge 5 ] || { echo "usage: $0 OLD_BIN NEW_BIN RUNS \"K…\" DUMP…" >&2; exit 2; }
old=$1 new=$2 runs=$3 ks=$4
shift 4
out=$(mktemp -d)
trap 'rm -rf "$out"' EXIT
for dump in "$@"; do
  for k in $ks; do
    for i in $(seq "$runs"); do
      for side in old new; do
        bin=$old; [ "$side" = new ] && bin=$new
        s=$(date +%s.%N)
        # shellcheck disable=SC2086
        "$bin" filter "$dump" -o "$out/$side" --k "$k" --no-html --methods mean \
          --decisions "$out/$side.dec" ${EXTRA:-} >/dev/null
        e=$(date +%s.%N)
        t=$(python3 -c "import json; t = json.load(open('$out/$side/report.json'))['timing']; print(t['streaming_seconds'], t['final_pass_seconds'])")
        echo "$dump $k $side $(echo "$e - $s" | bc) $t"
      done
      cmp -s "$out/old.dec" "$out/new.dec" || { echo "decisions differ: $dump k = $k" >&2; exit 1; }
    done
  done
done | python3 -c "
import sys, statistics as st
v = {}
for line in sys.stdin:
    d, k, side, wall, s, f = line.split()
    v.setdefault((d, k), {}).setdefault(side, []).append((float(s), float(f), float(wall)))
print('dump k: new/old median ratio of streaming, final pass, process (old process s)')
for (d, k), x in v.items():
    m = lambda side, i: st.median(r[i] for r in x[side])
    print(f'{d} {k}: %.2f %.2f %.2f (%.2f s)' % tuple([m('new', i) / m('old', i) for i in range(3)] + [m('old', 2)]))
"
