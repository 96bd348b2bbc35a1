#!/usr/bin/env bash
# Should σ_image scale with the film? The same scenes at SIZES
# (default "64 128 256") pixels a side, 64 spp, each swept over σ_image
# 1.5, 3, 6 px with the other defaults; "scaled" means σ_image = 3 px at
# 128 and in proportion (1.5 at 64, 6 at 256). References: 1024 spp (512 at
# 256²). Writes OUT/sigma_image.csv (default out/sigma_image): one line per
# dump, σ_image and image (filtered, filtered_energy) or baseline.
#
#   PATHDENSITY=… RENDER=… bash tools/results/sigma_image_scale.sh
set -euo pipefail
cd "$(dirname "$0")/../.."
bin=${PATHDENSITY:-target/release/pathdensity}
render=${RENDER:-target/release/render}
py=tools/mitsuba/.venv/bin/python
sizes=${SIZES:-"64 128 256"}
ours=${SCENES:-"two-lights sky"}
theirs=${MITSUBA_SCENES:-"caustic glossy-highlight indirect-room"}
out=${OUT:-out/sigma_image}
mkdir -p "$out"
csv="$out/sigma_image.csv"
rm -f "$csv"
sweep() { # renderer scene size ref
    "$bin" sweep "$out/dump.pds" --reference "$4" -o "$out/sweep" --k 5 --sigma-color 50 \
        --sigma-image 1.5,3,6 --white auto > /dev/null
    [ -f "$csv" ] || echo "renderer,scene,size,$(head -1 "$out/sweep/sweep.csv")" > "$csv"
    tail -n +2 "$out/sweep/sweep.csv" | sed "s/^/$1,$2,$3,/" >> "$csv"
    echo "$1 $2 $3 done" >&2
}
refspp() { [ "$1" -ge 256 ] && echo 512 || echo 1024; }
for size in $sizes; do
    for s in $theirs; do
        ref="$out/mitsuba-$s-$size-ref.exr"
        [ -f "$ref" ] || "$py" tools/mitsuba/export.py "tools/mitsuba/scenes/$s.xml" -o "$out/ref.pds" \
            --spp 1 --size "${size}x$size" --reference-spp "$(refspp "$size")" --reference-out "$ref" > /dev/null
        "$py" tools/mitsuba/export.py "tools/mitsuba/scenes/$s.xml" -o "$out/dump.pds" \
            --spp 64 --size "${size}x$size" --order pass > /dev/null
        sweep mitsuba "$s" "$size" "$ref"
    done
    for s in $ours; do
        ref="$out/ours-$s-$size-ref.exr"
        "$render" --scene "$s" --width "$size" --height "$size" --spp 64 --order pass \
            -o "$out/dump.pds" $([ -f "$ref" ] || echo "--reference-spp $(refspp "$size") --reference-out $ref") > /dev/null
        sweep ours "$s" "$size" "$ref"
    done
done
rm -f "$out/dump.pds" "$out/ref.pds"
