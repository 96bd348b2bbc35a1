#!/usr/bin/env bash
# The dumps the fidelity tables are measured on: our renderer's scenes
# (SCENES) and the Mitsuba exporter's (MITSUBA_SCENES) at SIZE² (default
# 128) pixels and each of SPPS (default "16 64 256") spp, seed 1,
# pass-major, with one reference per scene (REF_SPP, default 1024, for ours;
# MI_REF_SPP, default 4096, for Mitsuba's, rendered by Mitsuba itself).
# Writes OUT/RENDERER-SCENE-SPP.pds and OUT/RENDERER-SCENE-ref.exr, and
# OUT/RENDERER-SCENE-albedo.exr and -normal.exr, the denoisers'
# auxiliary inputs (ours: 16 camera rays a pixel; Mitsuba's: 64 spp of
# its aov integrator); a file already there is kept. Needs Mitsuba (bash tools/mitsuba/setup.sh). Blender Cycles'
# builtin scenes (CYCLES_SCENES, default "caustic highlight room textured";
# reference CY_REF_SPP, default 4096, by Cycles; albedo and normal from its
# denoising passes) when tools/cycles/.venv exists (bash tools/cycles/setup.sh).
#
#   bash tools/results/dumps.sh OUT
set -euo pipefail
cd "$(dirname "$0")/../.."
out=${1:?usage: dumps.sh OUT}
threads=${THREADS:-2}
size=${SIZE:-128}
spps=${SPPS:-"16 64 256"}
ours=${SCENES:-"glossy-room two-lights indirect-room sky"}
theirs=${MITSUBA_SCENES:-"caustic glossy-highlight indirect-room"}
ref_spp=${REF_SPP:-1024}
mi_ref_spp=${MI_REF_SPP:-4096}
cycles=${CYCLES_SCENES:-"caustic highlight room textured"}
cy_ref_spp=${CY_REF_SPP:-4096}
cy=tools/cycles/.venv/bin/python
py=tools/mitsuba/.venv/bin/python
mkdir -p "$out"
cargo build --release --quiet --bin render
for s in $ours; do
    ref="$out/ours-$s-ref.exr"
    albedo="$out/ours-$s-albedo.exr" normal="$out/ours-$s-normal.exr"
    for spp in $spps; do
        dump="$out/ours-$s-$spp.pds"
        [ -f "$dump" ] && continue
        refargs=()
        [ -f "$ref" ] || refargs=(--reference-spp "$ref_spp" --reference-out "$ref")
        [ -f "$albedo" ] && [ -f "$normal" ] ||
            refargs+=(--albedo-out "$albedo" --normal-out "$normal")
        ./target/release/render --scene "$s" --width "$size" --height "$size" --spp "$spp" \
            --order pass --threads "$threads" -o "$dump" "${refargs[@]}" > /dev/null
        echo "$dump" >&2
    done
    # A folder made before the albedo and normal were written gets them.
    if [ ! -f "$albedo" ] || [ ! -f "$normal" ]; then
        tmp=$(mktemp -d)
        trap 'rm -rf "$tmp"' EXIT
        ./target/release/render --scene "$s" --width "$size" --height "$size" --spp 1 \
            --threads "$threads" -o "$tmp/aux.pds" --albedo-out "$albedo" \
            --normal-out "$normal" > /dev/null
        rm -rf "$tmp"
        echo "$albedo" >&2
    fi
done
for s in $theirs; do
    ref="$out/mitsuba-$s-ref.exr"
    for spp in $spps; do
        dump="$out/mitsuba-$s-$spp.pds"
        [ -f "$dump" ] && continue
        refargs=()
        [ -f "$ref" ] || refargs=(--reference-spp "$mi_ref_spp" --reference-out "$ref"
            --albedo-out "$out/mitsuba-$s-albedo.exr" --normal-out "$out/mitsuba-$s-normal.exr"
            --aux-spp 64)
        $py tools/mitsuba/export.py "tools/mitsuba/scenes/$s.xml" -o "$dump" \
            --size "${size}x${size}" --spp "$spp" --seed 1 --quiet "${refargs[@]}"
        echo "$dump" >&2
    done
done
[ -x "$cy" ] || { echo "no tools/cycles/.venv: Cycles' scenes left out" >&2; exit 0; }
for s in $cycles; do
    ref="$out/cycles-$s-ref.exr"
    for spp in $spps; do
        dump="$out/cycles-$s-$spp.pds"
        [ -f "$dump" ] && continue
        refargs=()
        [ -f "$ref" ] || refargs=(--reference-spp "$cy_ref_spp" --reference-out "$ref"
            --albedo-out "$out/cycles-$s-albedo.exr" --normal-out "$out/cycles-$s-normal.exr")
        $cy tools/cycles/export.py "builtin:$s" -o "$dump" --size "${size}x${size}" --spp "$spp" \
            --seed 1 --order pass --threads "$threads" --quiet "${refargs[@]}"
        echo "$dump" >&2
    done
done
