#!/usr/bin/env bash
# Same-period A/B of two pathdensity binaries on the run users make (the
# default `filter`: every image, the report and its σ map) over several
# dumps and k, with the new binary's bare replay (`--no-html --methods
# mean`) beside it; each of the three in turn, RUNS rounds. Checks that
# both binaries write the same images (every EXR and PNG) and prints, per
# dump and k, the medians of whole-process wall seconds, new / old and the
# new default run against the bare one. SKIP lists file patterns not
# compared (a change meant to alter them).
#
#   SKIP="sigma*.png" tools/bench/ab_default.sh OLD_BIN NEW_BIN RUNS "K…" DUMP…
set -euo pipefail
[ $# -ge 5 ] || { echo "usage: $0 OLD_BIN NEW_BIN RUNS \"K…\" DUMP…" >&2; exit 2; }
old=$1 new=$2 runs=$3 ks=$4
shift 4
out=$(mktemp -d)
trap 'rm -rf "$out"' EXIT
wall() { local s e; s=$(date +%s.%N); "$@" >/dev/null 2>&1; e=$(date +%s.%N); echo "$e - $s" | bc; }
for dump in "$@"; do
  for k in $ks; do
    for i in $(seq "$runs"); do
      echo "$dump $k old $(wall "$old" filter "$dump" -o "$out/old" --k "$k")"
      echo "$dump $k new $(wall "$new" filter "$dump" -o "$out/new" --k "$k")"
      echo "$dump $k bare $(wall "$new" filter "$dump" -o "$out/bare" --k "$k" --no-html --methods mean)"
      for f in "$out"/old/*.exr "$out"/old/*.png; do
        skip=0
        for pat in ${SKIP:-}; do
          # shellcheck disable=SC2053
          [[ $(basename "$f") == $pat ]] && skip=1
        done
        [ $skip = 1 ] && continue
        cmp -s "$f" "$out/new/$(basename "$f")" || { echo "differs: $(basename "$f") ($dump, k = $k)" >&2; exit 1; }
      done
    done
  done
done | python3 -c "
import sys, os, statistics as st
v = {}
for line in sys.stdin:
    dump, k, side, t = line.split()
    v.setdefault((dump, k), {}).setdefault(side, []).append(float(t))
print('| dump | k | old default | new default | new / old | bare | new default / bare |')
print('|---|---|---|---|---|---|---|')
for (dump, k), s in v.items():
    m = {n: st.median(x) for n, x in s.items()}
    print(f'| {os.path.basename(dump)} | {k} | {m[\"old\"]:.3f} | {m[\"new\"]:.3f} | {m[\"new\"] / m[\"old\"]:.2f} | {m[\"bare\"]:.3f} | {m[\"new\"] / m[\"bare\"]:.2f} |')
"
