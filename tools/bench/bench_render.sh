#!/usr/bin/env bash
# Renderer throughput per scene: 256 × 256 at 16 spp (the moving scene:
# 8 frames at 2 spp, the same sample count), pixel-major, THREADS threads
# (default 2). Prints a markdown table for docs/BENCHMARKS.md.
set -euo pipefail
cd "$(dirname "$0")/../.."
threads=${THREADS:-2}
cargo build --release --quiet
tmp=$(mktemp -d)
trap 'rm -rf "$tmp"' EXIT
echo "| scene | samples | seconds | M samples/s |"
echo "|---|---:|---:|---:|"
for s in glossy-room diffuse-room two-lights indirect-room sky moving; do
    args=(--spp 16)
    [ "$s" = moving ] && args=(--spp 2 --frames 8)
    line=$(./target/release/render --scene "$s" --width 256 --height 256 "${args[@]}" \
        --threads "$threads" -o "$tmp/$s.pds")
    # "...: NAME W×H×F at N spp, COUNT samples in S s (R M samples/s)"
    count=$(sed -E 's/.*, ([0-9]+) samples in.*/\1/' <<<"$line")
    secs=$(sed -E 's/.* in ([0-9.]+) s .*/\1/' <<<"$line")
    rate=$(sed -E 's/.*\(([0-9.]+) M samples\/s\).*/\1/' <<<"$line")
    echo "| $s | $count | $secs | $rate |"
done
