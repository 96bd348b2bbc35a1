#!/usr/bin/env bash
# Scale: filter a 100M-sample synthetic dump (1024 × 1024 × 96 spp, 2.4 GB)
# and record wall time and peak memory, split into the process's own
# memory (RssAnon: tree, images, per-record decisions and σ, grouping) and
# the mapped dump (RssFile: clean page cache the kernel can drop).
# Usage: tools/bench/scale_test.sh [DIR] (default /tmp/pd-scale; needs ~5 GB).
set -euo pipefail
cd "$(dirname "$0")/../.."
dir=${1:-/tmp/pd-scale}
mkdir -p "$dir"
cargo build --release --quiet
pd=target/release/pathdensity
for order in pixel pass; do
    dump=$dir/scale-$order.pds
    [ -f "$dump" ] || $pd synth -o "$dump" --width 1024 --height 1024 --spp 96 --order $order >/dev/null
done
peak() { # PID: prints "anon_kB file_kB" peaks while PID lives
    local a=0 f=0 x y
    while kill -0 "$1" 2>/dev/null; do
        x=$(awk '/RssAnon/ {print $2}' /proc/"$1"/status 2>/dev/null || echo 0)
        y=$(awk '/RssFile/ {print $2}' /proc/"$1"/status 2>/dev/null || echo 0)
        [ "${x:-0}" -gt "$a" ] && a=$x
        [ "${y:-0}" -gt "$f" ] && f=$y
        sleep 0.05
    done
    echo "$a $f"
}
echo "| dump | options | wall s | peak RssAnon MB | peak RssFile MB | stored |"
echo "|---|---|---:|---:|---:|---:|"
for order in pixel pass; do
    for opts in "--no-html" ""; do
        out=$dir/out-$order
        start=$(date +%s.%N)
        $pd filter "$dir/scale-$order.pds" -o "$out" $opts >"$dir/log" 2>&1 &
        pid=$!
        read -r anon file < <(peak $pid)
        wait $pid
        end=$(date +%s.%N)
        stored=$(python3 -c "import json;print(json.load(open('$out/report.json'))['counts']['stored'])")
        printf "| %s | %s | %.1f | %.0f | %.0f | %s |\n" "$order-major" "${opts:-the default images + report}" \
            "$(echo "$end - $start" | bc)" "$(echo "$anon / 1024" | bc)" "$(echo "$file / 1024" | bc)" "$stored"
    done
done
