#!/usr/bin/env bash
# The run users make against the bare replay and the render (
# docs/BENCHMARKS.md, "The default run"): on a Mitsuba 3 dump of
# glossy-highlight.xml at 128 × 128 × 64 spp (1,048,576 samples), for each
# k, RUNS interleaved rounds of
#   render   Mitsuba exporting the samples (tools/mitsuba/export.py)
#   bare     pathdensity filter --no-html --methods mean
#   default  pathdensity filter (the default images, report.html, σ map)
#   sigma    pathdensity filter --sigma-map (every sample's exact σ)
# whole-process wall seconds; prints min and median of each and the ratios.
#
#   bash tools/bench/default_run.sh [RUNS=5] [K…=5 10 50]
set -euo pipefail
cd "$(dirname "$0")/../.."
bin=${PATHDENSITY:-target/release/pathdensity}
py=tools/mitsuba/.venv/bin/python
runs=${1:-5}
shift || true
ks=("${@:-5 10 50}")
work=$(mktemp -d)
trap 'rm -rf "$work"' EXIT
wall() { local s e; s=$(date +%s.%N); "$@" >/dev/null 2>&1; e=$(date +%s.%N); echo "$e - $s" | bc; }
render() { "$py" tools/mitsuba/export.py tools/mitsuba/scenes/glossy-highlight.xml -o "$work/d.pds" --spp 64 --order pass; }
render >/dev/null
for k in ${ks[@]}; do
  for i in $(seq "$runs"); do
    echo "render $(wall render)"
    echo "bare $(wall "$bin" filter "$work/d.pds" -o "$work/b" --k "$k" --no-html --methods mean)"
    echo "default $(wall "$bin" filter "$work/d.pds" -o "$work/d" --k "$k")"
    echo "sigma $(wall "$bin" filter "$work/d.pds" -o "$work/s" --k "$k" --sigma-map)"
  done | python3 -c "
import sys, statistics as st
v = {}
for line in sys.stdin:
    name, t = line.split(); v.setdefault(name, []).append(float(t))
m = {n: st.median(x) for n, x in v.items()}
print('k = $k:', '  '.join(f'{n} {min(x):.2f}/{m[n]:.2f} s' for n, x in v.items()), '(min/median)')
print('  median ratios: default/bare %.2f, sigma/bare %.2f, bare/render %.2f, default/render %.2f' % (
    m['default'] / m['bare'], m['sigma'] / m['bare'], m['bare'] / m['render'], m['default'] / m['render']))
"
done
