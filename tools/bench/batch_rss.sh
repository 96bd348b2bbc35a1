#!/usr/bin/env bash
# Peak memory of `pathdensity batch` over 1, 10 and 100 dumps of the same
# size (docs/BENCHMARKS.md, "Batch"): it must not grow with the number of
# dumps.
#
#   bash tools/bench/batch_rss.sh [WORKDIR]    (PATHDENSITY: the binary, target/release/pathdensity by default)
set -euo pipefail
cd "$(dirname "$0")/../.."
bin=${PATHDENSITY:-target/release/pathdensity}
work=${1:-/tmp/batch_rss}
rm -rf "$work" && mkdir -p "$work/shots"
for i in $(seq 1 100); do
  "$bin" synth -o "$work/shots/s$(printf %03d "$i").pds" --width 128 --height 128 --spp 16 --seed "$i" >/dev/null
done
for n in 1 10 100; do
  rm -rf "$work/out$n"
  list=$(ls "$work"/shots/*.pds | head -n "$n")
  start=$(date +%s.%N)
  # shellcheck disable=SC2086
  rss=$(bash tools/bench/peak_rss.sh "$bin" batch $list -o "$work/out$n")
  end=$(date +%s.%N)
  echo "$n dumps ($(du -sh --apparent-size "$work/shots" | cut -f1) of 100 on disk): $rss, $(echo "$end - $start" | bc) s"
done
