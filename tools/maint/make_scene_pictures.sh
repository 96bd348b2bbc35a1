#!/usr/bin/env bash
# Renders every scene at 128 × 128, 256 spp and keeps the mean image's
# preview as docs/scenes/NAME.png (frame 0 for the animation).
set -euo pipefail
cd "$(dirname "$0")/../.."
cargo build --release --quiet
tmp=$(mktemp -d)
trap 'rm -rf "$tmp"' EXIT
mkdir -p docs/scenes
for s in glossy-room diffuse-room two-lights indirect-room sky moving; do
    ./target/release/render --scene "$s" --width 128 --height 128 --spp 256 -o "$tmp/$s.pds" >/dev/null
    ./target/release/pathdensity filter "$tmp/$s.pds" -o "$tmp/$s" >/dev/null
    if [ -f "$tmp/$s/mean.png" ]; then cp "$tmp/$s/mean.png" "docs/scenes/$s.png"
    else cp "$tmp/$s/mean_0000.png" "docs/scenes/$s.png"; fi
    echo "docs/scenes/$s.png"
done
