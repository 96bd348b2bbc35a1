#!/usr/bin/env bash
# Regenerates fixtures/demo.pds and fixtures/demo_ref.exr, the embedded
# default of README's first command.
#
# demo.pds: a 64 × 64 synthetic still at 16 spp (smooth colour field, 1% of
# samples fireflies at 100–300× their value, a 3 × 3-pixel light of
# radiance 20). demo_ref.exr: the mean of the same field without fireflies
# at 1024 spp and another seed: what the fireflies hide.
set -euo pipefail
cd "$(dirname "$0")/.."
cargo build --release --quiet
bin=target/release/pathdensity
tmp=$(mktemp -d)
trap 'rm -rf "$tmp"' EXIT
$bin synth -o fixtures/demo.pds --width 64 --height 64 --spp 16 \
    --fireflies 0.01 --light 30,20,3,20 --seed 1
$bin synth -o "$tmp/ref.pds" --width 64 --height 64 --spp 1024 \
    --fireflies 0 --light 30,20,3,20 --seed 2
$bin filter "$tmp/ref.pds" -o "$tmp/ref" >/dev/null
cp "$tmp/ref/mean.exr" fixtures/demo_ref.exr
